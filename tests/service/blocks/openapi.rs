//! The published OpenAPI document: references resolve, optional members admit null, requests
//! are closed objects, exclusive members and links are stated.

use geomint::http::openapi::document;
use geomint::http::paths;
use serde_json::{json, Value};

/// Every schema object in `value`, with its JSON pointer.
fn walk<'a>(value: &'a Value, at: String, out: &mut Vec<(String, &'a Value)>) {
    match value {
        Value::Object(map) => {
            out.push((at.clone(), value));
            for (k, v) in map {
                walk(v, format!("{at}/{k}"), out);
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                walk(v, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
}

#[test]
fn every_reference_resolves_and_every_alternative_is_a_schema() {
    let doc = document();
    let mut nodes = Vec::new();
    walk(&doc, String::new(), &mut nodes);
    for (at, node) in &nodes {
        if let Some(target) = node.get("$ref").and_then(Value::as_str) {
            let pointer = target.strip_prefix('#').expect("a local reference");
            assert!(
                doc.pointer(pointer).is_some(),
                "{at}: {target} does not resolve"
            );
        }
        for key in ["oneOf", "anyOf", "allOf"] {
            if let Some(branches) = node.get(key).and_then(Value::as_array) {
                assert!(
                    branches.iter().all(Value::is_object),
                    "{at}/{key}: {branches:?}"
                );
            }
        }
    }
}

#[test]
fn optional_members_admit_null_and_required_ones_do_not() {
    let doc = document();
    let simulate = &doc["components"]["schemas"]["SimulateRequest"];
    assert_eq!(simulate["properties"]["h"]["type"], json!("number"));
    assert_eq!(
        simulate["properties"]["jacobian_defect"]["type"],
        json!(["boolean", "null"])
    );
    let output = &doc["components"]["schemas"]["OutputOptions"];
    assert_eq!(
        output["properties"]["every"]["type"],
        json!(["integer", "null"])
    );
    assert_eq!(output["properties"]["every"]["format"], json!("uint64"));
    assert_eq!(output["properties"]["every"]["maximum"], json!(u64::MAX));
    let map = &doc["components"]["schemas"]["EnergyMapRequest"]["properties"]["method"];
    assert_eq!(map["anyOf"][1], json!({"type": "null"}));
}

#[test]
fn request_objects_are_closed_and_answers_open() {
    let schemas = &document()["components"]["schemas"];
    for name in [
        "SimulateRequest",
        "ConvergenceRequest",
        "SweepRequest",
        "AxisRequest",
        "RunSpec",
    ] {
        assert_eq!(
            schemas[name]["additionalProperties"],
            json!(false),
            "{name}"
        );
    }
    for branch in schemas["DampingEntry"]["oneOf"].as_array().unwrap() {
        assert_eq!(branch["additionalProperties"], json!(false));
    }
    // Constraint fragments stay open, and so do the answers.
    assert!(schemas["SimulateRequest"]["oneOf"][0]
        .get("additionalProperties")
        .is_none());
    assert!(schemas["SimulationDocument"]
        .get("additionalProperties")
        .is_none());
}

#[test]
fn exclusive_members_and_links_are_stated() {
    let doc = document();
    let schemas = &doc["components"]["schemas"];
    let one_of = |name: &str| -> Vec<Value> {
        schemas[name]["oneOf"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b["required"][0].clone())
            .collect()
    };
    assert_eq!(
        one_of("SimulateRequest"),
        [json!("methods"), json!("method")]
    );
    assert_eq!(one_of("RunSpec"), [json!("h"), json!("tolerance")]);
    assert_eq!(
        one_of("SystemDefinition"),
        [json!("potential"), json!("hamiltonian")]
    );
    assert_eq!(
        schemas["ConvergenceRequest"]["not"]["allOf"][1]["required"],
        json!(["charts"])
    );
    let created = &doc["paths"][paths::RECORDINGS]["post"]["responses"]["201"]["links"];
    for op in ["get_recording", "recording_samples", "delete_recording"] {
        assert_eq!(created[op]["operationId"], json!(op));
        assert_eq!(created[op]["parameters"]["id"], json!("$response.body#/id"));
    }
}
