//! Which methods a system can run: the catalogue's requirements checked against the system's
//! structure and damping rate, and for a typed-in system the facts its definition answers with.

use super::{build, Base, Method, MethodId};
use crate::system::Structure;
use crate::systems::custom::{CustomModel, Facts};

/// The methods that run on a system of this structure and damping rate (the plain methods, and
/// each composition when some base runs), in catalogue order.
pub fn applicable(structure: Structure, rate: f64) -> Vec<&'static str> {
    let runs = |m: Method| m.requirements().iter().all(|r| r.met_by(structure, rate));
    MethodId::ALL
        .iter()
        .filter(|&&id| match Method::new(id) {
            Method::Composition { scheme, .. } => Base::ALL
                .iter()
                .any(|&base| runs(Method::composition(scheme, base))),
            m => runs(m),
        })
        .map(|id| id.as_str())
        .collect()
}

/// What a typed-in system's definition is, at its default parameter values: its dimension,
/// structure and damping, and the methods that apply (for a driven system, those that can take
/// the time t).
pub fn facts(model: &CustomModel) -> Facts {
    let (structure, rate) = model.structure_at_defaults();
    let time_dependent = model.time_dependent();
    let mut methods = applicable(structure, rate);
    if time_dependent {
        methods.retain(|id| {
            MethodId::parse(id).is_some_and(|m| build::no_time(&Method::new(m), rate).is_none())
        });
    }
    Facts {
        dimension: model.dimension(),
        separable: structure.separable_constant_mass,
        damping: model.damping_kind(),
        methods,
        time_dependent,
    }
}
