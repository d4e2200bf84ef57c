//! The recordings store: ids, dates, where room comes from, a write that survives a second store.

use std::fs;
use std::io::Write;

use geomint::store::dates::rfc3339;
use geomint::store::entry::SpecSummary;
use geomint::store::index::Index;
use geomint::store::recordings::{
    is_valid_id, new_id, RecordingEntry, RecordingOwner, RecordingStore, StoreError,
};
use geomint::store::tempfile::TMP_PREFIX;

#[test]
fn dates_are_rfc3339() {
    assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
    assert_eq!(rfc3339(951_782_400_123), "2000-02-29T00:00:00.123Z");
    assert_eq!(rfc3339(1_767_225_599_999), "2025-12-31T23:59:59.999Z");
}

fn entry(id: &str, owner: Option<&str>, bytes: u64, at: u64) -> RecordingEntry {
    RecordingEntry {
        id: id.into(),
        created: String::new(),
        bytes,
        spec: None,
        origin: Default::default(),
        application_id: None,
        created_unix_ms: at,
        owner: owner.map(String::from),
        job: None,
    }
}

fn owner(name: &str, quota: Option<u64>) -> RecordingOwner {
    RecordingOwner {
        name: name.into(),
        quota,
    }
}

fn ids(evicted: &[RecordingEntry]) -> Vec<&str> {
    evicted.iter().map(|e| e.id.as_str()).collect()
}

#[test]
fn room_comes_from_the_owners_own_then_the_unowned_never_others() {
    let mut index = Index::default();
    for (id, who, at) in [
        ("old", None, 0),
        ("b1", Some("bob"), 1),
        ("a1", Some("alice"), 2),
        ("a2", Some("alice"), 3),
    ] {
        index.insert(entry(id, who, 10, at));
    }
    // Past alice's quota of 25: her oldest goes, not bob's older one nor the unowned.
    index.insert(entry("a3", Some("alice"), 10, 4));
    let evicted = index
        .make_room("a3", &owner("alice", Some(25)), 1000)
        .unwrap();
    assert_eq!(ids(&evicted), ["a1"]);
    assert_eq!(
        (index.owned("alice"), index.owned("bob"), index.total()),
        (20, 10, 40)
    );
    // Past the cap of 40: bob's new one takes his own oldest first, then the unowned.
    index.insert(entry("b2", Some("bob"), 10, 5));
    let evicted = index.make_room("b2", &owner("bob", None), 40).unwrap();
    assert_eq!(ids(&evicted), ["b1"]);
    index.insert(entry("b3", Some("bob"), 10, 6));
    let evicted = index.make_room("b3", &owner("bob", None), 40).unwrap();
    assert_eq!(ids(&evicted), ["b2"], "bob's own before the unowned");
    index.insert(entry("b4", Some("bob"), 20, 7));
    let evicted = index.make_room("b4", &owner("bob", None), 40).unwrap();
    assert_eq!(ids(&evicted), ["b3", "old"]);
    // Only alice's could make room for carol: refused, nothing removed.
    index.insert(entry("c1", Some("carol"), 10, 8));
    let before = index.total();
    assert!(matches!(
        index.make_room("c1", &owner("carol", None), 40),
        Err(StoreError::FullOfOthers { .. })
    ));
    assert_eq!(index.total(), before);
}

#[test]
fn ids_are_checked_strictly() {
    assert!(is_valid_id(&new_id()));
    assert!(is_valid_id("0123456789abcdef0123456789abcdef"));
    for bad in [
        "",
        "0123456789ABCDEF0123456789ABCDEF",
        "0123456789abcdef0123456789abcde",
        "0123456789abcdef0123456789abcdef0",
        "../../etc/passwd",
        "0123456789abcdef0123456789abcde/",
        "0123456789abcdef0123456789abcdeg",
    ] {
        assert!(!is_valid_id(bad), "{bad}");
    }
}

/// A store opened on the directory while another writes a recording (another server on the
/// same data directory; on a loaded machine a slow write overlaps the start-up of the next
/// test's server) leaves the write alone, and removes only temporary files nobody holds.
#[test]
fn a_write_in_progress_survives_a_second_store() {
    let dir = std::env::temp_dir().join(format!("geomint-store-{}", new_id()));
    fs::create_dir_all(&dir).unwrap();
    let abandoned = dir.join(format!("{TMP_PREFIX}{}.rrd", new_id()));
    fs::write(&abandoned, b"torn").unwrap();
    let writer = RecordingStore::open(&dir, 1 << 30);
    assert!(!abandoned.exists(), "an unlocked leftover is removed");
    let spec = SpecSummary {
        system: "pendulum".into(),
        methods: vec!["modin_3s".into()],
        h: 0.1,
        steps: 1,
        every: 1,
        t_end: 0.1,
        samples_per_method: 2,
    };
    let owner = RecordingOwner {
        name: "alice".into(),
        quota: None,
    };
    let entry = writer
        .save(spec, &owner, |mut w| {
            // Mid-write, a second store scans the directory.
            w.write_all(b"RRF2").unwrap();
            w.flush().unwrap();
            let temporaries = || {
                fs::read_dir(&dir)
                    .unwrap()
                    .flatten()
                    .filter(|f| f.file_name().to_string_lossy().starts_with(TMP_PREFIX))
                    .count()
            };
            assert_eq!(temporaries(), 1);
            let second = RecordingStore::open(&dir, 1 << 30);
            assert!(second.list().is_empty());
            assert_eq!(temporaries(), 1, "the write in progress was removed");
            w.write_all(&[0; 8]).unwrap();
            w.write_all(b"RRF2FOOT\0\0\0\0").unwrap();
            Ok(w)
        })
        .unwrap();
    assert_eq!(entry.bytes, 24);
    let reopened = RecordingStore::open(&dir, 1 << 30);
    assert_eq!(reopened.list(), vec![entry]);
    fs::remove_dir_all(&dir).unwrap();
}
