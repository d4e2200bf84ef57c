//! Where a simulation's recording puts everything: the entity names and colours of each method,
//! the invariants' parts, the phase portraits and what the world view shows ([`Layout`]); the
//! sample times on the `step` timeline; the pieces the growing paths are logged in
//! ([`path_blocks`]); and the default blueprint that arranges the views ([`send_blueprint`]),
//! with a tab per chaos indicator when the runs carry them.

use rerun::external::re_sdk_types::blueprint::components::ContainerKind;
use rerun::RecordingStream;

use super::blueprint::{self, BlueprintNode};
use super::{entity_names, entity_part, RecordingError};
use crate::core::chaos::Indicator;
use crate::core::simulation::stream::StreamHeader;
use crate::core::simulation::SimulationDocument;
use crate::core::systems::World;

/// Degrees of freedom with a phase portrait (the first ones; an N-body run has 3N).
pub const MAX_PHASE_DOFS: usize = 6;

/// Where everything of a simulation goes: entity names and colours per method, the invariant
/// parts and what the world view shows. Made from the document ([`Layout::of`]) or, before any
/// sample exists, from the stream's header ([`Layout::of_header`]).
#[derive(Clone, Debug)]
pub struct Layout {
    /// Method labels, in request order.
    pub labels: Vec<String>,
    /// Entity names of the methods (the first path part).
    pub methods: Vec<String>,
    /// The system's invariants as (name, entity part).
    pub invariants: Vec<(String, String)>,
    /// Degrees of freedom with a phase portrait.
    pub phase_dofs: usize,
    /// Whether the runs carry energy errors.
    pub energy_error: bool,
    /// How the system appears in space.
    pub world: World,
    /// Degrees of freedom of the system.
    pub dof: usize,
    /// Whether the runs collect a Poincaré section.
    pub section: bool,
    /// The chaos indicators the runs carry, and the exponents of a `lyapunov` spectrum.
    pub indicators: Vec<Indicator>,
    /// Exponents per spectrum (with `lyapunov`).
    pub exponents: usize,
}

/// The entity part of each scalar indicator series, and the view title.
pub const INDICATOR_SERIES: [(Indicator, &str, &str); 5] = [
    (Indicator::Megno, "megno_mean", "MEGNO ⟨Y⟩"),
    (Indicator::Megno, "megno", "MEGNO Y"),
    (Indicator::Fli, "fli", "FLI"),
    (Indicator::Sali, "sali", "SALI"),
    (Indicator::Gali, "gali", "GALI"),
];

impl Layout {
    /// The layout of a simulation of system `system` with `dof` degrees of freedom, methods
    /// `labels` (request order) and the system's `invariants`.
    pub fn new(
        world: World,
        dof: usize,
        labels: Vec<String>,
        invariants: &[String],
        energy_error: bool,
    ) -> Self {
        Layout {
            methods: entity_names(&labels),
            labels,
            invariants: invariants
                .iter()
                .map(|n| (n.clone(), entity_part(n)))
                .collect(),
            phase_dofs: dof.min(MAX_PHASE_DOFS),
            energy_error,
            world,
            dof,
            section: false,
            indicators: Vec::new(),
            exponents: 0,
        }
    }

    /// This layout, with a Poincaré section when `section`.
    pub fn with_section(mut self, section: bool) -> Self {
        self.section = section;
        self
    }

    /// The same layout with the chaos indicators `indicators` (`exponents` per spectrum).
    pub fn with_indicators(mut self, indicators: Vec<Indicator>, exponents: usize) -> Self {
        self.indicators = indicators;
        self.exponents = exponents;
        self
    }

    /// The layout of a simulation's document.
    pub fn of(doc: &SimulationDocument) -> Self {
        let columns = doc.runs.first().map(|r| &r.columns);
        let indicators = columns.map_or(Vec::new(), |c| {
            Indicator::ALL
                .into_iter()
                .filter(|i| match i {
                    Indicator::Lyapunov => c.lyapunov.is_some(),
                    Indicator::Megno => c.megno.is_some(),
                    Indicator::Fli => c.fli.is_some(),
                    Indicator::Sali => c.sali.is_some(),
                    Indicator::Gali => c.gali.is_some(),
                })
                .collect()
        });
        let exponents = columns
            .and_then(|c| c.lyapunov.as_ref())
            .and_then(|l| l.first())
            .map_or(0, Vec::len);
        Layout::new(
            doc.system.world.clone(),
            doc.system.q0.len(),
            doc.runs.iter().map(|r| r.method.clone()).collect(),
            &doc.invariants,
            doc.runs.iter().any(|r| r.columns.energy_error.is_some()),
        )
        .with_section(doc.section.is_some())
        .with_indicators(indicators, exponents)
    }

    /// The layout of a simulation announced by a stream's header.
    pub fn of_header(header: &StreamHeader) -> Self {
        Layout::new(
            header.system.world.clone(),
            header.system.q0.len(),
            header.methods.clone(),
            &header.invariants,
            header.energy_error,
        )
        .with_section(header.section.is_some())
        .with_indicators(header.indicators.clone(), header.deviations.unwrap_or(0))
    }

    /// The entity paths of method `index`'s chaos indicators.
    pub fn indicator_entities(&self, index: usize) -> Vec<String> {
        let m = &self.methods[index];
        let mut paths = Vec::new();
        if self.indicators.contains(&Indicator::Lyapunov) {
            paths.extend((0..self.exponents).map(|i| format!("/{m}/indicators/lyapunov/{i}")));
        }
        for (indicator, part, _) in INDICATOR_SERIES {
            if self.indicators.contains(&indicator) {
                paths.push(format!("/{m}/indicators/{part}"));
            }
        }
        paths
    }

    /// Every entity path of method `index` that holds data, in a fixed order.
    pub fn method_entities(&self, index: usize) -> Vec<String> {
        let m = &self.methods[index];
        let mut paths = vec![format!("/{m}/energy")];
        if self.energy_error {
            paths.push(format!("/{m}/energy_error"));
        }
        for (_, part) in &self.invariants {
            paths.push(format!("/{m}/invariants/{part}"));
        }
        paths.push(format!("/{m}/force_evaluations"));
        for dof in 0..self.phase_dofs {
            paths.push(format!("/{m}/phase/{dof}/point"));
            paths.push(format!("/{m}/phase/{dof}/path"));
        }
        paths.push(format!("/{m}/world/bodies"));
        paths.push(format!("/{m}/world/path"));
        if self.section {
            for dof in 0..self.phase_dofs {
                paths.push(format!("/{m}/section/{dof}"));
            }
            paths.push(format!("/{m}/world/section"));
        }
        paths.extend(self.indicator_entities(index));
        paths
    }
}

/// The step index of sample `i` of a run: samples are taken at step 0, every `every` steps and
/// at the last step (`steps`), so sample i is at min(i·every, steps).
pub fn sample_step(i: u64, every: u64, steps: u64) -> i64 {
    i.saturating_mul(every).min(steps) as i64
}

/// The step index of every sample of a run of `count` samples (see [`sample_step`]).
pub fn sample_steps(count: usize, every: u64, steps: u64) -> Vec<i64> {
    (0..count as u64)
        .map(|i| sample_step(i, every, steps))
        .collect()
}

/// Most rows of a path entity: longer runs draw their paths in blocks of several samples.
pub const MAX_PATH_ROWS: usize = 1000;

/// A block of consecutive samples drawn as one path row, logged at the time of its last sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathBlock {
    /// First sample of the block (the last sample of the previous block).
    pub start: usize,
    /// Last sample of the block.
    pub end: usize,
}

/// Samples per path row of a run of `n` samples: ⌈(n − 1)/[`MAX_PATH_ROWS`]⌉, at least 1.
pub fn path_block_len(n: usize) -> usize {
    n.saturating_sub(1).div_ceil(MAX_PATH_ROWS).max(1)
}

/// How the path of a run of `n` samples is cut into rows: the first row holds sample 0 alone,
/// then each row continues the path by up to ⌈(n − 1)/[`MAX_PATH_ROWS`]⌉ samples (one sample
/// per row for runs of up to about 1000 samples), so at most about [`MAX_PATH_ROWS`] + 1 rows.
pub fn path_blocks(n: usize) -> Vec<PathBlock> {
    if n == 0 {
        return Vec::new();
    }
    let block = path_block_len(n);
    let mut blocks = vec![PathBlock { start: 0, end: 0 }];
    let mut start = 0;
    while start + 1 < n {
        let end = (start + block).min(n - 1);
        blocks.push(PathBlock { start, end });
        start = end;
    }
    blocks
}

/// The default layout: energy of all methods on top of the other plots (energy error,
/// invariants, force evaluations as tabs), beside the 3-D world with the spec and a grid of
/// phase portraits.
fn blueprint_tree(layout: &Layout) -> BlueprintNode {
    let each = |f: &dyn Fn(&str) -> String| -> Vec<String> {
        layout.methods.iter().map(|m| f(m)).collect()
    };
    let mut plots = Vec::new();
    if layout.energy_error {
        plots.push(BlueprintNode::view(
            "TimeSeries",
            "energy error",
            each(&|m| format!("/{m}/energy_error")),
        ));
    }
    for (name, part) in &layout.invariants {
        plots.push(BlueprintNode::view(
            "TimeSeries",
            name.clone(),
            each(&|m| format!("/{m}/invariants/{part}")),
        ));
    }
    plots.push(BlueprintNode::view(
        "TimeSeries",
        "force evaluations",
        each(&|m| format!("/{m}/force_evaluations")),
    ));
    if layout.indicators.contains(&Indicator::Lyapunov) {
        plots.push(BlueprintNode::view(
            "TimeSeries",
            "Lyapunov spectrum",
            each(&|m| format!("/{m}/indicators/lyapunov/**")),
        ));
    }
    for (indicator, part, title) in INDICATOR_SERIES {
        if layout.indicators.contains(&indicator) {
            plots.push(BlueprintNode::view(
                "TimeSeries",
                title,
                each(&|m| format!("/{m}/indicators/{part}")),
            ));
        }
    }
    let left = BlueprintNode::container(
        ContainerKind::Vertical,
        vec![
            BlueprintNode::view("TimeSeries", "energy", each(&|m| format!("/{m}/energy"))),
            BlueprintNode::container(ContainerKind::Tabs, plots),
        ],
    );

    let mut trails = each(&|m| format!("/{m}/world/path"));
    if layout.section {
        trails.extend(each(&|m| format!("/{m}/world/section")));
    }
    let world =
        BlueprintNode::view("3D", "world", each(&|m| format!("/{m}/world/**"))).with_trails(trails);
    let spec = BlueprintNode::view("TextDocument", "spec", vec!["/spec".to_string()]);
    let phases: Vec<BlueprintNode> = (0..layout.phase_dofs)
        .map(|dof| {
            BlueprintNode::view(
                "2D",
                format!("phase (q{dof}, p{dof})"),
                each(&|m| format!("/{m}/phase/{dof}/**")),
            )
            .with_trails(each(&|m| format!("/{m}/phase/{dof}/path")))
        })
        .collect();
    // A section's points accumulate: every point up to the time cursor is shown.
    let sections: Vec<BlueprintNode> = (0..layout.phase_dofs)
        .filter(|_| layout.section)
        .map(|dof| {
            let points = each(&|m| format!("/{m}/section/{dof}"));
            BlueprintNode::view("2D", format!("section (q{dof}, p{dof})"), points.clone())
                .with_trails(points)
        })
        .collect();
    let mut views = vec![BlueprintNode::container(
        ContainerKind::Tabs,
        vec![world, spec],
    )];
    if !sections.is_empty() {
        views.push(BlueprintNode::container(ContainerKind::Grid, sections));
    }
    views.push(BlueprintNode::container(ContainerKind::Grid, phases));
    let right = BlueprintNode::container(ContainerKind::Vertical, views);
    BlueprintNode::container(ContainerKind::Horizontal, vec![left, right])
}

/// Sends the default blueprint for `layout` through `rec` (as Rerun's own SDKs do: a blueprint
/// store logged in full, then an activation command making it the active and default one).
pub fn send_blueprint(rec: &RecordingStream, layout: &Layout) -> Result<(), RecordingError> {
    blueprint::send(rec, &blueprint_tree(layout))
}
