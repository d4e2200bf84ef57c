//! The default blueprint of a recording, built as a tree of views and containers and logged
//! as Rerun's blueprint records into a blueprint store that is then activated.
//!
//! A node's id follows from its place in the tree, so that every recording with the same layout
//! has the same blueprint paths: Rerun interns entity paths for the life of the process, and
//! random ids would grow that table with every recording a long-running server writes.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use rerun::external::re_log_types::{BlueprintActivationCommand, LogMsg, StoreId, StoreKind};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, ViewBlueprint, ViewContents, ViewportBlueprint, VisibleTimeRanges,
};
use rerun::external::re_sdk_types::blueprint::components::{
    ContainerKind, IncludedContent, QueryExpression, RootContainer, ViewClass,
};
use rerun::external::re_sdk_types::datatypes::{
    TimeInt, TimeRange, TimeRangeBoundary, VisibleTimeRange,
};
use rerun::external::uuid::{Builder, Uuid};
use rerun::sink::{LogSink, SinkFlushError};
use rerun::{EntityPath, RecordingStream, RecordingStreamBuilder};

use super::{RecordingError, APPLICATION_ID, STEP_TIMELINE, TIME_TIMELINE};

/// A view of the blueprint under construction.
pub(super) struct ViewSpec {
    class: &'static str,
    name: String,
    contents: Vec<String>,
    /// Entities shown over the whole timeline up to the cursor.
    trails: Vec<String>,
}

/// A container of the blueprint under construction.
pub(super) struct ContainerSpec {
    kind: ContainerKind,
    children: Vec<BlueprintNode>,
}

pub(super) enum BlueprintNode {
    View(ViewSpec),
    Container(ContainerSpec),
}

impl BlueprintNode {
    pub(super) fn view(
        class: &'static str,
        name: impl Into<String>,
        contents: Vec<String>,
    ) -> BlueprintNode {
        BlueprintNode::View(ViewSpec {
            class,
            name: name.into(),
            contents,
            trails: Vec::new(),
        })
    }

    pub(super) fn container(kind: ContainerKind, children: Vec<BlueprintNode>) -> BlueprintNode {
        BlueprintNode::Container(ContainerSpec { kind, children })
    }

    /// Shows `entities` of this view over the whole timeline up to the time cursor (paths that
    /// grow), not only at the cursor.
    pub(super) fn with_trails(mut self, entities: Vec<String>) -> BlueprintNode {
        if let BlueprintNode::View(v) = &mut self {
            v.trails = entities;
        }
        self
    }

    /// The blueprint path of this node when its id is `id`.
    fn path(&self, id: Uuid) -> String {
        match self {
            BlueprintNode::View(_) => format!("view/{id}"),
            BlueprintNode::Container(_) => format!("container/{id}"),
        }
    }

    /// Logs this node, with id `id`, and its children.
    fn log(&self, bp: &RecordingStream, id: Uuid) -> Result<(), RecordingError> {
        match self {
            BlueprintNode::View(v) => {
                let path = self.path(id);
                bp.log(
                    format!("{path}/ViewContents"),
                    &ViewContents::new(
                        v.contents.iter().map(|q| QueryExpression(q.clone().into())),
                    ),
                )?;
                bp.log(
                    path.as_str(),
                    &ViewBlueprint::new(ViewClass(v.class.into()))
                        .with_display_name(v.name.clone())
                        .with_space_origin("/"),
                )?;
                // Paths grow: everything from the start of the timeline up to the cursor.
                let upto_cursor = TimeRange {
                    start: TimeRangeBoundary::Infinite,
                    end: TimeRangeBoundary::CursorRelative(TimeInt::from(0)),
                };
                let ranges = VisibleTimeRanges::new([STEP_TIMELINE, TIME_TIMELINE].map(|tl| {
                    VisibleTimeRange {
                        timeline: tl.into(),
                        range: upto_cursor,
                    }
                }));
                for entity in &v.trails {
                    let at = ViewContents::blueprint_base_visualizer_path_for_entity(
                        id,
                        &EntityPath::from(entity.as_str()),
                    );
                    bp.log(at, &ranges)?;
                }
            }
            BlueprintNode::Container(c) => {
                let children: Vec<(&BlueprintNode, Uuid)> = c
                    .children
                    .iter()
                    .enumerate()
                    .map(|(i, child)| (child, child_id(id, i)))
                    .collect();
                for &(child, child_id) in &children {
                    child.log(bp, child_id)?;
                }
                bp.log(
                    self.path(id),
                    &ContainerBlueprint::new(c.kind).with_contents(
                        children
                            .iter()
                            .map(|&(child, id)| IncludedContent(child.path(id).into())),
                    ),
                )?;
            }
        }
        Ok(())
    }
}

/// The id of the root container.
const ROOT_ID: Uuid = Uuid::from_u128(0x6765_6f6d_696e_7442_6c75_6570_7269_6e74);

/// The id of child `index` of the node with id `parent`: a fixed mix of the two (SplitMix64's
/// finaliser on each half), stamped as a version-4 UUID as Rerun's own ids are.
fn child_id(parent: Uuid, index: usize) -> Uuid {
    let mix = |mut z: u64| {
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let (hi, lo) = parent.as_u64_pair();
    let seed = (index as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    let bytes =
        (u128::from(mix(hi ^ seed)) << 64 | u128::from(mix(lo.wrapping_add(seed)))).to_be_bytes();
    Builder::from_random_bytes(bytes).into_uuid()
}

/// A sink that keeps the messages of a blueprint stream for [`send`] to take. Unlike Rerun's
/// memory sink it holds no handle of its own stream: that handle made a cycle (stream → sink →
/// storage → stream) that kept every blueprint stream, its batcher thread and its data alive
/// for the life of the process.
#[derive(Clone, Default)]
struct Collected(Arc<Mutex<Vec<LogMsg>>>);

impl Collected {
    fn take(&self) -> Vec<LogMsg> {
        std::mem::take(&mut *self.0.lock().unwrap_or_else(PoisonError::into_inner))
    }
}

impl LogSink for Collected {
    fn send(&self, msg: LogMsg) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(msg);
    }

    fn flush_blocking(&self, _timeout: Duration) -> Result<(), SinkFlushError> {
        Ok(())
    }
}

/// Sends the blueprint with root container `root` through `rec` (as Rerun's own SDKs do: a
/// blueprint store logged in full, then an activation command making it the active and default
/// one).
pub(super) fn send(rec: &RecordingStream, root: &BlueprintNode) -> Result<(), RecordingError> {
    let blueprint_id = StoreId::random(StoreKind::Blueprint, APPLICATION_ID);
    let bp = RecordingStreamBuilder::from_store_id(&blueprint_id)
        .enabled(true)
        .send_properties(false)
        .buffered()?;
    let collected = Collected::default();
    bp.set_sink(Box::new(collected.clone()));
    bp.set_time_sequence("blueprint", 0);
    root.log(&bp, ROOT_ID)?;
    bp.log(
        "viewport",
        &ViewportBlueprint::new()
            .with_root_container(RootContainer(ROOT_ID.into()))
            .with_auto_layout(false)
            .with_auto_views(false),
    )?;
    bp.flush_blocking()
        .map_err(|e| RecordingError::Sink(e.to_string()))?;
    drop(bp);
    let messages = collected.take();
    rec.send_blueprint(
        messages,
        BlueprintActivationCommand {
            blueprint_id,
            make_active: true,
            make_default: true,
        },
    );
    Ok(())
}

/// A map study's layout: its views in a grid, beside the summary at `/summary`.
pub(super) fn grid_beside_summary(views: Vec<BlueprintNode>) -> BlueprintNode {
    BlueprintNode::container(
        ContainerKind::Horizontal,
        vec![
            BlueprintNode::container(ContainerKind::Grid, views),
            BlueprintNode::view("TextDocument", "summary", vec!["/summary".to_string()]),
        ],
    )
}
