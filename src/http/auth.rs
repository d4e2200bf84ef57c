//! Authentication and scopes, as one middleware in front of every route: the request's
//! [`Caller`] from its `Authorization: Bearer` header and the server's anonymous policy
//! ([`crate::access`]), refused with 401 (no or a wrong token) or 403 (a token without the scope)
//! before any handler reads the request, and otherwise put in the request's extensions for the
//! handlers ([`Caller`] is an extractor; [`super::answer::Client`] carries it to admission).
//!
//! Which scope a route needs follows from its OpenAPI operation ([`scope_of`]): the health check
//! and this document (tag `service`) are open to all; reading (`GET`) needs `read`; computing
//! (`POST` of a simulation, a stability map or a study) needs `run`; storing and deleting (`POST`
//! and `DELETE` of the catalogue and the recordings) need `store` — storing a recording of a
//! simulation the server runs (a JSON body) needs `run` too. Anything else needs `admin`, so a
//! route added without a rule is closed, not open. The same rule writes each operation's
//! `security` into the document ([`document_security`]). Files of the page are open to all.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;

use axum::extract::{ConnectInfo, FromRequestParts, MatchedPath, Request, State};
use axum::http::request::Parts;
use axum::http::{header, Extensions, Method};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use serde_json::{json, Value};

use super::paths;
use super::state::AppState;
use super::ApiError;
use crate::access::{Anonymous, Caller, Scope, Scopes};

/// The scope an operation needs (`None`: open to all), by its method and tags.
pub fn scope_of(method: &str, tags: &[&str]) -> Option<Scope> {
    let method = method.to_ascii_lowercase();
    let tagged = |names: &[&str]| tags.iter().any(|t| names.contains(t));
    if tagged(&["service"]) {
        return None;
    }
    Some(match method.as_str() {
        "get" | "head" => Scope::Read,
        "post" if tagged(&["simulation", "stability", "studies"]) => Scope::Run,
        "post" | "delete" if tagged(&["catalog", "recordings"]) => Scope::Store,
        "post" | "delete" if tagged(&["jobs"]) => Scope::Run,
        _ => Scope::Admin,
    })
}

/// What each route needs, by path template and method, read from the routes' OpenAPI document.
#[derive(Clone, Debug, Default)]
pub struct RouteScopes(HashMap<String, HashMap<Method, Option<Scope>>>);

const METHODS: [&str; 5] = ["get", "post", "put", "patch", "delete"];

impl RouteScopes {
    /// Every rule: route template, method and the scope it needs (`None`: open to all).
    pub fn rules(&self) -> impl Iterator<Item = (&str, &Method, Option<Scope>)> {
        self.0.iter().flat_map(|(path, methods)| {
            methods
                .iter()
                .map(move |(method, scope)| (path.as_str(), method, *scope))
        })
    }

    /// The scopes of the operations of `doc` (the OpenAPI document as JSON).
    pub fn of(doc: &Value) -> Self {
        let mut routes: HashMap<String, HashMap<Method, Option<Scope>>> = HashMap::new();
        for (path, item) in doc["paths"].as_object().into_iter().flatten() {
            for method in METHODS {
                let Some(operation) = item.get(method) else {
                    continue;
                };
                let tags: Vec<&str> = operation["tags"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .filter_map(Value::as_str)
                    .collect();
                let Ok(parsed) = method.to_ascii_uppercase().parse::<Method>() else {
                    continue;
                };
                routes
                    .entry(path.clone())
                    .or_default()
                    .insert(parsed, scope_of(method, &tags));
            }
        }
        RouteScopes(routes)
    }

    /// What a request to `route` (its matched path template; none for the page's files) with
    /// `method` needs. A method the route does not take is left to the router (405); a route
    /// that the document does not describe needs `admin`.
    pub fn need(&self, method: &Method, route: Option<&str>) -> Option<Scope> {
        let route = route?;
        let Some(methods) = self.0.get(route) else {
            return Some(Scope::Admin);
        };
        let method = if method == Method::HEAD {
            &Method::GET
        } else {
            method
        };
        methods.get(method).copied().flatten()
    }
}

/// The caller a request was authenticated as; one without (never the case behind [`app`]'s
/// middleware) may do nothing.
///
/// [`app`]: super::app
pub fn caller_of(extensions: &Extensions) -> Arc<Caller> {
    extensions.get::<Arc<Caller>>().cloned().unwrap_or_else(|| {
        Arc::new(Caller {
            owner: "anonymous".into(),
            token: false,
            scopes: Scopes::NONE,
            quotas: Default::default(),
            largest_run: Some(0),
        })
    })
}

impl<S: Send + Sync> FromRequestParts<S> for Caller {
    type Rejection = std::convert::Infallible;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Self::Rejection> {
        Ok((*caller_of(&parts.extensions)).clone())
    }
}

/// Who the access log names for an answer (put in the response's extensions).
#[derive(Clone, Debug)]
pub struct LoggedCaller(pub String);

/// The middleware: authenticates the request and checks the scope its route needs.
pub async fn authorize(
    State((state, routes)): State<(AppState, Arc<RouteScopes>)>,
    mut request: Request,
    next: Next,
) -> Response {
    let address = request
        .extensions()
        .get::<ConnectInfo<SocketAddr>>()
        .map(|info| info.0.ip());
    let headers = request.headers();
    let values = headers
        .get_all(header::AUTHORIZATION)
        .iter()
        .map(|v| v.as_bytes());
    let caller = match state.access.caller(values, address) {
        Ok(caller) => caller,
        Err(refusal) => return ApiError::from(refusal).into_response(),
    };
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map(MatchedPath::as_str);
    let mut needs: Vec<Scope> = routes.need(request.method(), route).into_iter().collect();
    // Storing a recording of a simulation runs it.
    if route == Some(paths::RECORDINGS)
        && request.method() == Method::POST
        && !super::recordings::is_rrd_upload(request.headers())
    {
        needs.push(Scope::Run);
    }
    let logged = LoggedCaller(caller.owner.clone());
    if let Some(refusal) = needs.into_iter().find_map(|s| caller.require(s).err()) {
        let mut response = ApiError::from(refusal).into_response();
        response.extensions_mut().insert(logged);
        return response;
    }
    request.extensions_mut().insert(Arc::new(caller));
    let mut response = next.run(request).await;
    response.extensions_mut().insert(logged);
    response
}

/// Writes the bearer scheme and each operation's `security` into `doc`, and the refusals it
/// brings (401, 403 and, for computing routes, 429 with `Retry-After`): an operation a client
/// without a token may call under `anonymous` lists the empty requirement `{}` beside the scope.
pub fn document_security(doc: &mut Value, anonymous: Anonymous) {
    let error = json!({"application/json": {"schema": {"$ref": "#/components/schemas/ErrorBody"}}});
    if let Some(components) = doc.get_mut("components").and_then(Value::as_object_mut) {
        components.insert(
            "securitySchemes".into(),
            json!({"bearer": {
                "type": "http",
                "scheme": "bearer",
                "description": "A token of the server's tokens file (`geomint token` makes one). \
                    Scopes: `read` (catalogues, stored systems and recordings), `run` (simulations \
                    and studies), `store` (storing, and deleting what the token stored), `admin` \
                    (everything, deleting what anyone stored)."
            }}),
        );
    }
    let Some(paths) = doc.get_mut("paths").and_then(Value::as_object_mut) else {
        return;
    };
    for item in paths.values_mut() {
        for method in METHODS {
            let Some(operation) = item.get_mut(method).and_then(Value::as_object_mut) else {
                continue;
            };
            let tags: Vec<String> = operation
                .get("tags")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
                .filter_map(|t| t.as_str().map(str::to_string))
                .collect();
            let tags: Vec<&str> = tags.iter().map(String::as_str).collect();
            let Some(scope) = scope_of(method, &tags) else {
                operation.insert("security".into(), json!([{}]));
                continue;
            };
            let open = match anonymous {
                Anonymous::All => true,
                Anonymous::Public => matches!(scope, Scope::Read | Scope::Run),
                Anonymous::None => false,
            };
            let required = json!({"bearer": [scope.name()]});
            let security = if open {
                json!([{}, required])
            } else {
                json!([required])
            };
            operation.insert("security".into(), security);
            let Some(responses) = operation
                .get_mut("responses")
                .and_then(Value::as_object_mut)
            else {
                continue;
            };
            responses.entry("401").or_insert_with(|| json!({
                "description": "No token where the route needs one, or a token that is not valid \
                    (code `unauthorized`, field `Authorization`)",
                "headers": {"WWW-Authenticate": {"schema": {"type": "string"}}},
                "content": error.clone(),
            }));
            responses.entry("403").or_insert_with(|| json!({
                "description": format!("The token lacks the `{}` scope, or (deleting) does not own \
                    what it would delete (code `forbidden`), or the request is beyond its quota \
                    (code `quota_exceeded`)", scope.name()),
                "content": error.clone(),
            }));
            if scope == Scope::Run {
                responses.entry("429").or_insert_with(|| json!({
                    "description": "The caller has its quota of runs in flight (code \
                        `too_many_runs`) or has used its steps per minute (code `rate_limited`)",
                    "headers": {"Retry-After": {"schema": {"type": "integer", "minimum": 0},
                        "description": "Seconds to wait before retrying"}},
                    "content": error.clone(),
                }));
            }
        }
    }
}
