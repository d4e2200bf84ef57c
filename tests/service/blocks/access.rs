//! Who may do what: the scopes of the routes, tokens and their file, quotas in use.

use std::sync::Arc;

use axum::http::Method;
use geomint::access::tokens::*;
use geomint::access::usage::Usage;
use geomint::access::Scope;
use geomint::access::{Caller, Quotas, Scopes};
use geomint::core::error::ErrorCode;
use geomint::http::auth::RouteScopes;
use geomint::http::{openapi, paths};

/// Every route of the service has its rule: none falls to `admin` by omission, and the
/// ones open to all are exactly the service's own.
#[test]
fn every_route_has_a_scope() {
    let doc = openapi::document();
    let routes = RouteScopes::of(&doc);
    let mut seen = Vec::new();
    for (path, method, scope) in routes.rules() {
        seen.push(format!("{method} {path} {scope:?}"));
        assert_ne!(scope, Some(Scope::Admin), "{method} {path}");
    }
    seen.sort();
    let open: Vec<&String> = seen.iter().filter(|s| s.ends_with("None")).collect();
    assert_eq!(open.len(), 2, "{open:?}");
    let need = |m: Method, p: &str| routes.need(&m, Some(p));
    assert_eq!(need(Method::DELETE, paths::RECORDING), Some(Scope::Store));
    assert_eq!(need(Method::HEAD, paths::RECORDING), Some(Scope::Read));
    assert_eq!(need(Method::POST, paths::SWEEP), Some(Scope::Run));
    assert_eq!(
        need(Method::PUT, paths::SWEEP),
        None,
        "left to the router's 405"
    );
    assert_eq!(
        need(Method::GET, "/api/v1/unknown/{id}"),
        Some(Scope::Admin)
    );
    assert_eq!(need(Method::GET, paths::HEALTHZ), None);
}

#[test]
fn a_generated_line_reads_back_and_admits_only_its_secret() {
    let quotas = Quotas {
        recordings_bytes: Some(1 << 20),
        systems: Some(3),
        runs: Some(1),
        steps_per_minute: Some(1_000_000),
    };
    let scopes = Scopes::parse("read,store").unwrap();
    let made = generate("alice", scopes, &quotas).unwrap();
    assert!(made.secret.starts_with(SECRET_PREFIX) && made.secret.len() == 47);
    assert!(!made.line.contains(&made.secret));
    let file = TokenFile::parse(&format!("# tokens\n\n{}  # alice\n", made.line)).unwrap();
    let entry = file.verify(&made.secret).expect("its own secret passes");
    assert_eq!(
        (entry.name.as_str(), entry.scopes, &entry.quotas),
        ("alice", scopes, &quotas)
    );
    let other = generate("alice", scopes, &quotas).unwrap();
    assert!(file.verify(&other.secret).is_none());
    assert!(file.verify("").is_none());
    assert!(file.verify(&made.secret[..46]).is_none());
    assert!(file.verify(&"x".repeat(MAX_SECRET_LEN + 1)).is_none());
}

#[test]
fn wrong_lines_are_named() {
    let digest = digest_text(&digest("s"));
    for (text, says) in [
        ("alice read".to_string(), "name scopes"),
        (format!("al/ice read {digest}"), "not a token name"),
        (
            format!("alice read,write {digest}"),
            "unknown scope `write`",
        ),
        ("alice read sha256:abc".to_string(), "64 hex digits"),
        ("alice read gmt_secret".to_string(), "not a digest"),
        (format!("alice read {digest} runs=-1"), "runs"),
        (format!("alice read {digest} bytes=1"), "unknown quota"),
        (format!("a read {digest}\na run {digest}"), "used twice"),
    ] {
        let error = TokenFile::parse(&text).unwrap_err();
        assert!(error.to_string().contains(says), "{text}: {error}");
    }
    let error = TokenFile::parse(&format!("a read {digest}\nb run {digest}")).unwrap_err();
    assert_eq!(error.line, 2);
}

fn caller(quotas: Quotas) -> Caller {
    Caller {
        owner: "alice".into(),
        token: true,
        scopes: Scopes::ALL,
        quotas,
        largest_run: None,
    }
}

#[test]
fn runs_in_flight_are_counted_until_they_end() {
    let usage = Arc::new(Usage::default());
    let alice = caller(Quotas {
        runs: Some(2),
        ..Quotas::default()
    });
    let first = usage.admit(&alice, Some(1)).unwrap();
    let _second = usage.admit(&alice, None).unwrap();
    let refused = usage.admit(&alice, Some(1)).unwrap_err();
    assert_eq!(
        (refused.detail.code, refused.retry_after_secs),
        (ErrorCode::TooManyRuns, Some(1))
    );
    drop(first);
    let _third = usage.admit(&alice, Some(1)).unwrap();
    assert_eq!(usage.runs_in_flight("alice"), 2);
}

#[test]
fn steps_per_minute_refuse_with_the_wait() {
    let usage = Arc::new(Usage::default());
    let alice = caller(Quotas {
        steps_per_minute: Some(6_000),
        ..Quotas::default()
    });
    drop(usage.admit(&alice, Some(4_000)).unwrap());
    let refused = usage.admit(&alice, Some(4_000)).unwrap_err();
    assert_eq!(refused.detail.code, ErrorCode::RateLimited);
    // 2000 steps come back after 20 s.
    let wait = refused.retry_after_secs.unwrap();
    assert!((19..=21).contains(&wait), "{wait}");
    let never = usage.admit(&alice, Some(6_001)).unwrap_err();
    assert_eq!(never.detail.code, ErrorCode::QuotaExceeded);
    // Quotas beyond u32 cells count in larger units.
    let big = caller(Quotas {
        steps_per_minute: Some(1 << 40),
        ..Quotas::default()
    });
    drop(usage.admit(&big, Some(1 << 39)).unwrap());
    assert!(usage.admit(&big, Some(1 << 40)).is_err());
}
