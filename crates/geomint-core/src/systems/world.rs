//! How a system appears in physical space: which points its configuration puts where, and what
//! joins them to the origin (a rod, a spring). Each system's catalogue entry carries its
//! [`World`]; the recordings' 3-D view draws it from the Cartesian configuration, whatever the
//! chart the run used. A user-defined system draws its bodies where its own expressions put
//! them ([`Drawing`]).

use std::sync::Arc;

use crate::expr::CompiledFunction;

/// The embedding of a system's Cartesian configuration in 3-D space.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum World {
    /// A point on the x axis at (q, 0, 0).
    Line,
    /// A unit pendulum bob at (sin q, 0, −cos q) on a rod from the origin.
    Pendulum,
    /// A mass at q ∈ R³ on a spring from the origin.
    Spring,
    /// N bodies at q[3i..3i+3].
    Bodies,
    /// A mass at (x, y) in the plane with y pointing down, drawn at (x, 0, −y) on a spring from
    /// the origin.
    PlanarSpring,
    /// A particle in the plane at (x, y, 0).
    Plane,
    /// Bodies where a user-defined system's `positions` put them.
    Drawn(Arc<Drawing>),
}

/// The bodies of a user-defined system: its position expressions compiled as one function of q.
/// A 2-D position (a, b) is drawn at (a, 0, b), in the vertical plane with b pointing up, like
/// the planar pendulum.
#[derive(Debug)]
pub struct Drawing {
    function: CompiledFunction,
    /// Coordinates per body: 2 or 3.
    dims: usize,
    bodies: usize,
}

impl Drawing {
    /// The drawing whose `function` gives `dims` (2 or 3) coordinates per body; a last body
    /// with fewer has the rest at zero.
    pub fn new(function: CompiledFunction, dims: usize) -> Self {
        let bodies = function.output_count().div_ceil(dims);
        Drawing {
            function,
            dims,
            bodies,
        }
    }

    /// The bodies' coordinates at `q` as the definition writes them (2 or 3 per body, body
    /// after body), into `out`.
    pub fn coordinates(&self, q: &[f64], out: &mut Vec<f64>) {
        out.clear();
        if q.len() != self.function.input_count() {
            return;
        }
        out.resize(self.function.output_count(), 0.0);
        self.function.eval(q, out);
    }

    /// The positions of the bodies at `q`, appended to `out`.
    fn positions(&self, q: &[f64], out: &mut Vec<[f64; 3]>) {
        if q.len() != self.function.input_count() {
            return;
        }
        let mut values = vec![0.0; self.bodies * self.dims];
        let outputs = self.function.output_count();
        self.function.eval(q, &mut values[..outputs]);
        out.extend(values.chunks_exact(self.dims).map(|c| match *c {
            [a, b] => [a, 0.0, b],
            [x, y, z] => [x, y, z],
            _ => [0.0; 3],
        }));
    }
}

impl PartialEq for Drawing {
    /// The same compiled drawing.
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self, other)
    }
}

impl Eq for Drawing {}

/// What joins a body to the origin in the drawing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Link {
    /// A rigid rod.
    Rod,
    /// A spring.
    Spring,
}

impl Link {
    /// The entity name of the link.
    pub fn as_str(self) -> &'static str {
        match self {
            Link::Rod => "rod",
            Link::Spring => "spring",
        }
    }
}

impl World {
    /// Bodies drawn per sample for `dof` degrees of freedom.
    pub fn bodies(&self, dof: usize) -> usize {
        match self {
            World::Bodies => dof / 3,
            World::Drawn(drawing) => drawing.bodies,
            _ => 1,
        }
    }

    /// The positions of the bodies for the Cartesian configuration `q`, appended to `out`.
    pub fn positions(&self, q: &[f64], out: &mut Vec<[f64; 3]>) {
        let at = |i: usize| q.get(i).copied().unwrap_or(0.0);
        match self {
            World::Line => out.push([at(0), 0.0, 0.0]),
            World::Pendulum => out.push([at(0).sin(), 0.0, -at(0).cos()]),
            World::PlanarSpring => out.push([at(0), 0.0, -at(1)]),
            World::Plane => out.push([at(0), at(1), 0.0]),
            World::Spring | World::Bodies => {
                out.extend(q.chunks_exact(3).map(|c| [c[0], c[1], c[2]]))
            }
            World::Drawn(drawing) => drawing.positions(q, out),
        }
    }

    /// The Cartesian configuration whose bodies stand at `points` (x, y, z of each, in a row):
    /// the inverse of [`positions`](Self::positions), where the drawing determines it (a
    /// pendulum's angle, or a user's drawing, is not read back).
    pub fn configuration(&self, points: &[f64]) -> Option<Vec<f64>> {
        let at = |i: usize| points.get(i).copied();
        match self {
            World::Pendulum | World::Drawn(_) => None,
            World::Spring | World::Bodies => Some(points.to_vec()),
            World::PlanarSpring => Some(vec![at(0)?, -at(2)?]),
            World::Plane => Some(vec![at(0)?, at(1)?]),
            World::Line => Some(vec![at(0)?]),
        }
    }

    /// What joins the body to the origin, if anything.
    pub fn link(&self) -> Option<Link> {
        match self {
            World::Pendulum => Some(Link::Rod),
            World::Spring | World::PlanarSpring => Some(Link::Spring),
            _ => None,
        }
    }
}
