//! The stability routes over real HTTP: each test starts `app(state)` on a loopback port and
//! talks to it with reqwest, and checks the answers against the core's `stability` module.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use crate::decoded;
use crate::server;
use decoded::Decoded;
use geomint::core::methods::{Base, Method, MethodId};
use geomint::core::stability::{self, Relation, StabilityAxis};
use rerun::components::{ImageBuffer, TensorData};
use rerun::external::re_sdk_types::datatypes::TensorBuffer;
use rerun::{SegmentationImage, Tensor};

use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, post_json as post, start, Server};

pub(crate) const MAP: &str = "/api/v1/stability";
pub(crate) const POINT: &str = "/api/v1/stability/point";

/// A test configuration: a safety time limit so that no run outlives its test.
pub(crate) fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(15),
        ..Config::default()
    }
}

/// Posts raw bytes and returns (status, error object), checking the error shape.
pub(crate) async fn post_error(
    server: &Server,
    path: &str,
    body: String,
    content_type: &str,
) -> (u16, Value) {
    let response = client()
        .post(server.url(path))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    assert_eq!(
        response.headers()["content-type"],
        "application/json",
        "status {status}"
    );
    let error = response.json::<Value>().await.unwrap()["error"].clone();
    let keys: BTreeSet<&str> = error
        .as_object()
        .expect("an error object")
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(keys, BTreeSet::from(["code", "message", "field"]));
    assert!(!error["message"].as_str().unwrap().is_empty());
    (status, error)
}

pub(crate) fn axis_json(a: StabilityAxis) -> Value {
    json!({"min": a.min, "max": a.max, "n": a.n})
}

/// A grid of booleans as rows.
pub(crate) fn bool_rows(cells: &[bool], cols: usize) -> Value {
    Value::from(
        cells
            .chunks(cols)
            .map(|r| Value::from(r.to_vec()))
            .collect::<Vec<_>>(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn maps_are_rows_by_columns_and_equal_the_core_bit_for_bit() {
    let server = start(config()).await;
    // Not square, so that a transposition shows; csv2 is undefined at γh = 2, which this grid
    // hits at (γ, h) = (4, 0.5) and (2, 1).
    let gamma = StabilityAxis {
        min: 0.0,
        max: 4.0,
        n: 9,
    };
    let h = StabilityAxis {
        min: 0.0,
        max: 1.0,
        n: 5,
    };
    let omega = 3.51;
    let body = json!({
        "methods": ["csv1", {"id": "triple_jump", "base": "csv1"}, "rk4", "csv2", "implicit_midpoint"],
        "omega": omega,
        "gamma": axis_json(gamma),
        "h": axis_json(h),
    });
    let started = Instant::now();
    let (status, doc) = post(&server, MAP, &body).await;
    println!("5 maps of 9×5: {:?}", started.elapsed());
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["omega"].as_f64(), Some(omega));
    assert_eq!(doc["gamma"], axis_json(gamma));
    assert_eq!(doc["h"], axis_json(h));
    let choices = [
        Method::new(MethodId::Csv1),
        Method::triple_jump(Base::Csv1),
        Method::new(MethodId::Rk4),
        Method::new(MethodId::Csv2),
        Method::new(MethodId::ImplicitMidpoint),
    ];
    let maps = doc["maps"].as_array().unwrap();
    assert_eq!(maps.len(), choices.len());
    let mut nulls = 0;
    for (choice, got) in choices.iter().zip(maps) {
        let core = stability::map(choice, omega, gamma, h).unwrap();
        let label = choice.label();
        assert_eq!(got["method"], label.as_str());
        // h.n rows of gamma.n columns in every grid.
        for key in ["spectral_radius", "stable", "analytic", "printed"] {
            if got[key].is_null() {
                continue;
            }
            let rows = got[key].as_array().unwrap();
            assert_eq!(rows.len(), h.n, "{label} {key}");
            for row in rows {
                assert_eq!(row.as_array().unwrap().len(), gamma.n, "{label} {key}");
            }
        }
        for (k, &expected) in core.spectral_radius.iter().enumerate() {
            let cell = &got["spectral_radius"][k / gamma.n][k % gamma.n];
            if expected.is_finite() {
                assert_eq!(
                    cell.as_f64().map(f64::to_bits),
                    Some(expected.to_bits()),
                    "{label} cell {k}: {cell} vs {expected:e}"
                );
            } else {
                assert!(cell.is_null(), "{label} cell {k}: {cell} for {expected}");
                nulls += 1;
            }
        }
        assert_eq!(got["stable"], bool_rows(&core.stable, gamma.n), "{label}");
        let has_relation = matches!(choice.id(), MethodId::Csv1 | MethodId::Csv2);
        assert_eq!(core.analytic.is_some(), has_relation, "{label}");
        for (key, grid, count, core_count) in [
            (
                "analytic",
                &core.analytic,
                "disagreements",
                core.disagreements,
            ),
            (
                "printed",
                &core.printed,
                "printed_disagreements",
                core.printed_disagreements,
            ),
        ] {
            match grid {
                Some(cells) => {
                    assert_eq!(got[key], bool_rows(cells, gamma.n), "{label} {key}");
                    assert_eq!(got[count].as_u64(), Some(core_count as u64), "{label}");
                }
                None => {
                    assert!(got[key].is_null(), "{label} {key}");
                    assert!(got[count].is_null(), "{label} {count}");
                }
            }
        }
        // A zero step is the identity.
        assert!(got["spectral_radius"][0]
            .as_array()
            .unwrap()
            .iter()
            .all(|r| r.as_f64() == Some(1.0)));
    }
    assert_eq!(nulls, 2, "csv2 is undefined at the two cells with γh = 2");
    assert!(maps[3]["spectral_radius"][2][8].is_null());
    assert!(maps[3]["spectral_radius"][4][4].is_null());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_study_comes_as_a_recording_of_tensors_and_verdict_images() {
    let server = start(config()).await;
    let body = json!({
        "methods": ["csv1", "csv2", "rk4"],
        "omega": 3.51,
        "gamma": {"min": 0, "max": 4, "n": 9},
        "h": {"min": 0, "max": 1, "n": 5},
    });
    let (status, doc) = post(&server, MAP, &body).await;
    assert_eq!(status, 200, "{doc}");
    let response = client()
        .post(server.url(&format!("{MAP}?format=rrd")))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(
        response.headers()["content-type"],
        "application/octet-stream"
    );
    assert!(response.headers()["content-disposition"]
        .to_str()
        .unwrap()
        .starts_with("attachment"));
    let d = Decoded::of(&response.bytes().await.unwrap());
    assert_eq!(d.application_ids, BTreeSet::from(["geomint".to_string()]));
    assert_eq!(d.activations, 1, "a default blueprint");
    // `/__properties` holds the recording's name and start time.
    let mut expected: BTreeSet<String> = ["/", "/__properties", "/spec"].map(String::from).into();
    for m in ["csv1", "csv2", "rk4"] {
        for part in ["spectral_radius", "verdict", "summary"] {
            expected.insert(format!("/{m}/{part}"));
        }
    }
    assert_eq!(d.chunks.keys().cloned().collect::<BTreeSet<_>>(), expected);

    let mut disagreeing = 0;
    for map in doc["maps"].as_array().unwrap() {
        let m = map["method"].as_str().unwrap();
        // The tensor: h rows × γ columns, equal to the JSON bit for bit, NaN for null.
        let tensors: Vec<TensorData> = d.static_batch(
            &format!("/{m}/spectral_radius"),
            Tensor::descriptor_data().component,
        );
        let tensor = &tensors[0];
        assert_eq!(tensor.shape(), [5, 9], "{m}");
        let names: Vec<String> = (0..2)
            .map(|k| tensor.dim_name(k).unwrap().to_string())
            .collect();
        assert_eq!(names, ["h", "gamma"]);
        let TensorBuffer::F64(radii) = &tensor.buffer else {
            panic!("{m}: f64 radii")
        };
        let json_radii: Vec<&Value> = map["spectral_radius"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|r| r.as_array().unwrap())
            .collect();
        assert_eq!(radii.len(), json_radii.len());
        for (r, j) in radii.iter().zip(json_radii) {
            match j.as_f64() {
                Some(x) => assert_eq!(r.to_bits(), x.to_bits(), "{m}"),
                None => assert!(r.is_nan(), "{m}: {r} for null"),
            }
        }
        // The verdict image: classes 1 stable, 2 unstable, 3/4 where the relation disagrees.
        let buffers: Vec<ImageBuffer> = d.static_batch(
            &format!("/{m}/verdict"),
            SegmentationImage::descriptor_buffer().component,
        );
        let classes: &[u8] = &buffers[0].0;
        assert_eq!(classes.len(), 45, "{m}");
        let cells = map["stable"]
            .as_array()
            .unwrap()
            .iter()
            .enumerate()
            .flat_map(|(k, row)| {
                row.as_array()
                    .unwrap()
                    .iter()
                    .enumerate()
                    .map(move |(j, s)| (k, j, s.as_bool().unwrap()))
            });
        for ((k, j, stable), &class) in cells.zip(classes) {
            let analytic = map["analytic"][k][j].as_bool();
            let want = match (stable, analytic) {
                (true, Some(false)) => 3,
                (false, Some(true)) => 4,
                (true, _) => 1,
                (false, _) => 2,
            };
            assert_eq!(class, want, "{m} cell ({k}, {j})");
            disagreeing += u32::from(class >= 3);
        }
    }
    println!("cells where the corrected relation disagrees (boundary included): {disagreeing}");

    let (status, error) = post_error(
        &server,
        &format!("{MAP}?format=png"),
        body.to_string(),
        "application/json",
    )
    .await;
    assert_eq!(status, 422);
    assert_eq!(error["field"], "format");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn csv1_agrees_with_the_corrected_relation_not_the_printed_one() {
    let server = start(config()).await;
    let body = json!({
        "methods": ["csv1"],
        "omega": 3.51,
        "gamma": {"min": 0, "max": 3.5, "n": 100},
        "h": {"min": 0, "max": 1, "n": 100},
    });
    let started = Instant::now();
    let (status, doc) = post(&server, MAP, &body).await;
    println!("csv1 100×100 map: {:?}", started.elapsed());
    assert_eq!(status, 200, "{doc}");
    let map = &doc["maps"][0];
    let unstable = map["stable"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap())
        .filter(|s| !s.as_bool().unwrap())
        .count();
    println!(
        "csv1: {unstable} unstable cells, disagreements {}, printed {}",
        map["disagreements"], map["printed_disagreements"]
    );
    assert!(
        unstable > 100,
        "only {unstable} unstable cells: no unstable region"
    );
    assert_eq!(map["disagreements"], 0);
    let printed = map["printed_disagreements"].as_u64().unwrap();
    assert!(
        printed > 100,
        "printed relation disagrees in only {printed}"
    );
    // The corrected relation is hω ≤ 2 whatever γ: row k (h = k/99) is stable iff it holds.
    for (k, row) in map["analytic"].as_array().unwrap().iter().enumerate() {
        let expected = 0.5 * (k as f64 / 99.0).powi(2) * 3.51f64.powi(2) <= 2.0;
        assert!(
            row.as_array()
                .unwrap()
                .iter()
                .all(|c| c.as_bool() == Some(expected)),
            "row {k}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn point_answers_match_the_core_and_the_exact_flow() {
    let server = start(config()).await;
    let (omega, gamma, h) = (3.51f64, 0.5f64, 0.2f64);
    let (status, doc) = post(
        &server,
        POINT,
        &json!({"method": "csv1", "omega": omega, "gamma": gamma, "h": h}),
    )
    .await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["method"], "csv1");
    let a = &doc["analysis"];
    let det = a["method"]["det"].as_f64().unwrap();
    println!("csv1 det − e^(−2γh) = {:e}", det - (-2.0 * gamma * h).exp());
    assert!((det - (-2.0 * gamma * h).exp()).abs() < 1e-13, "det {det}");
    let beta = (omega * omega - gamma * gamma).sqrt();
    let exact_half_trace = 0.5 * a["exact"]["trace"].as_f64().unwrap();
    assert!(
        (exact_half_trace - (-gamma * h).exp() * (beta * h).cos()).abs() < 1e-14,
        "½tr {exact_half_trace}"
    );
    // Everything equals the core's analysis.
    let core = stability::analyse(&Method::new(MethodId::Csv1), omega, gamma, h).unwrap();
    assert_eq!(*a, serde_json::to_value(&core).unwrap());
    assert_eq!(a["stable"], true);
    assert_eq!(doc["analytic"], json!({"corrected": true, "printed": true}));

    // Where the printed relation (3.17) is wrong: stable, as the corrected one says.
    let (_, doc) = post(
        &server,
        POINT,
        &json!({"method": {"id": "csv1"}, "omega": omega, "gamma": 3.0, "h": 0.5}),
    )
    .await;
    assert_eq!(doc["analysis"]["stable"], true, "{doc}");
    let radius = doc["analysis"]["method"]["spectral_radius"]
        .as_f64()
        .unwrap();
    assert!(radius <= 1.0, "spectral radius {radius}");
    assert_eq!(
        doc["analytic"],
        json!({"corrected": true, "printed": false})
    );
    assert_eq!(
        stability::analytic_stable(MethodId::Csv1, Relation::Printed, omega, 3.0, 0.5),
        Some(false)
    );
    // Past hω = 2 csv1 is unstable.
    let (_, doc) = post(
        &server,
        POINT,
        &json!({"method": "csv1", "omega": omega, "gamma": 1.0, "h": 0.6}),
    )
    .await;
    assert_eq!(doc["analysis"]["stable"], false, "{doc}");
    assert_eq!(doc["analytic"]["corrected"], false);

    // A method without analytic relations, in object form.
    let (status, doc) = post(
        &server,
        POINT,
        &json!({"method": {"id": "triple_jump", "base": "csv2"}, "omega": omega, "gamma": gamma, "h": h}),
    )
    .await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["method"], "triple_jump(csv2)");
    assert!(doc["analytic"].is_null());
    let core = stability::analyse(&Method::triple_jump(Base::Csv2), omega, gamma, h).unwrap();
    assert_eq!(doc["analysis"], serde_json::to_value(&core).unwrap());

    // csv2 is undefined at γh = 2 (a null cell in its map): the point is refused, naming h.
    let (status, doc) = post(
        &server,
        POINT,
        &json!({"method": "csv2", "omega": omega, "gamma": 4.0, "h": 0.5}),
    )
    .await;
    assert_eq!(status, 422, "{doc}");
    assert_eq!(doc["error"]["code"], "invalid_value");
    assert_eq!(doc["error"]["field"], "h");
    // Just beside it, it is defined and unstable.
    let (status, doc) = post(
        &server,
        POINT,
        &json!({"method": "csv2", "omega": omega, "gamma": 4.0, "h": 0.49}),
    )
    .await;
    assert_eq!(status, 200, "{doc}");
    let radius = doc["analysis"]["method"]["spectral_radius"]
        .as_f64()
        .unwrap();
    println!("csv2 spectral radius at γh = 1.96: {radius}");
    assert!(radius > 1.0, "{radius}");
    assert_eq!(doc["analysis"]["stable"], false);
}
