//! Regular or chaotic: chaos indicators from deviation vectors advanced by each method's own
//! tangent map (see [`crate::tangent`]), the tangent-map method of Skokos & Gerlach (Phys. Rev. E
//! 82 (2010) 036704). A symplectic method's tangent map is symplectic and a conformal
//! symplectic one's conformal, so the exponents pair as the flow's do (Dressler 1988; Wojtkowski
//! & Liverani 1998 for the conformal case): λ_i + λ_{2n+1−i} = −2γ — at every finite time, with
//! the frame of [`frame`].
//!
//! With A(t) the product of the step tangent maps and v₁…v_k the starting frame:
//! - **Lyapunov spectrum** (Benettin et al., Meccanica 15 (1980) 9 and 21): A V = Q R̃ by
//!   re-orthonormalising every `qr_every` steps; λ_i(t) = ln R̃_ii/t, reported largest first.
//! - **MEGNO** (Cincotta & Simó, A&AS 147 (2000) 205): Y(t) = (2/t)∫₀ᵗ s d(ln δ(s)), with
//!   δ = ‖A v₁‖, and its mean ⟨Y⟩(t) = (1/t)∫₀ᵗ Y(s) ds. Quasi-periodic motion gives ⟨Y⟩ → 2
//!   (δ grows linearly), an isochronous one ⟨Y⟩ → 0 (δ bounded), chaos ⟨Y⟩ ≈ λ₁t/2.
//!   *Discrete form.* A method is a map, known at the steps t_j = j·m·h of the re-orthonormalisation
//!   grid. Taking ln δ linear in t between grid points makes the integral exact: over
//!   [t_{j−1}, t_j], ∫ s d(ln δ) = Δ_j (t_{j−1} + t_j)/2 with Δ_j = ln δ_j − ln δ_{j−1}, so
//!   Y_j = (2/t_j) Σ_{i≤j} Δ_i (t_{i−1} + t_i)/2, and ⟨Y⟩_j = (1/t_j) Σ_{i≤j} (Y_{i−1} + Y_i)
//!   (t_i − t_{i−1})/2 by the trapezoidal rule, Y₀ = 0. For δ = e^{λt} this gives Y = λt and
//!   ⟨Y⟩ = λt/2 exactly. (Cincotta, Giordano & Simó, Physica D 182 (2003) 151, write the
//!   map's form with weights i instead of i − ½: Y_N = (2/N)Σ i Δ_i. The two differ by
//!   ln(δ_N/δ₀)/N, which vanishes for regular motion and adds λh for chaos, so both have the
//!   same limits; ours is the continuous definition's quadrature.)
//! - **FLI** (Froeschlé, Lega & Gonczi, Celest. Mech. Dyn. Astron. 67 (1997) 41), in the
//!   one-vector form of Lega, Guzzo & Froeschlé (Physica D 182 (2003) 179):
//!   FLI(t) = sup_{s≤t} ln ‖A(s) v₁‖, the supremum over the grid and t.
//! - **SALI** (Skokos, J. Phys. A 34 (2001) 10029) of v₁, v₂ and **GALI_k** (Skokos, Bountis &
//!   Antonopoulos, Physica D 231 (2007) 30) of the k vectors, evolved without
//!   orthonormalisation: their directions are the normalised columns of R̃ in the Q basis, which
//!   the frame tracks, so they come from the same run without underflow (see [`frame`]).
//!
//! Indicators are updated on the grid of every `qr_every` steps; a sample between grid points
//! shows what an update at its step would give, without changing the run, so the numbers do not
//! depend on how often it is sampled. A threshold (`stop_when`) is looked at on the grid.

pub mod frame;
mod tracker;

use serde::{Deserialize, Serialize};

use crate::error::{CoreError, Field};
pub use tracker::{OneVectorLanes, Tracker};

/// Steps between re-orthonormalisations when a request does not say.
pub const DEFAULT_QR_EVERY: u64 = 10;

/// An indicator a request can ask for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Indicator {
    /// The Lyapunov spectrum (finite-time estimates), largest first.
    Lyapunov,
    /// MEGNO Y and its running mean ⟨Y⟩.
    Megno,
    /// The fast Lyapunov indicator.
    Fli,
    /// The smaller alignment index of the first two deviation vectors.
    Sali,
    /// The generalized alignment index of all deviation vectors.
    Gali,
}

impl Indicator {
    /// Every indicator, in the order answers list them.
    pub const ALL: [Indicator; 5] = [
        Indicator::Lyapunov,
        Indicator::Megno,
        Indicator::Fli,
        Indicator::Sali,
        Indicator::Gali,
    ];

    /// The name in requests.
    pub fn as_str(self) -> &'static str {
        match self {
            Indicator::Lyapunov => "lyapunov",
            Indicator::Megno => "megno",
            Indicator::Fli => "fli",
            Indicator::Sali => "sali",
            Indicator::Gali => "gali",
        }
    }

    /// The indicator of this name.
    pub fn parse(name: &str) -> Option<Indicator> {
        Indicator::ALL.into_iter().find(|i| i.as_str() == name)
    }

    /// Deviation vectors it needs at least.
    pub fn needs(self) -> usize {
        match self {
            Indicator::Sali | Indicator::Gali => 2,
            _ => 1,
        }
    }
}

/// A number the indicators report, by the name answers and thresholds give it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Statistic {
    /// The largest finite-time Lyapunov exponent.
    LyapunovMax,
    /// MEGNO Y(t).
    Megno,
    /// The running mean ⟨Y⟩(t).
    MegnoMean,
    /// FLI(t).
    Fli,
    /// SALI(t).
    Sali,
    /// GALI_k(t).
    Gali,
}

impl Statistic {
    /// Every statistic.
    pub const ALL: [Statistic; 6] = [
        Statistic::LyapunovMax,
        Statistic::Megno,
        Statistic::MegnoMean,
        Statistic::Fli,
        Statistic::Sali,
        Statistic::Gali,
    ];

    /// The name in answers and thresholds.
    pub fn as_str(self) -> &'static str {
        match self {
            Statistic::LyapunovMax => "lyapunov_max",
            Statistic::Megno => "megno",
            Statistic::MegnoMean => "megno_mean",
            Statistic::Fli => "fli",
            Statistic::Sali => "sali",
            Statistic::Gali => "gali",
        }
    }

    /// The statistic of this name.
    pub fn parse(name: &str) -> Option<Statistic> {
        Statistic::ALL.into_iter().find(|s| s.as_str() == name)
    }

    /// The indicator that reports it.
    pub fn indicator(self) -> Indicator {
        match self {
            Statistic::LyapunovMax => Indicator::Lyapunov,
            Statistic::Megno | Statistic::MegnoMean => Indicator::Megno,
            Statistic::Fli => Indicator::Fli,
            Statistic::Sali => Indicator::Sali,
            Statistic::Gali => Indicator::Gali,
        }
    }

    /// Whether chaos makes it grow (a threshold stops the run when the value reaches it from
    /// below), rather than fall to zero (SALI, GALI: stops when the value falls to it).
    pub fn grows_with_chaos(self) -> bool {
        !matches!(self, Statistic::Sali | Statistic::Gali)
    }
}

/// Where an indicator crossed its threshold, which stopped the run (`ThresholdStop` in the
/// OpenAPI document, the name it has always had there).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = ThresholdStop))]
pub struct ThresholdCrossing {
    /// The step at which it was seen (a step of the indicators' grid); the run's last sample.
    pub step: u64,
    /// Its time.
    pub t: f64,
    /// The statistic that reached its threshold, e.g. `megno_mean`.
    pub indicator: Statistic,
    /// Its value there.
    pub value: f64,
    /// The threshold.
    pub threshold: f64,
}

/// Where a request gave the indicators' inputs, as errors name them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChaosFields {
    /// `indicators`.
    pub indicators: Field,
    /// `deviations`.
    pub deviations: Field,
    /// `qr_every`.
    pub qr_every: Field,
    /// `stop_when`.
    pub stop_when: Field,
}

impl Default for ChaosFields {
    fn default() -> Self {
        ChaosFields {
            indicators: "indicators".into(),
            deviations: "deviations".into(),
            qr_every: "qr_every".into(),
            stop_when: "stop_when".into(),
        }
    }
}

/// The indicators as a request asks for them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChaosSpec {
    /// The indicators (at least one, each once).
    pub indicators: Vec<Indicator>,
    /// Deviation vectors k, 1 ≤ k ≤ 2n (default: 2n with `lyapunov` or `gali`, else 2 with
    /// `sali`, else 1).
    pub deviations: Option<usize>,
    /// Steps between re-orthonormalisations and indicator updates (default 10).
    pub qr_every: Option<u64>,
    /// Stop a run when one of these reaches its threshold (from below for growing statistics,
    /// from above for SALI and GALI).
    pub stop_when: Vec<(Statistic, f64)>,
    /// Where each input came from.
    pub fields: ChaosFields,
}

impl ChaosSpec {
    /// The indicators `indicators` with every option at its default.
    pub fn new(indicators: &[Indicator]) -> Self {
        ChaosSpec {
            indicators: indicators.to_vec(),
            deviations: None,
            qr_every: None,
            stop_when: Vec::new(),
            fields: ChaosFields::default(),
        }
    }

    /// Checks the spec for a system of `n` degrees of freedom.
    pub fn plan(&self, n: usize) -> Result<ChaosPlan, CoreError> {
        let f = &self.fields;
        if self.indicators.is_empty() {
            return Err(CoreError::Empty {
                field: f.indicators.clone(),
                what: "indicator",
            });
        }
        for (i, indicator) in self.indicators.iter().enumerate() {
            if self.indicators[..i].contains(indicator) {
                return Err(CoreError::Duplicate {
                    field: f.indicators.index(i),
                    value: indicator.as_str().to_string(),
                });
            }
        }
        let asks = |i: Indicator| self.indicators.contains(&i);
        let k = match self.deviations {
            Some(k) => k,
            None if asks(Indicator::Lyapunov) || asks(Indicator::Gali) => 2 * n,
            None if asks(Indicator::Sali) => 2,
            None => 1,
        };
        if !(1..=2 * n).contains(&k) {
            return Err(CoreError::Count {
                field: f.deviations.clone(),
                got: k as u64,
                min: 1,
                max: 2 * n as u64,
                what: "deviation vectors (1 to 2n, the phase-space dimension)",
            });
        }
        if let Some(&needy) = self.indicators.iter().find(|i| i.needs() > k) {
            return Err(CoreError::NeedsDeviations {
                field: f.deviations.clone(),
                indicator: needy.as_str(),
                needed: needy.needs(),
                got: k,
            });
        }
        let qr_every = self.qr_every.unwrap_or(DEFAULT_QR_EVERY);
        if qr_every == 0 {
            return Err(CoreError::Count {
                field: f.qr_every.clone(),
                got: 0,
                min: 1,
                max: u64::MAX,
                what: "steps between re-orthonormalisations",
            });
        }
        for &(statistic, threshold) in &self.stop_when {
            let field = f.stop_when.key(statistic.as_str());
            if !asks(statistic.indicator()) {
                return Err(CoreError::ThresholdWithoutIndicator {
                    field,
                    statistic: statistic.as_str(),
                    indicator: statistic.indicator().as_str(),
                });
            }
            if !threshold.is_finite() {
                return Err(CoreError::NotFinite { field });
            }
        }
        Ok(ChaosPlan {
            indicators: Indicator::ALL.into_iter().filter(|&i| asks(i)).collect(),
            deviations: k,
            qr_every,
            stop_when: self.stop_when.clone(),
        })
    }
}

/// Validated indicators for a system: what to report, with how many vectors, how often.
#[derive(Clone, Debug, PartialEq)]
pub struct ChaosPlan {
    /// The indicators asked for, in [`Indicator::ALL`]'s order.
    pub indicators: Vec<Indicator>,
    /// Deviation vectors k.
    pub deviations: usize,
    /// Steps between re-orthonormalisations.
    pub qr_every: u64,
    /// Thresholds that stop a run.
    pub stop_when: Vec<(Statistic, f64)>,
}

impl ChaosPlan {
    /// Whether `indicator` is reported.
    pub fn asks(&self, indicator: Indicator) -> bool {
        self.indicators.contains(&indicator)
    }
}

/// The indicators at one time: the ones asked for, the others `None`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct IndicatorValues {
    /// The finite-time Lyapunov spectrum, largest first (k exponents; 0 at t = 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lyapunov: Option<Vec<f64>>,
    /// MEGNO Y(t).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub megno: Option<f64>,
    /// MEGNO's running mean ⟨Y⟩(t).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub megno_mean: Option<f64>,
    /// The fast Lyapunov indicator.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fli: Option<f64>,
    /// The smaller alignment index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sali: Option<f64>,
    /// The generalized alignment index GALI_k.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gali: Option<f64>,
}

impl IndicatorValues {
    /// The value of `statistic`, if reported.
    pub fn get(&self, statistic: Statistic) -> Option<f64> {
        match statistic {
            Statistic::LyapunovMax => self.lyapunov.as_ref().and_then(|l| l.first().copied()),
            Statistic::Megno => self.megno,
            Statistic::MegnoMean => self.megno_mean,
            Statistic::Fli => self.fli,
            Statistic::Sali => self.sali,
            Statistic::Gali => self.gali,
        }
    }
}
