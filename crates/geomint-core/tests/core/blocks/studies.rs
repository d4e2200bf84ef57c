//! The pieces studies are made of: shards, axes, whole steps, default samples.

use geomint_core::error::Field;
use geomint_core::studies::convergence::*;
use geomint_core::studies::parts::*;
use geomint_core::studies::settings::*;
use geomint_core::studies::sweep::axis::*;

#[test]
fn shards_cover_the_cells_once_in_order() {
    for (cells, count) in [(1, 1), (10, 3), (10201, 7), (7, 7)] {
        let mut next = 0;
        for index in 0..count {
            let range = Shard { index, count }.cells(cells).unwrap();
            assert_eq!(range.start, next);
            assert!(range.len() >= cells / count && range.len() <= cells / count + 1);
            next = range.end;
        }
        assert_eq!(next, cells);
    }
    assert!(Shard { index: 0, count: 8 }.cells(7).is_err());
}

#[test]
fn shard_designations_are_read_strictly() {
    assert_eq!(Shard::parse("2/5"), Ok(Shard { index: 2, count: 5 }));
    for bad in [
        "5/5",
        "0/0",
        "-1/3",
        "1/",
        "/3",
        "1/3/4",
        "a/3",
        " 1/3",
        "1/1000001",
    ] {
        assert!(Shard::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn targets_read_their_names_back() {
    for name in ["h", "params.gamma", "q0[0]", "p0[12]"] {
        assert_eq!(Target::parse(name).unwrap().name(), name);
    }
    for bad in [
        "", "params.", "q0[]", "q0[-1]", "q0[+1]", "q0[1", "x", "p0[ 1]",
    ] {
        assert_eq!(Target::parse(bad), None, "{bad}");
    }
}

#[test]
fn log_axes_end_on_their_bounds() {
    let axis = Axis {
        target: Target::Step,
        min: 1e-3,
        max: 1.0,
        n: 7,
        scale: Scale::Log,
        field: Field::new("axes").index(0),
    };
    let v = axis.values();
    assert_eq!((v[0], v[6]), (1e-3, 1.0));
    assert!((v[3] - 10f64.powf(-1.5)).abs() < 1e-15);
    let grid = Grid {
        axes: vec![axis.clone(), Axis { n: 3, ..axis }],
    };
    assert_eq!(grid.cells(), 21);
    let point = grid.point(7 + 6);
    assert_eq!(point[0], v[6]);
    assert!((point[1] - 10f64.powf(-1.5)).abs() < 1e-15);
}

#[test]
fn whole_steps_allow_round_off_only() {
    assert_eq!(whole_steps(10.0, 0.04), Some(250));
    assert_eq!(whole_steps(10.0, 0.04 / 32.0), Some(8000));
    assert_eq!(whole_steps(10.0, 0.3), None);
    assert_eq!(whole_steps(1.0, 3.0), None);
}

#[test]
fn default_samples_divide_every_step_count() {
    assert_eq!(default_samples(&[250]), 250);
    assert_eq!(default_samples(&[8000]), 1000);
    assert_eq!(default_samples(&[1024 * 3]), 768);
    assert_eq!(default_samples(&[7]), 7);
    assert_eq!(default_samples(&[250, 500, 1000]), 250);
    assert_eq!(default_samples(&[250, 1000, 4000]), 250);
}
