//! The jobs' fair gate: which waiting part goes next, and owners taking turns under contention.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use geomint::jobs::fair::{next, Claim, FairGate};

fn claim(owner: &str, priority: i32, submitted: u64, steps: u64) -> Claim {
    Claim {
        owner: owner.to_string(),
        priority,
        submitted: (submitted, format!("job{submitted}")),
        steps,
    }
}

/// The least served owner first (between equals, the one with the oldest job); within an owner
/// the highest priority, then the first submitted; a priority does not jump another owner's turn.
#[test]
fn the_least_served_owner_goes_first_then_priority_then_age() {
    let waiting = [
        claim("alice", 0, 1, 10),
        claim("alice", 5, 3, 10),
        claim("bob", 0, 2, 10),
        claim("bob", 0, 0, 10),
    ];
    let served = HashMap::from([("alice".to_string(), 100), ("bob".to_string(), 50)]);
    assert_eq!(next(&waiting, &served), Some(3), "bob's oldest job");
    let served = HashMap::from([("alice".to_string(), 50), ("bob".to_string(), 100)]);
    assert_eq!(next(&waiting, &served), Some(1), "alice's priority-5 job");
    let served = HashMap::from([("alice".to_string(), 100), ("bob".to_string(), 100)]);
    assert_eq!(
        next(&waiting, &served),
        Some(3),
        "equal service: the owner of the oldest job"
    );
    assert_eq!(next(&[], &served), None);
}

/// While alice's part runs, two more of hers and two of bob's wait: once it ends bob goes first
/// (his count starts at the clock, where alice's running part started), then they alternate —
/// bob is not given twice in a row the time before he arrived.
#[test]
fn owners_alternate_once_both_wait() {
    let gate = Arc::new(FairGate::new(1));
    let stop = AtomicBool::new(false);
    let first = gate.wait(claim("alice", 0, 0, 10), &stop).unwrap();
    let order = Arc::new(Mutex::new(Vec::new()));
    let mut threads = Vec::new();
    for (i, owner) in ["alice", "bob", "alice", "bob"].into_iter().enumerate() {
        let (gate, order) = (gate.clone(), order.clone());
        threads.push(std::thread::spawn(move || {
            let stop = AtomicBool::new(false);
            let turn = gate.wait(claim(owner, 0, 1 + i as u64, 10), &stop).unwrap();
            order.lock().unwrap().push(owner);
            std::thread::sleep(Duration::from_millis(5));
            drop(turn);
        }));
        // Each claim waits before the next arrives.
        std::thread::sleep(Duration::from_millis(30));
    }
    drop(first);
    for t in threads {
        t.join().unwrap();
    }
    assert_eq!(*order.lock().unwrap(), ["bob", "alice", "bob", "alice"]);
}

/// A waiting claim whose stop flag is set gives up its place.
#[test]
fn a_stopped_claim_leaves_the_queue() {
    let gate = FairGate::new(1);
    let stop = AtomicBool::new(false);
    let held = gate.wait(claim("alice", 0, 0, 10), &stop).unwrap();
    let stopped = AtomicBool::new(true);
    assert!(gate.wait(claim("bob", 0, 1, 10), &stopped).is_none());
    drop(held);
    assert!(gate.wait(claim("bob", 0, 2, 10), &stop).is_some());
}
