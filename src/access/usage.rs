//! What callers use now, for the quotas no store records: runs in flight and steps started in the
//! last minute, per owner (a token's name, an anonymous client's address).
//!
//! Both live in memory. Runs in flight end with their processes anyway; the rate is a GCRA
//! limiter (`governor`) per owner with a burst of one minute's quota, so a caller may spend its
//! minute at once and then gets it back continuously. A restart gives every caller a full minute.
//! Stored bytes and definitions are counted by the stores from what they keep on disk, so those
//! quotas hold across restarts.

use std::collections::HashMap;
use std::num::NonZeroU32;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use governor::clock::{Clock, DefaultClock};
use governor::{DefaultDirectRateLimiter, Quota};

use super::{Caller, Refusal};
use crate::core::error::{ErrorCode, ErrorDetail};

/// Limiters unused this long are full again, the same as new ones: dropped when many pile up.
const IDLE: Duration = Duration::from_secs(60);
/// How many limiters are kept before the idle ones are dropped.
const KEEP: usize = 4096;

#[derive(Debug)]
struct Rate {
    per_minute: u64,
    /// Steps per cell of the limiter (quotas beyond u32 cells count in larger units).
    unit: u64,
    limiter: DefaultDirectRateLimiter,
    used: Instant,
}

impl Rate {
    fn new(per_minute: u64) -> Self {
        let unit = per_minute.div_ceil(u64::from(u32::MAX)).max(1);
        let cells = u32::try_from(per_minute / unit).unwrap_or(u32::MAX).max(1);
        let cells = NonZeroU32::new(cells).unwrap_or(NonZeroU32::MIN);
        Rate {
            per_minute,
            unit,
            limiter: DefaultDirectRateLimiter::direct(Quota::per_minute(cells)),
            used: Instant::now(),
        }
    }
}

/// Runs in flight and recent steps per owner.
#[derive(Debug, Default)]
pub struct Usage {
    in_flight: Mutex<HashMap<String, usize>>,
    rates: Mutex<HashMap<String, Rate>>,
    clock: DefaultClock,
}

/// A run counted in flight for its owner until dropped.
#[derive(Debug)]
pub struct RunGuard {
    usage: Arc<Usage>,
    owner: String,
}

impl Drop for RunGuard {
    fn drop(&mut self) {
        let mut in_flight = self
            .usage
            .in_flight
            .lock()
            .unwrap_or_else(|p| p.into_inner());
        if let Some(n) = in_flight.get_mut(&self.owner) {
            *n -= 1;
            if *n == 0 {
                in_flight.remove(&self.owner);
            }
        }
    }
}

impl Usage {
    /// Runs `owner` has in flight now.
    pub fn runs_in_flight(&self, owner: &str) -> usize {
        let in_flight = self.in_flight.lock().unwrap_or_else(|p| p.into_inner());
        in_flight.get(owner).copied().unwrap_or(0)
    }

    /// Admits a run of `caller` predicting `steps` (`None` for a study, which the rate does not
    /// count): 401 past an anonymous client's small-run budget, 429 `too_many_runs` at its quota
    /// of runs in flight, 429 `rate_limited` with the wait in `Retry-After` past its steps per
    /// minute, 403 `quota_exceeded` for a run larger than a whole minute's steps.
    pub fn admit(
        self: &Arc<Self>,
        caller: &Caller,
        steps: Option<u64>,
    ) -> Result<RunGuard, Refusal> {
        if let Some(largest) = caller.largest_run {
            let what = match steps {
                Some(n) if n <= largest => None,
                Some(n) => Some(format!(
                    "a run of {n} steps × coordinates, more than the {largest} a client without a token may run"
                )),
                None => Some("a study, which a client without a token may not run".to_string()),
            };
            if let Some(what) = what {
                return Err(Refusal::from(ErrorDetail::at(
                    ErrorCode::Unauthorized,
                    "Authorization",
                    format!("{what}: send a token with the `run` scope"),
                )));
            }
        }
        let guard = self.enter(caller)?;
        if let (Some(per_minute), Some(n)) = (caller.quotas.steps_per_minute, steps) {
            self.charge(&caller.owner, per_minute, n)?;
        }
        Ok(guard)
    }

    /// Counts a run of `owner` in flight without checking its quota (a job that was admitted
    /// when it was submitted).
    pub fn hold(self: &Arc<Self>, owner: &str) -> RunGuard {
        let mut in_flight = self.in_flight.lock().unwrap_or_else(|p| p.into_inner());
        *in_flight.entry(owner.to_string()).or_insert(0) += 1;
        RunGuard {
            usage: Arc::clone(self),
            owner: owner.to_string(),
        }
    }

    fn enter(self: &Arc<Self>, caller: &Caller) -> Result<RunGuard, Refusal> {
        let mut in_flight = self.in_flight.lock().unwrap_or_else(|p| p.into_inner());
        let count = in_flight.entry(caller.owner.clone()).or_insert(0);
        if caller.quotas.runs.is_some_and(|max| *count >= max) {
            let max = caller.quotas.runs.unwrap_or(0);
            if *count == 0 {
                in_flight.remove(&caller.owner);
            }
            return Err(Refusal::from(ErrorDetail::new(
                ErrorCode::TooManyRuns,
                format!(
                    "`{}` has {max} runs in flight, its quota; retry once one ends",
                    caller.owner
                ),
            ))
            .with_retry_after(1));
        }
        *count += 1;
        Ok(RunGuard {
            usage: Arc::clone(self),
            owner: caller.owner.clone(),
        })
    }

    fn charge(&self, owner: &str, per_minute: u64, steps: u64) -> Result<(), Refusal> {
        let mut rates = self.rates.lock().unwrap_or_else(|p| p.into_inner());
        if rates.len() >= KEEP {
            rates.retain(|_, rate| rate.used.elapsed() < IDLE);
        }
        let rate = rates
            .entry(owner.to_string())
            .and_modify(|r| {
                if r.per_minute != per_minute {
                    *r = Rate::new(per_minute);
                }
            })
            .or_insert_with(|| Rate::new(per_minute));
        rate.used = Instant::now();
        let cells = steps.div_ceil(rate.unit);
        let Some(cells) = u32::try_from(cells).ok().and_then(NonZeroU32::new) else {
            if steps == 0 {
                return Ok(());
            }
            return Err(larger_than_rate(owner, steps, per_minute));
        };
        match rate.limiter.check_n(cells) {
            Ok(Ok(())) => Ok(()),
            Ok(Err(not_until)) => {
                let wait = not_until.wait_time_from(self.clock.now());
                let secs = wait.as_secs() + u64::from(wait.subsec_nanos() > 0);
                Err(Refusal::from(ErrorDetail::new(
                    ErrorCode::RateLimited,
                    format!(
                        "`{owner}` has started more than its {per_minute} steps per minute; \
                         this run of {steps} fits in {secs} s"
                    ),
                ))
                .with_retry_after(secs.max(1)))
            }
            Err(_) => Err(larger_than_rate(owner, steps, per_minute)),
        }
    }
}

fn larger_than_rate(owner: &str, steps: u64, per_minute: u64) -> Refusal {
    Refusal::from(ErrorDetail::new(
        ErrorCode::QuotaExceeded,
        format!("a run of {steps} steps is more than `{owner}`'s quota of {per_minute} steps per minute"),
    ))
}
