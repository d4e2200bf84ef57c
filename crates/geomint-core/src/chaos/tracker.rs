//! One run's deviation vectors and the running sums of its indicators: advanced by the driver
//! after every step (the range guard), updated on the grid of every `qr_every` steps
//! (re-orthonormalisation, MEGNO, FLI, the directions behind SALI and GALI, thresholds), and read
//! at samples without being changed. [`OneVectorLanes`] keeps the sums of one vector for many
//! runs side by side, updated together with the same arithmetic.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, Dim};

use super::frame;
use super::{ChaosPlan, Indicator, IndicatorValues, Statistic};
use crate::system::{MechanicalSystem, State};
use crate::tangent::Tangent;

/// MEGNO's running sums at the last grid point (module docs of `chaos`).
#[derive(Clone, Copy, Debug, Default)]
struct Megno {
    /// ln δ.
    l: f64,
    /// Σ Δ_i (t_{i−1} + t_i)/2.
    s: f64,
    /// Y.
    y: f64,
    /// ∫ Y dt.
    integral: f64,
}

impl Megno {
    /// The sums after a grid interval [t0, t1] over which ln δ went from `self.l` to `l`.
    #[inline(always)]
    fn advance(self, l: f64, t0: f64, t1: f64) -> Megno {
        let s = self.s + 0.5 * (t0 + t1) * (l - self.l);
        let y = 2.0 * s / t1;
        let integral = self.integral + 0.5 * (self.y + y) * (t1 - t0);
        Megno { l, s, y, integral }
    }
}

/// The tangent dynamics of one run and its indicators.
pub struct Tracker<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// The deviation vectors (`tangent.jac`, 2n × k) and the tangent maps' work space.
    pub tangent: Tangent<D>,
    plan: ChaosPlan,
    h: f64,
    /// Power-of-two exponents the range guard took out of each column since the last update.
    exponents: Vec<i32>,
    /// Σ ln R_ii up to the last update.
    log_r: Vec<f64>,
    /// The normalised columns of R̃ (k × k): the directions SALI and GALI read.
    directions: DMatrix<f64>,
    last_step: u64,
    megno: Megno,
    fli: f64,
    /// Scratch: a copy of the vectors, R, the directions at a sample, and growths.
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    peek_directions: DMatrix<f64>,
    work: DMatrix<f64>,
    growth: Vec<f64>,
    sorted: Vec<f64>,
}

/// What one interval adds, before it is kept or dropped.
struct Interval {
    megno: Megno,
    fli: f64,
}

impl<D: Dim> Tracker<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The deviation vectors of `plan` at `z`, for a run of step `h`.
    pub fn new<S: MechanicalSystem<Dim = D>>(
        sys: &S,
        z: &State<D>,
        plan: &ChaosPlan,
        h: f64,
    ) -> Self {
        let n = z.q.len();
        let k = plan.deviations;
        Tracker {
            tangent: Tangent::with_columns(sys, z, frame::start(n, k)),
            plan: plan.clone(),
            h,
            exponents: vec![0; k],
            log_r: vec![0.0; k],
            directions: DMatrix::identity(k, k),
            last_step: 0,
            megno: Megno::default(),
            fli: 0.0,
            q: DMatrix::zeros(2 * n, k),
            r: DMatrix::zeros(k, k),
            peek_directions: DMatrix::zeros(k, k),
            work: DMatrix::zeros(k, k),
            growth: vec![0.0; k],
            sorted: Vec::with_capacity(k),
        }
    }

    /// Steps between updates.
    pub fn qr_every(&self) -> u64 {
        self.plan.qr_every
    }

    /// Adds the powers of two by which the deviation vectors were scaled outside the tracker
    /// (the lanes keep them in range themselves) since it last saw them.
    pub fn add_exponents(&mut self, exponents: &[i32]) {
        for (e, x) in self.exponents.iter_mut().zip(exponents) {
            *e += x;
        }
    }

    /// After step `step` (counted from 1): keeps the vectors in range, and on the grid updates
    /// the indicators. Returns the threshold a grid update found passed: the statistic, its
    /// value and the threshold.
    #[inline]
    pub fn after_step(&mut self, step: u64) -> Option<(Statistic, f64, f64)> {
        frame::guard(&mut self.tangent.jac, &mut self.exponents);
        if !step.is_multiple_of(self.plan.qr_every) {
            return None;
        }
        self.update(step);
        if self.plan.stop_when.is_empty() {
            return None;
        }
        let values = self.values_at(step, false);
        self.plan
            .stop_when
            .iter()
            .find_map(|&(statistic, threshold)| {
                let value = values.get(statistic)?;
                let passed = if statistic.grows_with_chaos() {
                    value >= threshold
                } else {
                    value <= threshold
                };
                passed.then_some((statistic, value, threshold))
            })
    }

    /// Re-orthonormalises the vectors and keeps the interval's growth.
    fn update(&mut self, step: u64) {
        frame::orthonormalise(&mut self.tangent.jac, &mut self.r);
        for (g, (i, &e)) in self
            .growth
            .iter_mut()
            .zip(self.exponents.iter().enumerate())
        {
            *g = frame::log_growth(self.r[(i, i)], e);
        }
        let interval = self.interval(step);
        for (sum, g) in self.log_r.iter_mut().zip(&self.growth) {
            *sum += g;
        }
        if self.wants_directions() {
            frame::advance_directions(
                &mut self.directions,
                &self.r,
                &self.exponents,
                &mut self.work,
            );
        }
        self.exponents.fill(0);
        self.megno = interval.megno;
        self.fli = interval.fli;
        self.last_step = step;
    }

    fn wants_directions(&self) -> bool {
        self.plan.asks(Indicator::Sali) || self.plan.asks(Indicator::Gali)
    }

    /// MEGNO and FLI with the interval since the last update ending at `step`, whose growths are
    /// in `growth`.
    fn interval(&self, step: u64) -> Interval {
        let l = self.log_r[0] + self.growth[0];
        if step == self.last_step {
            return Interval {
                megno: self.megno,
                fli: self.fli,
            };
        }
        let (t0, t1) = (self.last_step as f64 * self.h, step as f64 * self.h);
        Interval {
            megno: self.megno.advance(l, t0, t1),
            fli: self.fli.max(l),
        }
    }

    /// The indicators at step `step` (a sample), as an update there would give them; the run
    /// is not changed.
    pub fn peek(&mut self, step: u64) -> IndicatorValues {
        self.values_at(step, true)
    }

    /// The indicators at `step`: after an update at `step` (`measure` false) from the kept sums,
    /// else (`measure` true) from a re-orthonormalised copy of the vectors.
    fn values_at(&mut self, step: u64, measure: bool) -> IndicatorValues {
        let fresh = measure && step != self.last_step;
        if fresh {
            self.q.copy_from(&self.tangent.jac);
            frame::orthonormalise(&mut self.q, &mut self.r);
            for (g, (i, &e)) in self
                .growth
                .iter_mut()
                .zip(self.exponents.iter().enumerate())
            {
                *g = frame::log_growth(self.r[(i, i)], e);
            }
        } else {
            self.growth.fill(0.0);
        }
        let interval = self.interval(step);
        let t = step as f64 * self.h;
        let mut values = IndicatorValues::default();
        let plan = &self.plan;
        if plan.asks(Indicator::Lyapunov) {
            self.sorted.clear();
            self.sorted
                .extend(self.log_r.iter().zip(&self.growth).map(|(sum, g)| {
                    if t > 0.0 {
                        (sum + g) / t
                    } else {
                        0.0
                    }
                }));
            self.sorted.sort_by(|a, b| b.total_cmp(a));
            values.lyapunov = Some(self.sorted.clone());
        }
        if plan.asks(Indicator::Megno) {
            values.megno = Some(interval.megno.y);
            values.megno_mean = Some(if t > 0.0 {
                interval.megno.integral / t
            } else {
                0.0
            });
        }
        if plan.asks(Indicator::Fli) {
            values.fli = Some(interval.fli);
        }
        if self.wants_directions() {
            self.peek_directions.copy_from(&self.directions);
            if fresh {
                frame::advance_directions(
                    &mut self.peek_directions,
                    &self.r,
                    &self.exponents,
                    &mut self.work,
                );
            }
            if plan.asks(Indicator::Sali) {
                values.sali = Some(frame::sali(&self.peek_directions));
            }
            if plan.asks(Indicator::Gali) {
                values.gali = Some(frame::gali(&self.peek_directions));
            }
        }
        values
    }
}

/// The sums of one deviation vector (k = 1, without the directions of SALI and GALI, which need
/// two) for `L` runs side by side, updated on the grid together: lane by lane what
/// [`Tracker::after_step`]'s update keeps, with its arithmetic, where ln δ, MEGNO's sums and the
/// FLI are all a lane needs (Σ ln R₁₁ is ln δ itself). A run with thresholds keeps its own
/// tracker, which looks at them after every update.
#[derive(Clone, Debug)]
pub struct OneVectorLanes<const L: usize> {
    h: f64,
    /// ln δ.
    l: [f64; L],
    s: [f64; L],
    y: [f64; L],
    integral: [f64; L],
    fli: [f64; L],
    last_step: [u64; L],
}

impl<const L: usize> OneVectorLanes<L> {
    /// The sums of runs of step `h` if their plan has them kept here, all at the start.
    pub fn new(plan: &ChaosPlan, h: f64) -> Option<Self> {
        let one_vector = plan.deviations == 1
            && plan.stop_when.is_empty()
            && !plan.asks(Indicator::Sali)
            && !plan.asks(Indicator::Gali);
        one_vector.then_some(OneVectorLanes {
            h,
            l: [0.0; L],
            s: [0.0; L],
            y: [0.0; L],
            integral: [0.0; L],
            fli: [0.0; L],
            last_step: [0; L],
        })
    }

    /// The update at `step` of the lanes in `due`, whose vectors had norm `r` (R₁₁, positive
    /// and finite) and were scaled by 2^`exponents` since the last update.
    // Lanes are indexed side by side in several arrays: the form the compiler vectorises.
    #[allow(clippy::needless_range_loop)]
    pub fn update(&mut self, step: u64, r: &[f64; L], exponents: &[i32; L], due: &[bool; L]) {
        let t1 = step as f64 * self.h;
        let mut growth = [0.0; L];
        for i in 0..L {
            if due[i] {
                growth[i] = frame::log_growth(r[i], exponents[i]);
            }
        }
        for i in 0..L {
            let l = self.l[i] + growth[i];
            let t0 = self.last_step[i] as f64 * self.h;
            let kept = Megno {
                l: self.l[i],
                s: self.s[i],
                y: self.y[i],
                integral: self.integral[i],
            };
            let m = kept.advance(l, t0, t1);
            let fli = self.fli[i].max(l);
            if due[i] {
                (self.l[i], self.s[i], self.y[i], self.integral[i]) = (m.l, m.s, m.y, m.integral);
                self.fli[i] = fli;
                self.last_step[i] = step;
            }
        }
    }

    /// Gives lane `i`'s sums to its run's `tracker`, as though the tracker had made the last
    /// update itself (its vectors and the exponents since then are the caller's to give).
    pub fn hand_to<D: Dim>(&self, i: usize, tracker: &mut Tracker<D>)
    where
        DefaultAllocator: Allocator<D>,
    {
        tracker.log_r[0] = self.l[i];
        tracker.megno = Megno {
            l: self.l[i],
            s: self.s[i],
            y: self.y[i],
            integral: self.integral[i],
        };
        tracker.fli = self.fli[i];
        tracker.last_step = self.last_step[i];
        tracker.exponents.fill(0);
    }

    /// Takes lane `i`'s sums back from `tracker` after it updated them itself.
    pub fn take_from<D: Dim>(&mut self, i: usize, tracker: &Tracker<D>)
    where
        DefaultAllocator: Allocator<D>,
    {
        self.l[i] = tracker.log_r[0];
        self.s[i] = tracker.megno.s;
        self.y[i] = tracker.megno.y;
        self.integral[i] = tracker.megno.integral;
        self.fli[i] = tracker.fli;
        self.last_step[i] = tracker.last_step;
    }
}
