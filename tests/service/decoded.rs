//! Recordings read back with Rerun's own decoder (`re_log_encoding`, the crate the viewer
//! uses), shared by the tests that check `.rrd` files.

use std::collections::{BTreeMap, BTreeSet};
use std::io::Cursor;

use re_log_encoding::DecoderApp;
use rerun::external::re_log_types::{LogMsg, StoreKind};
use rerun::log::Chunk;
use rerun::{Component, ComponentIdentifier, Scalars};

/// What a decoded `.rrd` holds.
#[derive(Default)]
pub struct Decoded {
    pub application_ids: BTreeSet<String>,
    pub recording_stores: BTreeSet<String>,
    pub blueprint_stores: BTreeSet<String>,
    pub activations: usize,
    /// Recording chunks by entity path.
    pub chunks: BTreeMap<String, Vec<Chunk>>,
    /// Blueprint entity paths.
    pub blueprint_entities: BTreeSet<String>,
}

impl Decoded {
    pub fn of(bytes: &[u8]) -> Decoded {
        Decoded::try_of(bytes).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The recording in `bytes`, or what does not decode (for example a file still being
    /// written).
    pub fn try_of(bytes: &[u8]) -> Result<Decoded, String> {
        let mut out = Decoded::default();
        let decoder = DecoderApp::decode_eager(Cursor::new(bytes))
            .map_err(|e| format!("not an rrd stream: {e}"))?;
        for msg in decoder {
            match msg.map_err(|e| format!("a message does not decode: {e}"))? {
                LogMsg::SetStoreInfo(info) => {
                    let id = &info.info.store_id;
                    out.application_ids.insert(id.application_id().to_string());
                    let name = id.recording_id().to_string();
                    match id.kind() {
                        StoreKind::Recording => out.recording_stores.insert(name),
                        StoreKind::Blueprint => out.blueprint_stores.insert(name),
                    };
                }
                LogMsg::ArrowMsg(store, arrow) => {
                    let chunk = Chunk::from_arrow_msg(&arrow)
                        .map_err(|e| format!("a chunk does not decode: {e}"))?;
                    let path = chunk.entity_path().to_string();
                    match store.kind() {
                        StoreKind::Recording => out.chunks.entry(path).or_default().push(chunk),
                        StoreKind::Blueprint => {
                            out.blueprint_entities.insert(path);
                        }
                    }
                }
                LogMsg::BlueprintActivationCommand(_) => out.activations += 1,
            }
        }
        Ok(out)
    }

    /// Temporal rows of an entity.
    pub fn rows(&self, path: &str) -> usize {
        self.chunks[path]
            .iter()
            .filter(|c| !c.is_static())
            .map(|c| c.num_rows())
            .sum()
    }

    /// Timeline names of an entity's temporal chunks.
    pub fn timelines(&self, path: &str) -> BTreeSet<String> {
        self.chunks[path]
            .iter()
            .filter(|c| !c.is_static())
            .flat_map(|c| c.timelines().keys().map(|k| k.to_string()))
            .collect()
    }

    /// (step, value) of every scalar row of an entity, in step order.
    pub fn scalars(&self, path: &str) -> Vec<(i64, f64)> {
        let component = Scalars::descriptor_scalars().component;
        let mut rows = Vec::new();
        for chunk in self.chunks[path].iter().filter(|c| !c.is_static()) {
            let steps = chunk.timelines()[&"step".into()].times_raw().to_vec();
            let values: Vec<f64> = chunk
                .iter_slices::<f64>(component)
                .map(|s| {
                    assert_eq!(s.len(), 1);
                    s[0]
                })
                .collect();
            assert_eq!(steps.len(), values.len());
            rows.extend(steps.into_iter().zip(values));
        }
        rows.sort_by_key(|r| r.0);
        rows
    }
}

impl Decoded {
    /// The first batch of `component` in an entity's static chunks.
    pub fn static_batch<C: Component>(&self, path: &str, component: ComponentIdentifier) -> Vec<C> {
        self.chunks[path]
            .iter()
            .filter(|c| c.is_static())
            .find_map(|c| c.component_batch::<C>(component, 0))
            .unwrap_or_else(|| panic!("{path} has a static {component}"))
            .expect("the batch decodes")
    }

    /// The recording's name, as its properties (`/__properties`) hold it.
    pub fn recording_name(&self) -> String {
        let names: Vec<rerun::components::Name> = self.static_batch(
            "/__properties",
            rerun::archetypes::RecordingInfo::descriptor_name().component,
        );
        names[0].as_str().to_string()
    }

    /// The recording's entity paths, without Rerun's own (`/__properties`).
    pub fn entity_paths(&self) -> BTreeSet<String> {
        self.chunks
            .keys()
            .filter(|p| !p.starts_with("/__"))
            .cloned()
            .collect()
    }
}

/// The entities of a one-degree-of-freedom simulation recording: `/`, `/spec` and, per method
/// entity name, its energy, force evaluations, phase portrait and world.
pub fn simulation_entities<S: AsRef<str>>(methods: &[S]) -> BTreeSet<String> {
    let mut expected: BTreeSet<String> = ["/", "/spec"].map(String::from).into();
    for m in methods {
        for e in [
            "energy",
            "force_evaluations",
            "phase/0/point",
            "phase/0/path",
            "world/bodies",
            "world/path",
        ] {
            expected.insert(format!("/{}/{e}", m.as_ref()));
        }
    }
    expected
}
