//! The OpenAPI 3 document of the service, generated from the handlers' `#[utoipa::path]`
//! annotations and the request and response types, so it follows the code; [`document`] adds
//! what the derive cannot say (members read as absent when `null`, fields that exclude each
//! other), so that a request valid by the document is one the readers accept.

use serde_json::{json, Map, Value};
use utoipa::OpenApi;

use super::answer::{AnyFormat, RecordFormat, StreamFormat};
use super::error::ErrorBody;
use super::handlers;
use super::recordings::{ListedRecording, RecordingCreated};
use crate::api::basins::BasinsRequest;
use crate::api::stability::{PointRequest, StabilityRequest};
use crate::api::studies::{ConvergenceRequest, EnergyMapRequest, WorkPrecisionRequest};
use crate::api::sweep::{Preset, SweepRequest};
use crate::api::system::SystemDefinition;
use crate::api::SimulateRequest;
use crate::core::methods::MethodInfo;
use crate::core::simulation::{SimulationDocument, StreamLine};
use crate::core::studies::basins::{BasinsDocument, BasinsLine};
use crate::core::studies::convergence::{ConvergenceDocument, ConvergenceLine};
use crate::core::studies::energy_map::{EnergyMapDocument, MapLine};
use crate::core::studies::stability::{PointDocument, StabilityDocument};
use crate::core::studies::sweep::{SweepDocument, SweepLine};
use crate::core::studies::work_precision::{StudyLine, WorkPrecisionDocument};
use crate::core::systems::SystemInfo;
use crate::recording::read::{RecordedDocument, RecordedRun};
use crate::store::recordings::{Origin, RecordingEntry};
use crate::store::systems::{StoredSystem, SystemEntry};

/// The document's info, shared schemas and tags; the paths come from the routes as
/// [`super::routes`] registers them.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "geomint",
        description = "Geometric numerical integration of damped Hamiltonian systems: structure-preserving \
            splittings and conformal symplectic methods beside Runge–Kutta baselines. Every error answers \
            `{\"error\": {\"code\", \"message\", \"field\"}}`."
    ),
    components(schemas(
        SimulateRequest,
        SimulationDocument,
        StreamLine,
        StabilityRequest,
        StabilityDocument,
        PointRequest,
        PointDocument,
        WorkPrecisionRequest,
        WorkPrecisionDocument,
        StudyLine,
        EnergyMapRequest,
        EnergyMapDocument,
        MapLine,
        ConvergenceRequest,
        ConvergenceDocument,
        ConvergenceLine,
        SweepRequest,
        SweepDocument,
        SweepLine,
        BasinsRequest,
        BasinsDocument,
        BasinsLine,
        Preset,
        SystemInfo,
        SystemEntry,
        StoredSystem,
        SystemDefinition,
        MethodInfo,
        ErrorBody,
        handlers::Health,
        ListedRecording,
        RecordingCreated,
        RecordingEntry,
        Origin,
        RecordedDocument,
        RecordedRun,
        AnyFormat,
        StreamFormat,
        RecordFormat,
    )),
    tags(
        (name = "catalog", description = "The systems and methods on offer, and the system definitions users store"),
        (name = "simulation", description = "Running simulations"),
        (name = "stability", description = "Linear stability analysis on the damped oscillator"),
        (name = "studies", description = "Work–precision studies (time against accuracy per method), convergence studies (error against step size, with the observed orders, per method and coordinate chart), energy-error maps across coordinate charts, and sweeps of any system over one or two axes"),
        (name = "recordings", description = "Rerun recordings (.rrd) of simulations, stored or uploaded, downloadable, and read back as samples"),
        (name = "jobs", description = "Studies submitted to run in the background: stored in parts as they finish, so that they survive restarts; their status, events and results"),
        (name = "service", description = "Health and this document"),
    )
)]
pub struct ApiDoc;

/// The document as a server whose clients without a token may do everything serves it.
pub fn document() -> Value {
    document_for(crate::access::Anonymous::All)
}

/// The document as served under `anonymous`, the policy for clients without a token.
pub fn document_for(anonymous: crate::access::Anonymous) -> Value {
    let (_, api) = super::routes(&super::Config::default()).split_for_parts();
    let mut doc = serde_json::to_value(api).unwrap_or_else(|e| json!({"error": e.to_string()}));
    // The readers take an explicit `null` for an optional member as its absence.
    null_as_absent(&mut doc);
    unsigned_ranges(&mut doc);
    close_requests(&mut doc);
    if let Some(schemas) = doc
        .pointer_mut("/components/schemas")
        .and_then(Value::as_object_mut)
    {
        exactly_one_of(schemas, "SimulateRequest", &["methods", "method"]);
        exactly_one_of(schemas, "SectionRequest", &["where", "period"]);
        not_both(schemas, "SectionRequest", ["where", "phase"]);
        not_both(schemas, "SectionRequest", ["period", "direction"]);
        at_least_one_of(
            schemas,
            "StopWhenRequest",
            &[
                "where",
                "lyapunov_max",
                "megno",
                "megno_mean",
                "fli",
                "sali",
                "gali",
            ],
        );
        only_with(schemas, "StopWhenRequest", "direction", "where");
        only_with(schemas, "StopWhenRequest", "count", "where");
        exactly_one_of(schemas, "SystemDefinition", &["potential", "hamiltonian"]);
        not_both(schemas, "SystemDefinition", ["hamiltonian", "mass"]);
        not_both(schemas, "ConvergenceRequest", ["chart", "charts"]);
        exactly_one_of(schemas, "RunSpec", &["h", "tolerance"]);
        exactly_one_of(schemas, "ReferenceRun", &["h", "tolerance"]);
        step_given_or_swept(schemas, "SweepRequest");
        optional_flattened(schemas, "RunColumns", "ChaosColumns");
    }
    let on_recording = ["get_recording", "recording_samples", "delete_recording"];
    link_created(&mut doc, super::paths::RECORDINGS, &["201"], &on_recording);
    link_created(
        &mut doc,
        super::paths::SYSTEMS,
        &["200", "201"],
        &["get_system", "delete_system"],
    );
    super::auth::document_security(&mut doc, anonymous);
    doc
}

/// Links the answers `statuses` of `POST path`, which carry the created item's `id`, to the
/// operations on that item (OpenAPI `links`, which clients and stateful testers follow).
fn link_created(doc: &mut Value, path: &str, statuses: &[&str], operations: &[&str]) {
    let path = path.replace('~', "~0").replace('/', "~1");
    for status in statuses {
        let at = format!("/paths/{path}/post/responses/{status}");
        if let Some(Value::Object(response)) = doc.pointer_mut(&at) {
            let links = operations.iter().map(|op| {
                let link = json!({"operationId": op, "parameters": {"id": "$response.body#/id"}});
                (op.to_string(), link)
            });
            response.insert("links".into(), Value::Object(links.collect()));
        }
    }
}

/// Calls `visit` on every object in `value`, each before its members, except under the members
/// named in `skip`.
fn for_each_object(
    value: &mut Value,
    skip: &[&str],
    visit: &mut impl FnMut(&mut Map<String, Value>),
) {
    match value {
        Value::Object(map) => {
            visit(map);
            for (key, child) in map.iter_mut() {
                if !skip.contains(&key.as_str()) {
                    for_each_object(child, skip, visit);
                }
            }
        }
        Value::Array(items) => items
            .iter_mut()
            .for_each(|item| for_each_object(item, skip, visit)),
        _ => {}
    }
}

/// Lets every optional member of every object schema in `value` be `null` (not inside examples,
/// which are data).
fn null_as_absent(value: &mut Value) {
    for_each_object(value, &["example", "examples"], &mut |map| {
        let required: Vec<String> = map
            .get("required")
            .and_then(Value::as_array)
            .map(|r| {
                r.iter()
                    .filter_map(Value::as_str)
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default();
        if let Some(Value::Object(properties)) = map.get_mut("properties") {
            for (name, member) in properties.iter_mut() {
                if !required.contains(name) {
                    admit_null(member);
                }
            }
        }
    });
}

/// Widens `schema` to admit `null` too.
fn admit_null(schema: &mut Value) {
    let null_schema = json!({"type": "null"});
    let Value::Object(map) = schema else { return };
    let has_null_branch = |k: &&str| {
        map.get(*k)
            .and_then(Value::as_array)
            .is_some_and(|a| a.contains(&null_schema))
    };
    if ["oneOf", "anyOf"].iter().any(has_null_branch) {
        return;
    }
    match map.get_mut("type") {
        Some(Value::String(t)) if t != "null" => {
            let t = std::mem::take(t);
            map.insert("type".into(), json!([t, "null"]));
        }
        Some(Value::Array(types)) if !types.contains(&json!("null")) => types.push(json!("null")),
        Some(_) => return,
        None => {
            *schema = json!({"anyOf": [std::mem::take(schema), null_schema]});
            return;
        }
    }
    if let Some(Value::Array(values)) = map.get_mut("enum") {
        values.push(Value::Null);
    }
}

/// Gives the unsigned integers their own range: the derive writes `u64` and `u32` as `int64` and
/// `int32` with minimum 0, formats whose range ends at 2⁶³ − 1 and 2³¹ − 1, below what the
/// readers take.
fn unsigned_ranges(value: &mut Value) {
    for_each_object(value, &[], &mut |map| {
        let unsigned = map
            .get("minimum")
            .and_then(Value::as_f64)
            .is_some_and(|m| m >= 0.0);
        let widened = match map.get("format").and_then(Value::as_str) {
            Some("int64") if unsigned => Some(("uint64", json!(u64::MAX))),
            Some("int32") if unsigned => Some(("uint32", json!(u32::MAX))),
            _ => None,
        };
        if let Some((format, max)) = widened {
            map.insert("format".into(), json!(format));
            map.entry("maximum").or_insert(max);
        }
    });
}

/// Closes the objects of request bodies to members they do not list (the readers refuse an
/// unknown member, naming it): every object schema with `properties` among the components a
/// request body refers to, directly or through other components.
fn close_requests(doc: &mut Value) {
    let mut pending: Vec<String> = Vec::new();
    if let Some(paths) = doc.get("paths") {
        for operation in paths
            .as_object()
            .into_iter()
            .flat_map(|p| p.values())
            .flat_map(|p| p.as_object())
            .flat_map(|p| p.values())
        {
            if let Some(body) = operation.get("requestBody") {
                refs_in(body, &mut pending);
            }
        }
    }
    let mut seen = std::collections::BTreeSet::new();
    while let Some(name) = pending.pop() {
        if !seen.insert(name.clone()) {
            continue;
        }
        if let Some(schema) = doc.pointer(&format!("/components/schemas/{name}")) {
            refs_in(schema, &mut pending);
        }
    }
    for name in seen {
        if let Some(schema) = doc.pointer_mut(&format!("/components/schemas/{name}")) {
            close_objects(schema);
        }
    }
}

/// The component names `value` refers to.
fn refs_in(value: &Value, out: &mut Vec<String>) {
    match value {
        Value::Object(map) => {
            if let Some(name) = map
                .get("$ref")
                .and_then(Value::as_str)
                .and_then(|r| r.strip_prefix("#/components/schemas/"))
            {
                out.push(name.to_string());
            }
            map.values().for_each(|v| refs_in(v, out));
        }
        Value::Array(items) => items.iter().for_each(|v| refs_in(v, out)),
        _ => {}
    }
}

/// Sets `additionalProperties: false` on every object schema in `value` that lists its
/// properties and says nothing of others (not on constraint fragments, which have no `type`).
fn close_objects(value: &mut Value) {
    for_each_object(value, &[], &mut |map| {
        let is_object = match map.get("type") {
            Some(Value::String(t)) => t == "object",
            Some(Value::Array(ts)) => ts.contains(&json!("object")),
            _ => false,
        };
        if is_object && map.contains_key("properties") && !map.contains_key("additionalProperties")
        {
            map.insert("additionalProperties".into(), json!(false));
        }
    });
}

/// A member that is present and not `null`.
fn given(name: &str) -> Value {
    json!({"required": [name], "properties": {name: {"not": {"type": "null"}}}})
}

/// Schema `name` takes exactly one of `members`.
fn exactly_one_of(schemas: &mut Map<String, Value>, name: &str, members: &[&str]) {
    if let Some(Value::Object(schema)) = schemas.get_mut(name) {
        schema.insert(
            "oneOf".into(),
            Value::Array(members.iter().map(|m| given(m)).collect()),
        );
    }
}

/// Schema `name` flattens an optional `part` (members all present or all absent): utoipa
/// writes it as "null or the part", which no object is, so the part is referred to as it is
/// with none of its members required.
fn optional_flattened(schemas: &mut Map<String, Value>, name: &str, part: &str) {
    let reference = json!({"$ref": format!("#/components/schemas/{part}")});
    if let Some(clauses) = schemas
        .get_mut(name)
        .and_then(|s| s.get_mut("allOf"))
        .and_then(Value::as_array_mut)
    {
        for clause in clauses.iter_mut() {
            let refers = clause
                .get("oneOf")
                .and_then(Value::as_array)
                .is_some_and(|options| options.iter().any(|o| o["$ref"] == reference["$ref"]));
            if refers {
                *clause = reference.clone();
            }
        }
    }
    if let Some(Value::Object(schema)) = schemas.get_mut(part) {
        schema.remove("required");
    }
}

/// Schema `name` takes at least one of `members`.
fn at_least_one_of(schemas: &mut Map<String, Value>, name: &str, members: &[&str]) {
    if let Some(Value::Object(schema)) = schemas.get_mut(name) {
        let any = json!({"anyOf": members.iter().map(|m| given(m)).collect::<Vec<_>>()});
        all_of(schema, any);
    }
}

/// Schema `name` takes `member` only beside `needs`.
fn only_with(schemas: &mut Map<String, Value>, name: &str, member: &str, needs: &str) {
    if let Some(Value::Object(schema)) = schemas.get_mut(name) {
        all_of(
            schema,
            json!({"anyOf": [{"not": given(member)}, given(needs)]}),
        );
    }
}

/// Adds `clause` to the schema's `allOf`.
fn all_of(schema: &mut Map<String, Value>, clause: Value) {
    match schema.get_mut("allOf").and_then(Value::as_array_mut) {
        Some(clauses) => clauses.push(clause),
        None => {
            schema.insert("allOf".into(), json!([clause]));
        }
    }
}

/// Sweep schema `name` takes `h` unless one of its axes varies `h`.
fn step_given_or_swept(schemas: &mut Map<String, Value>, name: &str) {
    if let Some(Value::Object(schema)) = schemas.get_mut(name) {
        let swept = json!({"required": ["axes"], "properties": {"axes": {
            "contains": {"required": ["name"], "properties": {"name": {"const": "h"}}}}}});
        schema.insert("anyOf".into(), json!([given("h"), swept]));
    }
}

/// Schema `name` does not take both `members` (nor both of any pair given before).
fn not_both(schemas: &mut Map<String, Value>, name: &str, members: [&str; 2]) {
    if let Some(Value::Object(schema)) = schemas.get_mut(name) {
        let [a, b] = members;
        let clause = json!({"allOf": [given(a), given(b)]});
        match schema.get_mut("not") {
            Some(before) => *before = json!({"anyOf": [before.take(), clause]}),
            None => {
                schema.insert("not".into(), clause);
            }
        }
    }
}
