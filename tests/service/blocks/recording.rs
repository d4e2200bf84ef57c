//! Pieces of the recordings: entity names, layout of samples and paths, colours, verdicts, the
//! header shown in errors.

use geomint::recording::layout::{path_blocks, sample_steps, PathBlock, MAX_PATH_ROWS};
use geomint::recording::read::show_bytes;
use geomint::recording::stability::Verdict;
use geomint::recording::sweep::{heatmap, ramp};
use geomint::recording::{entity_names, entity_part};

#[test]
fn the_ramp_runs_from_its_first_to_its_last_anchor() {
    assert_eq!(ramp(0.0), [68, 1, 84]);
    assert_eq!(ramp(1.0), [253, 231, 37]);
    assert_eq!(ramp(0.5), [33, 145, 140]);
    let (pixels, scale) = heatmap(&[1e-3, f64::NAN, 1e-1], true);
    assert_eq!(scale, Some((-3.0, -1.0)));
    assert_eq!(pixels, [[68, 1, 84], [0, 0, 0], [253, 231, 37]].concat());
}

#[test]
fn entity_parts_are_plain_and_unique() {
    assert_eq!(entity_part("modin_rks(rk4)"), "modin_rks_rk4");
    assert_eq!(entity_part("reference(1e-10)"), "reference_1e-10");
    assert_eq!(entity_part("L_z"), "L_z");
    assert_eq!(entity_part("spec"), "m_spec");
    assert_eq!(
        entity_names(&["heun", "heun", "triple_jump(csv1)", "heun"]),
        ["heun", "heun_2", "triple_jump_csv1", "heun_3"]
    );
}

#[test]
fn header_bytes_are_shown_as_text_or_hex() {
    assert_eq!(show_bytes(b"{\"a\""), "`{\"a\"`");
    assert_eq!(show_bytes(&[0, 1, 0xAB, 0xFF]), "0x0001ABFF");
    assert_eq!(show_bytes(b""), "0x");
}

#[test]
fn path_blocks_cover_every_sample_once() {
    assert_eq!(path_blocks(0), []);
    assert_eq!(path_blocks(1), [PathBlock { start: 0, end: 0 }]);
    let short = path_blocks(3);
    assert_eq!(
        short,
        [
            PathBlock { start: 0, end: 0 },
            PathBlock { start: 0, end: 1 },
            PathBlock { start: 1, end: 2 }
        ]
    );
    let long = path_blocks(1_000_001);
    assert_eq!(long.len(), MAX_PATH_ROWS + 1);
    assert!(long.windows(2).all(|w| w[0].end == w[1].start));
    assert_eq!(long.last().unwrap().end, 1_000_000);
}

#[test]
fn sample_steps_end_at_the_last_step() {
    assert_eq!(sample_steps(4, 10, 25), [0, 10, 20, 25]);
    assert_eq!(sample_steps(3, 10, 20), [0, 10, 20]);
    assert_eq!(sample_steps(2, 10, 25), [0, 10]);
}

#[test]
fn verdicts_mark_where_the_relation_disagrees() {
    assert_eq!(Verdict::of(true, None), Verdict::Stable);
    assert_eq!(Verdict::of(false, Some(false)), Verdict::Unstable);
    assert_eq!(
        Verdict::of(true, Some(false)),
        Verdict::StableAnalyticUnstable
    );
    assert_eq!(
        Verdict::of(false, Some(true)),
        Verdict::UnstableAnalyticStable
    );
}
