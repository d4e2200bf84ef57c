//! The drawings of configurations in physical space, and back.

use geomint_core::systems::world::*;

#[test]
fn configurations_invert_the_drawing() {
    for world in [
        World::Line,
        World::Spring,
        World::Bodies,
        World::PlanarSpring,
        World::Plane,
    ] {
        let q: Vec<f64> = match world {
            World::Line => vec![0.5],
            World::PlanarSpring | World::Plane => vec![0.5, -0.25],
            _ => vec![0.5, 0.0, -0.25, 1.0, 2.0, 3.0],
        };
        let q = if matches!(world, World::Spring) {
            q[..3].to_vec()
        } else {
            q
        };
        let mut points = Vec::new();
        world.positions(&q, &mut points);
        let flat: Vec<f64> = points.iter().flatten().copied().collect();
        assert_eq!(world.configuration(&flat), Some(q), "{world:?}");
    }
    assert_eq!(World::Pendulum.configuration(&[0.5, 0.0, -0.25]), None);
    assert_eq!(World::Plane.configuration(&[]), None);
}
