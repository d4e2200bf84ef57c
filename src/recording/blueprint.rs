//! The default blueprint of a recording, built as a tree of views and containers and logged
//! as Rerun's blueprint records into a blueprint store that is then activated.

use rerun::external::re_log_types::{BlueprintActivationCommand, StoreId, StoreKind};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, ViewBlueprint, ViewContents, ViewportBlueprint, VisibleTimeRanges,
};
use rerun::external::re_sdk_types::blueprint::components::{
    ContainerKind, IncludedContent, QueryExpression, RootContainer, ViewClass,
};
use rerun::external::re_sdk_types::datatypes::{
    TimeInt, TimeRange, TimeRangeBoundary, VisibleTimeRange,
};
use rerun::external::uuid::Uuid;
use rerun::{EntityPath, RecordingStream, RecordingStreamBuilder};

use super::{RecordingError, APPLICATION_ID, STEP_TIMELINE, TIME_TIMELINE};

/// A view of the blueprint under construction.
pub(super) struct ViewSpec {
    id: Uuid,
    class: &'static str,
    name: String,
    contents: Vec<String>,
    /// Entities shown over the whole timeline up to the cursor.
    trails: Vec<String>,
}

/// A container of the blueprint under construction.
pub(super) struct ContainerSpec {
    id: Uuid,
    kind: ContainerKind,
    children: Vec<Node>,
}

pub(super) enum Node {
    View(ViewSpec),
    Container(ContainerSpec),
}

impl Node {
    pub(super) fn view(
        class: &'static str,
        name: impl Into<String>,
        contents: Vec<String>,
    ) -> Node {
        Node::View(ViewSpec {
            id: Uuid::new_v4(),
            class,
            name: name.into(),
            contents,
            trails: Vec::new(),
        })
    }

    pub(super) fn container(kind: ContainerKind, children: Vec<Node>) -> Node {
        Node::Container(ContainerSpec {
            id: Uuid::new_v4(),
            kind,
            children,
        })
    }

    /// Shows `entities` of this view over the whole timeline up to the time cursor (paths that
    /// grow), not only at the cursor.
    pub(super) fn with_trails(mut self, entities: Vec<String>) -> Node {
        if let Node::View(v) = &mut self {
            v.trails = entities;
        }
        self
    }

    fn id(&self) -> Uuid {
        match self {
            Node::View(v) => v.id,
            Node::Container(c) => c.id,
        }
    }

    fn path(&self) -> String {
        match self {
            Node::View(v) => format!("view/{}", v.id),
            Node::Container(c) => format!("container/{}", c.id),
        }
    }

    fn log(&self, bp: &RecordingStream) -> Result<(), RecordingError> {
        match self {
            Node::View(v) => {
                let path = self.path();
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
                        v.id,
                        &EntityPath::from(entity.as_str()),
                    );
                    bp.log(at, &ranges)?;
                }
            }
            Node::Container(c) => {
                for child in &c.children {
                    child.log(bp)?;
                }
                bp.log(
                    self.path(),
                    &ContainerBlueprint::new(c.kind).with_contents(
                        c.children
                            .iter()
                            .map(|child| IncludedContent(child.path().into())),
                    ),
                )?;
            }
        }
        Ok(())
    }
}

/// Sends the blueprint with root container `root` through `rec` (as Rerun's own SDKs do: a
/// blueprint store logged in full, then an activation command making it the active and default
/// one).
pub(super) fn send(rec: &RecordingStream, root: &Node) -> Result<(), RecordingError> {
    let blueprint_id = StoreId::random(StoreKind::Blueprint, APPLICATION_ID);
    let (bp, storage) = RecordingStreamBuilder::from_store_id(&blueprint_id)
        .enabled(true)
        .send_properties(false)
        .memory()?;
    bp.set_time_sequence("blueprint", 0);
    root.log(&bp)?;
    bp.log(
        "viewport",
        &ViewportBlueprint::new()
            .with_root_container(RootContainer(root.id().into()))
            .with_auto_layout(false)
            .with_auto_views(false),
    )?;
    let messages = storage.take();
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
