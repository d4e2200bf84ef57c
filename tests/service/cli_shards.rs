//! `geomint study KIND --shard i/n` and `geomint study merge` for every kind of study: the
//! merged parts give the whole study's document, bit for bit apart from wall times, and merge
//! refuses parts that do not belong together.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::{json, Value};

use crate::server;

fn geomint(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_geomint"))
        .args(args)
        .env_remove("GEOMINT_MAX_STEPS")
        .output()
        .unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn succeeded(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    stderr
}

/// A written document, read with correctly rounded floats so that numbers compare bit for bit.
fn read(p: &Path) -> Value {
    geomint::api::json::parse_json(&std::fs::read(p).unwrap()).unwrap()
}

/// `doc` without what measures time, which no two runs share: wall times, timings and the
/// cost-versus-error lines fitted to them.
fn untimed(mut doc: Value) -> Value {
    fn strip(v: &mut Value) {
        match v {
            Value::Object(map) => {
                for key in [
                    "wall_ms",
                    "timings_ms",
                    "reference_ms",
                    "slope",
                    "intercept",
                ] {
                    map.remove(key);
                }
                map.values_mut().for_each(strip);
            }
            Value::Array(items) => items.iter_mut().for_each(strip),
            _ => {}
        }
    }
    strip(&mut doc);
    doc
}

/// Runs `spec` as `kind` whole and as `shards` shards, merges the shards given in reverse
/// order, and returns the whole document, the merged one and the part files.
fn whole_and_merged(
    dir: &Path,
    kind: &str,
    spec: &Value,
    shards: usize,
) -> (Value, Value, Vec<PathBuf>) {
    let spec_path = dir.join(format!("{kind}.json"));
    std::fs::write(&spec_path, serde_json::to_vec(spec).unwrap()).unwrap();
    let whole = dir.join(format!("{kind}-whole.json"));
    succeeded(&geomint(&[
        "study",
        kind,
        path(&spec_path),
        "-o",
        path(&whole),
    ]));
    let parts: Vec<PathBuf> = (0..shards)
        .map(|i| {
            let part = dir.join(format!("{kind}-part-{i}.json"));
            let shard = format!("{i}/{shards}");
            let log = succeeded(&geomint(&[
                "study",
                kind,
                path(&spec_path),
                "--shard",
                &shard,
                "-o",
                path(&part),
            ]));
            assert!(log.contains(&format!("cells of the {kind} study")), "{log}");
            assert_eq!(read(&part)["study"], kind);
            part
        })
        .collect();
    let merged = dir.join(format!("{kind}-merged.json"));
    let mut args = vec!["study", "merge"];
    args.extend(parts.iter().rev().map(|p| path(p)));
    args.extend(["-o", path(&merged)]);
    let log = succeeded(&geomint(&args));
    assert!(log.contains("merged "), "{log}");
    (read(&whole), read(&merged), parts)
}

#[test]
fn every_kind_of_study_merges_from_its_shards_to_its_whole_document() {
    let dir = server::scratch_dir("cli-shards");
    std::fs::create_dir_all(&dir).unwrap();
    let studies = [
        (
            "stability",
            json!({"methods": ["csv1", "rk4"], "omega": 1.0,
                "gamma": {"min": 0.0, "max": 1.0, "n": 5}, "h": {"min": 0.1, "max": 1.0, "n": 4}}),
        ),
        (
            "convergence",
            json!({"system": "harmonic_oscillator", "params": {"omega": 2, "gamma": 0.1},
                "methods": ["rk4", "csv1"], "h": [0.1, 0.05, 0.025], "t_end": 5}),
        ),
        (
            "work-precision",
            json!({"system": "harmonic_oscillator", "params": {"omega": 2.0, "gamma": 0.1},
                "q0": [1.0], "p0": [0.0], "t_end": 20, "samples": 40,
                "runs": [{"method": "csv1", "h": [0.1, 0.05]},
                         {"method": {"id": "kahan_li_8", "base": "csv1"}, "h": [0.5, 0.25]}]}),
        ),
        ("energy-map", json!({"nx": 5, "ny": 4, "t_max": 20})),
        (
            "sweep",
            json!({"system": "pendulum", "methods": ["modin_3s", "heun"], "h": 0.1,
                "t_end": 20, "every": 5,
                "axes": [{"name": "params.gamma", "min": 0.0, "max": 0.5, "n": 5}]}),
        ),
    ];
    let mut parts_of = Vec::new();
    for (kind, spec) in &studies {
        let (whole, merged, parts) = whole_and_merged(&dir, kind, spec, 3);
        // Untimed, the two are the same bit for bit: every error, verdict and final state.
        assert_eq!(untimed(merged.clone()), untimed(whole.clone()), "{kind}");
        assert!(untimed(whole.clone()) != Value::Null);
        parts_of.push((kind, parts));
    }
    // A merged document's wall time is its parts', summed in shard order.
    let (_, sweep_parts) = &parts_of[4];
    let summed: f64 = sweep_parts
        .iter()
        .map(|p| read(p)["wall_ms"].as_f64().unwrap())
        .sum();
    let merged_sweep = read(&dir.join("sweep-merged.json"));
    assert_eq!(merged_sweep["wall_ms"].as_f64(), Some(summed));

    // An energy map's runs are bounded by its total alone (100 steps each here), in shards as
    // whole.
    let map_spec = dir.join("energy-map.json");
    let small = dir.join("energy-map-small-limit.json");
    for args in [vec![], vec!["--shard", "0/2"]] {
        let mut all = vec!["study", "energy-map", path(&map_spec), "--max-steps", "50"];
        all.extend(args);
        all.extend(["-o", path(&small)]);
        succeeded(&geomint(&all));
    }

    // Kinds with a recording write it from the merged parts as from the whole study.
    let (_, stability_parts) = &parts_of[0];
    let rrd = dir.join("stability-merged.rrd");
    let mut args = vec!["study", "merge"];
    args.extend(stability_parts.iter().map(|p| path(p)));
    args.extend(["-o", path(&rrd)]);
    succeeded(&geomint(&args));
    let bytes = std::fs::read(&rrd).unwrap();
    assert_eq!(&bytes[..4], b"RRF2");

    // Refused with exit code 2 and the reason: a part of another kind of study, a shard missing,
    // a merge into a recording of a kind without one.
    let refused = |parts: &[&PathBuf], extra: &[&str], says: &str| {
        let mut args = vec!["study", "merge"];
        args.extend(parts.iter().map(|p| path(p)));
        args.extend(extra);
        let out = geomint(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(says), "{says}: {stderr}");
    };
    let (stability, convergence) = (&parts_of[0].1, &parts_of[1].1);
    refused(
        &[&convergence[0], &stability[1], &convergence[2]],
        &[],
        "belongs to another study",
    );
    refused(
        &[&convergence[0], &convergence[2]],
        &[],
        "missing shards [1] of 3",
    );
    let no_rrd = dir.join("convergence.rrd");
    refused(
        &convergence.iter().collect::<Vec<_>>(),
        &["-o", path(&no_rrd)],
        "no recording",
    );
    assert!(!no_rrd.exists());

    // Parts of a sweep written before parts carried their study and request still merge.
    let bare: Vec<PathBuf> = sweep_parts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut part = read(p);
            let fields = part.as_object_mut().unwrap();
            fields.remove("study");
            fields.remove("request");
            let bare = dir.join(format!("bare-{i}.json"));
            std::fs::write(&bare, serde_json::to_vec(&part).unwrap()).unwrap();
            bare
        })
        .collect();
    let merged = dir.join("bare-merged.json");
    let mut args = vec!["study", "merge"];
    args.extend(bare.iter().map(|p| path(p)));
    args.extend(["-o", path(&merged)]);
    succeeded(&geomint(&args));
    assert_eq!(
        untimed(read(&merged)),
        untimed(read(&dir.join("sweep-whole.json")))
    );
    // A part of a study this version does not know is refused by name.
    let mut strange = read(&convergence[0]);
    strange["study"] = json!("lyapunov-spectrum");
    let strange_path = dir.join("strange.json");
    std::fs::write(&strange_path, serde_json::to_vec(&strange).unwrap()).unwrap();
    refused(&[&strange_path], &[], "unknown study `lyapunov-spectrum`");
    let _ = std::fs::remove_dir_all(&dir);
}
