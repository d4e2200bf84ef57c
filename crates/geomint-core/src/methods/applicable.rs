//! Which methods a system can run: the catalogue's requirements checked against the system's
//! structure and damping rate (a typed-in system's facts list them: `systems::custom::facts`).

use super::{Base, Method, MethodId};
use crate::system::Structure;

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
