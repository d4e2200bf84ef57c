//! How jobs share the machine: one part at a time per slot of the gate, and the next part goes to
//! the owner that has been given the fewest steps — start-time fair queueing (Goyal, Vin & Cheng,
//! SIGCOMM 1996) with an owner as a flow and a part's predicted steps as its length. Among one
//! owner's parts the job of highest priority goes first, then the one submitted first.
//!
//! So one owner's thousand-part job and another owner's small job take turns part by part, and
//! the small one ends after about twice its own time, not after the large one. An owner that
//! arrives (or comes back) starts at the gate's clock, the count the last turn started from, so
//! it cannot claim the time it was away as a burst that would stall the others.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// What a waiting part asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Claim {
    /// Its job's owner.
    pub owner: String,
    /// Its job's priority among its owner's jobs (higher first).
    pub priority: i32,
    /// Its job's submission time (milliseconds since the Unix epoch) and id: the order among
    /// jobs of equal priority.
    pub submitted: (u64, String),
    /// The steps it predicts.
    pub steps: u64,
}

/// The claim among `waiting` that goes next, given the steps each owner has been given: the
/// owner least served (between equals, the one whose oldest claim is older), and of its claims
/// the one of highest priority, then the oldest. A priority orders an owner's own jobs only.
pub fn next(waiting: &[Claim], served: &HashMap<String, u64>) -> Option<usize> {
    let served = |owner: &str| served.get(owner).copied().unwrap_or(0);
    let oldest = |owner: &str| {
        waiting
            .iter()
            .filter(|c| c.owner == owner)
            .map(|c| &c.submitted)
            .min()
    };
    let owner = waiting
        .iter()
        .map(|c| c.owner.as_str())
        .min_by_key(|&o| (served(o), oldest(o)))?;
    (0..waiting.len())
        .filter(|&i| waiting[i].owner == owner)
        .min_by_key(|&i| (-i64::from(waiting[i].priority), &waiting[i].submitted))
}

#[derive(Debug, Default)]
struct GateState {
    free: usize,
    /// Waiting claims with their tickets.
    waiting: Vec<(u64, Claim)>,
    next_ticket: u64,
    /// Steps given to each owner.
    served: HashMap<String, u64>,
    /// The count the last turn given started from (its owner's before it): where an owner
    /// that arrives starts.
    clock: u64,
}

impl GateState {
    fn claims(&self) -> Vec<Claim> {
        self.waiting.iter().map(|(_, c)| c.clone()).collect()
    }

    fn withdraw(&mut self, ticket: u64) {
        self.waiting.retain(|(t, _)| *t != ticket);
    }
}

/// The gate parts pass to run.
#[derive(Debug, Default)]
pub struct FairGate {
    state: Mutex<GateState>,
    changed: Condvar,
}

/// A part's turn: its slot is given back when dropped.
#[derive(Debug)]
pub struct Turn<'a> {
    gate: &'a FairGate,
}

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        self.gate.lock().free += 1;
        self.gate.changed.notify_all();
    }
}

impl FairGate {
    /// A gate letting `slots` parts run at once.
    pub fn new(slots: usize) -> Self {
        FairGate {
            state: Mutex::new(GateState {
                free: slots.max(1),
                ..GateState::default()
            }),
            changed: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, GateState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Waits for `claim`'s turn; `None` once `stop` is set (the job was cancelled or the server
    /// is stopping).
    pub fn wait(&self, claim: Claim, stop: &AtomicBool) -> Option<Turn<'_>> {
        let mut state = self.lock();
        let ticket = state.next_ticket;
        state.next_ticket += 1;
        // An owner arriving (or back after a pause) starts at the gate's clock: the count its
        // last turn started from.
        let clock = state.clock;
        let own = state.served.entry(claim.owner.clone()).or_insert(0);
        *own = (*own).max(clock);
        state.waiting.push((ticket, claim));
        loop {
            if stop.load(Ordering::Relaxed) {
                state.withdraw(ticket);
                drop(state);
                self.changed.notify_all();
                return None;
            }
            if state.free > 0 {
                let chosen = next(&state.claims(), &state.served).map(|i| state.waiting[i].0);
                if chosen == Some(ticket) {
                    let index = state.waiting.iter().position(|(t, _)| *t == ticket);
                    let (_, claim) = state.waiting.remove(index.unwrap_or(0));
                    state.free -= 1;
                    let served = state.served.entry(claim.owner).or_insert(0);
                    let start = *served;
                    *served += claim.steps.max(1);
                    state.clock = start;
                    drop(state);
                    self.changed.notify_all();
                    return Some(Turn { gate: self });
                }
            }
            // Woken when a turn ends or a claim comes or goes; the timeout notices `stop`.
            state = self
                .changed
                .wait_timeout(state, Duration::from_millis(100))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Wakes every waiter (after `stop` flags were set).
    pub fn wake(&self) {
        self.changed.notify_all();
    }
}
