//! The catalogue entries of the built-in splittings.

use crate::methods::sources::*;
use crate::methods::{Citation, Group, Kind, MethodInfo, MethodOption, Requirement, Steps};

/// Catalogue entry of `modin_3s`.
pub const MODIN_3S_INFO: MethodInfo = MethodInfo {
    id: "modin_3s",
    name: "Three-term splitting (3S)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: MODIN,
        equation: "Algorithm 3.1",
    },
    group: Group::Geometric,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::MODIN_3S),
};

/// Catalogue entry of `modin_2s`.
pub const MODIN_2S_INFO: MethodInfo = MethodInfo {
    id: "modin_2s",
    name: "Two-term splitting (2S)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: MODIN,
        equation: "Algorithm 3.2",
    },
    group: Group::Geometric,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::MODIN_2S),
};

/// Catalogue entry of `modin_rks`.
pub const MODIN_RKS_INFO: MethodInfo = MethodInfo {
    id: "modin_rks",
    name: "Runge–Kutta splitting (RKS)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: MODIN,
        equation: "Algorithm 3.3",
    },
    group: Group::Geometric,
    options: &[MethodOption::Inner],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::MODIN_RKS),
};

/// Catalogue entry of `csv1`.
pub const CSV1_INFO: MethodInfo = MethodInfo {
    id: "csv1",
    name: "Conformal Störmer–Verlet 1 (CSV1)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[
        Requirement::SeparableConstantMass,
        Requirement::ConformalDamping,
    ],
    reference: Citation {
        paper: FLOYD,
        equation: "eq. (2.12)",
    },
    group: Group::Conformal,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::CSV1),
};

/// Catalogue entry of `symplectic_euler`.
pub const SYMPLECTIC_EULER_INFO: MethodInfo = MethodInfo {
    id: "symplectic_euler",
    name: "Symplectic Euler",
    order: 1,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: TAKACS,
        equation: "eq. (42)",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::SYMPLECTIC_EULER),
};

/// Catalogue entry of `symplectic_euler_adjoint`.
pub const SYMPLECTIC_EULER_ADJOINT_INFO: MethodInfo = MethodInfo {
    id: "symplectic_euler_adjoint",
    name: "Symplectic Euler (adjoint)",
    order: 1,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: TAKACS,
        equation: "footnote 3 (the adjoint of eqs. 42–43)",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::SYMPLECTIC_EULER_ADJOINT),
};

/// Catalogue entry of `position_verlet`.
pub const POSITION_VERLET_INFO: MethodInfo = MethodInfo {
    id: "position_verlet",
    name: "Störmer–Verlet (drift–kick–drift)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: GNI,
        equation: "Sec. I.1.4",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::POSITION_VERLET),
};

/// Catalogue entry of `velocity_verlet`.
pub const VELOCITY_VERLET_INFO: MethodInfo = MethodInfo {
    id: "velocity_verlet",
    name: "Störmer–Verlet (kick–drift–kick)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: GNI,
        equation: "Sec. I.1.4",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::VELOCITY_VERLET),
};

/// Catalogue entry of `blanes_moan_s6`.
pub const BLANES_MOAN_S6_INFO: MethodInfo = MethodInfo {
    id: "blanes_moan_s6",
    name: "Blanes–Moan S6 (order 4, six stages)",
    order: 4,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: BLANES_MOAN,
        equation: "S6",
    },
    group: Group::Geometric,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::BLANES_MOAN_S6),
};

/// Catalogue entry of `blanes_moan_srkn11`.
pub const BLANES_MOAN_SRKN11_INFO: MethodInfo = MethodInfo {
    id: "blanes_moan_srkn11",
    name: "Blanes–Moan SRKN11b (order 6, eleven stages)",
    order: 6,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[
        Requirement::SeparableConstantMass,
        Requirement::Conservative,
    ],
    reference: Citation {
        paper: BLANES_MOAN,
        equation: "SRKN11b",
    },
    group: Group::Geometric,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Splitting(super::BLANES_MOAN_SRKN11),
};
