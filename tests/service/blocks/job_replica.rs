//! The jobs' files kept in a replica (the JetStream bucket of a server with NATS; here a map in
//! memory): every file but the event log is kept under `ID/FILE` as it is written, a store on an
//! empty directory takes back the jobs it lacks with their bytes, names that are not a job's
//! files are never written, and a removal takes the job's names out.

use std::collections::BTreeMap;
use std::io;
use std::sync::{Arc, Mutex};

use geomint::store::jobs::{JobOutcome, JobRecord, JobStore, NotReplicated, Replica, JOB_FORMAT};
use geomint::store::recordings::new_id;
use serde_json::json;

/// Names and their bytes; `None` for a name listed that cannot be read (an object deleted
/// between the listing and the read).
#[derive(Debug, Default)]
struct Memory(Mutex<BTreeMap<String, Option<Vec<u8>>>>);

impl Memory {
    fn names(&self) -> Vec<String> {
        self.0.lock().unwrap().keys().cloned().collect()
    }

    fn insert(&self, name: &str, bytes: &[u8]) {
        self.0
            .lock()
            .unwrap()
            .insert(name.into(), Some(bytes.into()));
    }

    fn unreadable(&self, name: &str) {
        self.0.lock().unwrap().insert(name.into(), None);
    }
}

impl Replica for Memory {
    fn put(&self, name: &str, bytes: &[u8]) -> io::Result<()> {
        self.insert(name, bytes);
        Ok(())
    }

    fn get(&self, name: &str) -> io::Result<Vec<u8>> {
        let kept = self.0.lock().unwrap().get(name).cloned().flatten();
        kept.ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, name.to_string()))
    }

    fn names(&self) -> io::Result<Vec<String>> {
        Ok(Memory::names(self))
    }

    fn delete(&self, name: &str) -> io::Result<()> {
        self.0.lock().unwrap().remove(name);
        Ok(())
    }
}

fn record(id: &str, submitted: u64) -> JobRecord {
    JobRecord {
        format: JOB_FORMAT.into(),
        id: id.into(),
        owner: "alice".into(),
        study: "sweep".into(),
        request: json!({"system": "pendulum"}),
        priority: 0,
        submitted_unix_ms: submitted,
        cells: 8,
        part_cells: 4,
        recordings_quota: None,
    }
}

#[test]
fn a_store_on_an_empty_directory_takes_its_jobs_back_from_the_replica() {
    let root = crate::server::scratch_dir("job-replica");
    let memory = Arc::new(Memory::default());
    let (first, found) = JobStore::open(root.join("first"));
    assert!(found.is_empty());
    first.replicate_to(memory.clone());

    let id = new_id();
    let job = first.create(&record(&id, 1)).unwrap();
    job.write_part(0, &[1.5f64, 2.5, 3.5, 4.5]).unwrap();
    job.write_part(4, &[5.0f64, 6.0, 7.0, 8.0]).unwrap();
    job.append_event(br#"{"seq":1}"#).unwrap();
    let outcome = JobOutcome {
        state: "done".into(),
        error: None,
        ended_unix_ms: 2,
        recording: None,
    };
    job.write_outcome(&outcome).unwrap();
    job.write_result("result.json", b"{\"runs\":[]}").unwrap();
    let files = [
        "job.json",
        "parts/0-4.json",
        "parts/4-8.json",
        "outcome.json",
        "result.json",
    ];
    let mut expected: Vec<String> = files.iter().map(|f| format!("{id}/{f}")).collect();
    expected.sort();
    assert_eq!(memory.names(), expected, "every file but the event log");
    for file in files {
        let on_disk = std::fs::read(root.join("first").join(&id).join(file)).unwrap();
        assert_eq!(
            memory.get(&format!("{id}/{file}")).unwrap(),
            on_disk,
            "{file}"
        );
    }

    // Another job, kept with names no store writes, and a part without its record.
    let other = new_id();
    let other_record = serde_json::to_vec(&record(&other, 0)).unwrap();
    memory.insert(&format!("{other}/job.json"), &other_record);
    memory.insert(&format!("{other}/parts/0-4.json"), b"{}");
    for hostile in [
        "../escape.json",
        "parts/x/y.json",
        ".tmp-1",
        "",
        "parts/..",
        "parts",
    ] {
        memory.insert(&format!("{other}/{hostile}"), b"x");
    }
    let orphan = new_id();
    memory.insert(&format!("{orphan}/parts/0-4.json"), b"{}");
    // A job one of whose files cannot be read: not taken back, and nothing of it left here.
    let broken = new_id();
    let broken_record = serde_json::to_vec(&record(&broken, 2)).unwrap();
    memory.insert(&format!("{broken}/job.json"), &broken_record);
    memory.unreadable(&format!("{broken}/parts/0-4.json"));

    let (second, found) = JobStore::open(root.join("second"));
    assert!(found.is_empty());
    second.replicate_to(memory.clone());
    let restored = second.restore();
    let ids: Vec<&str> = restored.iter().map(|(r, _)| r.id.as_str()).collect();
    assert_eq!(ids, [other.as_str(), id.as_str()], "oldest first");
    assert_eq!(restored[1].0, record(&id, 1));
    let parts: Vec<f64> = restored[1].1.read_part(&(0..4)).unwrap();
    assert_eq!(parts, [1.5, 2.5, 3.5, 4.5]);
    assert_eq!(restored[1].1.outcome(), Some(outcome));
    assert_eq!(restored[1].1.parts_stored(), 2);
    assert!(
        restored[1].1.events().is_empty(),
        "the event log is not kept"
    );
    let second_dir = root.join("second");
    assert!(!second_dir.join("escape.json").exists());
    assert!(!second_dir.join(&other).join("parts/x").exists());
    assert!(!second_dir.join(&orphan).exists(), "no record, no job");
    assert!(
        !second_dir.join(&broken).exists(),
        "a job taken back whole or not at all"
    );
    let mut other_files: Vec<String> = std::fs::read_dir(second_dir.join(&other))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    other_files.sort();
    assert_eq!(other_files, ["job.json", "parts"]);
    assert!(second.restore().is_empty(), "each job taken back once");

    // A removal takes the job's names out of the replica, and only those.
    restored[1].1.remove().unwrap();
    assert!(memory.names().iter().all(|n| !n.starts_with(&id)));
    assert!(memory.names().contains(&format!("{other}/job.json")));
}

/// A job begun without a replica goes into one whole, once, when its server has one.
#[test]
fn a_job_begun_without_a_replica_goes_into_one_whole() {
    let root = crate::server::scratch_dir("job-replica-late");
    let (store, _) = JobStore::open(&root);
    let id = new_id();
    let job = store.create(&record(&id, 1)).unwrap();
    job.write_part(0, &[1.0f64, 2.0, 3.0, 4.0]).unwrap();
    assert_eq!(
        job.replicate_missing().unwrap(),
        0,
        "no replica, nothing put"
    );
    let memory = Arc::new(Memory::default());
    store.replicate_to(memory.clone());
    job.write_part(4, &[5.0f64, 6.0, 7.0, 8.0]).unwrap();
    assert_eq!(memory.names(), [format!("{id}/parts/4-8.json")]);
    assert_eq!(
        job.replicate_missing().unwrap(),
        2,
        "the record and the first part"
    );
    let expected = ["job.json", "parts/0-4.json", "parts/4-8.json"].map(|f| format!("{id}/{f}"));
    assert_eq!(memory.names(), expected);
    assert_eq!(job.replicate_missing().unwrap(), 0, "once");
}

/// A replica that takes nothing (a NATS server gone for longer than the bucket's patience).
#[derive(Debug)]
struct Refusing;

impl Replica for Refusing {
    fn put(&self, name: &str, _: &[u8]) -> io::Result<()> {
        Err(io::Error::other(format!("cannot keep {name}: no answer")))
    }

    fn get(&self, name: &str) -> io::Result<Vec<u8>> {
        Err(io::Error::other(format!("cannot read {name}: no answer")))
    }

    fn names(&self) -> io::Result<Vec<String>> {
        Err(io::Error::other("cannot list: no answer"))
    }

    fn delete(&self, name: &str) -> io::Result<()> {
        Err(io::Error::other(format!("cannot delete {name}: no answer")))
    }
}

#[test]
fn a_job_the_replica_refuses_is_not_left_on_disk() {
    let root = crate::server::scratch_dir("job-replica-refusing");
    let (store, _) = JobStore::open(&root);
    store.replicate_to(Arc::new(Refusing));
    let id = new_id();
    let error = store.create(&record(&id, 1)).unwrap_err();
    let inner = error
        .get_ref()
        .and_then(|e| e.downcast_ref::<NotReplicated>());
    assert!(
        inner.is_some_and(|e| e.0.contains("no answer")),
        "{error:?}"
    );
    assert!(!root.join(&id).exists(), "a refused job is no job");
    let (_, found) = JobStore::open(&root);
    assert!(found.is_empty());
    assert!(
        store.restore().is_empty(),
        "an unreachable replica gives back nothing"
    );
}
