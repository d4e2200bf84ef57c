//! The pieces of the messages that several errors share.

use super::{show, Field};

/// The names, comma-separated.
pub(super) fn list(names: &[String]) -> String {
    names.join(", ")
}

/// What a step limit counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepScope {
    /// The steps of one method's run.
    PerMethod,
    /// The steps of every setting of a study together.
    PerStudy,
}

pub(super) fn too_many_steps(field: &Field, steps: u64, limit: u64, scope: StepScope) -> String {
    match scope {
        StepScope::PerMethod => {
            format!("{field}: t_end/h = {steps} steps exceeds the limit of {limit} per method")
        }
        StepScope::PerStudy => format!(
            "{field}: {steps} steps over all settings exceed the limit of {limit} per study; use \
             fewer or larger steps"
        ),
    }
}

pub(super) fn at_point(q: &[f64]) -> String {
    if q.is_empty() {
        String::new()
    } else {
        let shown: Vec<String> = q.iter().map(|&x| show(x)).collect();
        format!(" at q = [{}]", shown.join(", "))
    }
}

pub(super) fn divisor_detail(h: f64, span: f64, show_ratio: bool) -> String {
    if show_ratio {
        format!("t_end/h = {}", span / h)
    } else {
        format!("{} does not", show(h))
    }
}
