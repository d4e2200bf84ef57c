//! Energy-error maps as the API and the command line take and give them: the strict parser of
//! `POST /api/v1/studies/energy-map` and `geomint study energy-map`, the result document, and its
//! NDJSON progress lines. The map itself is [`crate::core::energy_map`].

use std::time::Instant;

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::error::{codes, ErrorDetail};
use super::request::{check_fields, method, number, object, present, wrong_type, MethodSpec};
use crate::core::energy_map::{EnergyMap, EnergyMapSpec};
use crate::core::methods::{MethodChoice, MethodId};
use crate::core::run::{step_count, Budget};
use crate::core::systems::{self, PlanarKind, PlanarSpring};

/// The fields of a map request.
pub const MAP_FIELDS: &[&str] = &["method", "params", "h", "t_max", "nx", "ny", "x", "y"];
/// Default parameters of 001 Fig. 6 (l = m = k = 1, g = 0.02).
const FIG6_G: f64 = 0.02;
/// Default step and horizon (Fig. 6 uses t_max = 50 000; the default is a quick look).
const DEFAULT_H: f64 = 0.2;
const DEFAULT_T_MAX: f64 = 2000.0;
const DEFAULT_N: usize = 41;
/// Points on the analytic boundary curve.
const BOUNDARY_POINTS: usize = 360;

/// An energy-error map of the planar elastic pendulum (001 Fig. 6).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({"method": "symplectic_euler", "h": 0.2, "t_max": 2000, "nx": 41, "ny": 41}))]
pub struct EnergyMapRequest {
    /// The method, run in both charts (default `symplectic_euler`); it must run on the polar
    /// chart's non-separable Hamiltonian (symplectic Euler and its adjoint, implicit midpoint,
    /// the Runge–Kutta methods).
    pub method: MethodSpec,
    /// `m`, `k`, `l`, `g` of `elastic_pendulum_2d` (default 1, 1, 1 and g = 0.02 as in Fig. 6).
    #[schema(value_type = Object)]
    pub params: Map<String, Value>,
    /// Step size (default 0.2).
    pub h: f64,
    /// Final time (default 2000; Fig. 6 uses 50 000).
    pub t_max: f64,
    /// Grid points along x (default 41, at most 401).
    pub nx: usize,
    /// Grid points along y (default 41, at most 401).
    pub ny: usize,
    /// Range [min, max] of x₀ (default [−1.5, 1.5]).
    pub x: [f64; 2],
    /// Range [min, max] of y₀, y pointing down along gravity (default [−1.5, 1.5]).
    pub y: [f64; 2],
}

/// Counts over the map.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct MapSummary {
    /// Cells in the grid.
    pub cells: usize,
    /// Cells where ε(x,y) < ε(r,θ): Cartesian coordinates are more accurate.
    pub cartesian_better: usize,
    /// Cells where ε(r,θ) < ε(x,y).
    pub polar_better: usize,
    /// Cells whose polar run diverged.
    pub polar_diverged: usize,
    /// Cells whose Cartesian run diverged (the pivot only, where the spring has no direction).
    pub cartesian_diverged: usize,
    /// Cells in the region where Sec. 4.1 predicts the polar run to pass through the pivot.
    pub predicted_divergent: usize,
    /// Polar divergences outside that region (near its boundary, where the discrete motion
    /// reaches a little further than the exact one).
    pub diverged_outside_prediction: usize,
}

/// The map. Per-cell arrays are row-major: entry j·nx + i belongs to (x₀, y₀) = (xs[i], ys[j]).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct EnergyMapDocument {
    /// The method's label.
    pub method: String,
    /// m, k, l, g.
    pub params: MapParams,
    /// Step size.
    pub h: f64,
    /// Final time.
    pub t_max: f64,
    /// Steps per cell and chart.
    pub steps_per_run: u64,
    /// Grid x₀ values.
    pub xs: Vec<f64>,
    /// Grid y₀ values.
    pub ys: Vec<f64>,
    /// H at the start of each cell (p₀ = 0).
    pub energy: Vec<f64>,
    /// ℓ² energy error of eq. (50) in Cartesian coordinates (`null`: diverged).
    pub epsilon_cartesian: Vec<Option<f64>>,
    /// ℓ² energy error in polar coordinates (`null`: diverged, or the pivot).
    pub epsilon_polar: Vec<Option<f64>>,
    /// ε(x,y) − ε(r,θ) where both exist.
    pub difference: Vec<Option<f64>>,
    /// Time at which the polar run diverged (`null`: it did not).
    pub polar_diverged_at: Vec<Option<f64>>,
    /// Time at which the Cartesian run diverged.
    pub cartesian_diverged_at: Vec<Option<f64>>,
    /// Whether r₀ ≥ 2l + 2mg/k·cos θ₀ (Sec. 4.1).
    pub predicted_divergent: Vec<bool>,
    /// The boundary r = 2l + 2mg/k·cos θ as (x, y) points.
    pub boundary: Vec<[f64; 2]>,
    /// Counts.
    pub summary: MapSummary,
    /// Steps taken in all.
    pub steps: u64,
    /// Wall time in milliseconds.
    pub wall_ms: f64,
}

/// The pendulum's parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
pub struct MapParams {
    /// Mass.
    pub m: f64,
    /// Stiffness.
    pub k: f64,
    /// Rest length.
    pub l: f64,
    /// Gravity.
    pub g: f64,
}

/// What a map's progress stream carries.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum MapLine {
    /// Cells done so far (sent at most about 100 times per map).
    Progress {
        /// Cells done.
        done: usize,
        /// Cells in all.
        total: usize,
    },
    /// The map.
    Result(Box<EnergyMapDocument>),
    /// A failure.
    Error {
        /// What went wrong.
        error: ErrorDetail,
    },
    /// The last line of a complete stream.
    End,
}

fn range(v: &Value, field: &str) -> Result<[f64; 2], ErrorDetail> {
    let list = v
        .as_array()
        .filter(|a| a.len() == 2)
        .ok_or_else(|| wrong_type(field, "a range [min, max]", v))?;
    Ok([
        number(&list[0], &format!("{field}[0]"))?,
        number(&list[1], &format!("{field}[1]"))?,
    ])
}

fn count(v: &Value, field: &str) -> Result<usize, ErrorDetail> {
    v.as_u64()
        .map(|n| n as usize)
        .ok_or_else(|| wrong_type(field, "a whole number of grid points", v))
}

impl EnergyMapRequest {
    /// Parses a map request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = object(value, None)?;
        check_fields(obj, MAP_FIELDS, "")?;
        let get = |name: &str, default: f64| -> Result<f64, ErrorDetail> {
            present(obj, name).map_or(Ok(default), |v| number(v, name))
        };
        Ok(EnergyMapRequest {
            method: match present(obj, "method") {
                Some(v) => method(v, "method")?,
                None => MethodSpec::Id("symplectic_euler".into()),
            },
            params: match present(obj, "params") {
                Some(v) => object(v, Some("params"))?.clone(),
                None => Map::new(),
            },
            h: get("h", DEFAULT_H)?,
            t_max: get("t_max", DEFAULT_T_MAX)?,
            nx: present(obj, "nx").map_or(Ok(DEFAULT_N), |v| count(v, "nx"))?,
            ny: present(obj, "ny").map_or(Ok(DEFAULT_N), |v| count(v, "ny"))?,
            x: present(obj, "x").map_or(Ok([-1.5, 1.5]), |v| range(v, "x"))?,
            y: present(obj, "y").map_or(Ok([-1.5, 1.5]), |v| range(v, "y"))?,
        })
    }

    /// Validates the request (cheap: no integration).
    pub fn prepare(&self) -> Result<EnergyMapSpec, ErrorDetail> {
        let invalid = |field: &str, message: String| {
            ErrorDetail::at(codes::INVALID_VALUE, field, format!("{field}: {message}"))
        };
        let info = systems::info("elastic_pendulum_2d").map_err(|e| ErrorDetail::core(&e))?;
        let mut params = self.params.clone();
        params.entry("g").or_insert(Value::from(FIG6_G));
        let resolved = systems::resolve(&info, &params).map_err(|e| ErrorDetail::core(&e))?;
        let n = |name: &str| resolved.numbers[name];
        if !(self.h.is_finite() && self.h > 0.0) {
            return Err(invalid(
                "h",
                format!("must be finite and > 0, got {}", self.h),
            ));
        }
        if !(self.t_max.is_finite() && self.t_max > 0.0) {
            return Err(invalid(
                "t_max",
                format!("must be finite and > 0, got {}", self.t_max),
            ));
        }
        let choice = MethodChoice::parse(&self.method.to_input(), "method")
            .map_err(|e| ErrorDetail::core(&e))?;
        if choice.id == MethodId::Reference {
            return Err(invalid(
                "method",
                "the adaptive reference is not a fixed-step method; choose e.g. symplectic_euler"
                    .into(),
            ));
        }
        let spec = EnergyMapSpec {
            method: choice,
            pendulum: PlanarSpring {
                m: n("m"),
                k: n("k"),
                l: n("l"),
                g: n("g"),
                kind: PlanarKind::Pendulum,
            },
            h: self.h,
            steps: step_count(self.h, self.t_max),
            nx: self.nx,
            ny: self.ny,
            x: (self.x[0], self.x[1]),
            y: (self.y[0], self.y[1]),
        };
        spec.check()
            .map_err(|e| ErrorDetail::core(&e).singular_method())?;
        Ok(spec)
    }
}

/// Runs the map, reporting progress about every 1 % of the cells; an error when the budget
/// stopped it.
pub fn run(
    spec: &EnergyMapSpec,
    t_max: f64,
    budget: Budget<'_>,
    emit: &(dyn Fn(MapLine) -> bool + Sync),
) -> Result<EnergyMapDocument, ErrorDetail> {
    let started = Instant::now();
    let total = spec.nx * spec.ny;
    let every = (total / 100).max(1);
    // Cells finish on several threads: emit under a lock, and only counts above the last one
    // sent, so that the stream's `done` only grows.
    let last_sent = std::sync::Mutex::new(0usize);
    let progress = |done: usize, total: usize| {
        if done % every == 0 || done == total {
            let mut last = last_sent.lock().unwrap_or_else(|e| e.into_inner());
            if done > *last {
                *last = done;
                emit(MapLine::Progress { done, total });
            }
        }
    };
    let map = spec
        .run(budget, &progress)
        .map_err(|e| ErrorDetail::core(&e))?
        .ok_or_else(|| stopped(budget))?;
    Ok(document(
        spec,
        t_max,
        map,
        started.elapsed().as_secs_f64() * 1e3,
    ))
}

/// The error for a map the budget stopped.
fn stopped(budget: Budget<'_>) -> ErrorDetail {
    if budget
        .cancel
        .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    {
        ErrorDetail::new(
            codes::OVERLOADED,
            "the map was cancelled (the server is shutting down)",
        )
    } else {
        ErrorDetail::new(
            codes::TIMEOUT,
            "the map did not finish within the time limit; use fewer cells or a shorter t_max",
        )
    }
}

fn document(spec: &EnergyMapSpec, t_max: f64, map: EnergyMap, wall_ms: f64) -> EnergyMapDocument {
    let difference = map.difference();
    let polar_diverged_at: Vec<Option<f64>> = map.polar.iter().map(|r| r.diverged_at).collect();
    let cartesian_diverged_at: Vec<Option<f64>> =
        map.cartesian.iter().map(|r| r.diverged_at).collect();
    let summary = MapSummary {
        cells: difference.len(),
        cartesian_better: difference.iter().flatten().filter(|&&d| d < 0.0).count(),
        polar_better: difference.iter().flatten().filter(|&&d| d > 0.0).count(),
        polar_diverged: polar_diverged_at.iter().flatten().count(),
        cartesian_diverged: cartesian_diverged_at.iter().flatten().count(),
        predicted_divergent: map.predicted_divergent.iter().filter(|&&p| p).count(),
        diverged_outside_prediction: polar_diverged_at
            .iter()
            .zip(&map.predicted_divergent)
            .filter(|(d, &p)| d.is_some() && !p)
            .count(),
    };
    let s = &spec.pendulum;
    EnergyMapDocument {
        method: map.method,
        params: MapParams {
            m: s.m,
            k: s.k,
            l: s.l,
            g: s.g,
        },
        h: spec.h,
        t_max,
        steps_per_run: spec.steps,
        boundary: spec.boundary(BOUNDARY_POINTS),
        xs: map.xs,
        ys: map.ys,
        energy: map.energy,
        epsilon_cartesian: map.cartesian.iter().map(|r| r.epsilon).collect(),
        epsilon_polar: map.polar.iter().map(|r| r.epsilon).collect(),
        difference,
        polar_diverged_at,
        cartesian_diverged_at,
        predicted_divergent: map.predicted_divergent,
        summary,
        steps: map.steps,
        wall_ms,
    }
}
