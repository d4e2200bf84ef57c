//! The DOP853 tableau: the explicit Runge–Kutta method of order 8 by Dormand and Prince with
//! Hairer's embedded error estimators of orders 5 and 3 (Hairer, Nørsett, Wanner, *Solving
//! Ordinary Differential Equations I*, 2nd ed., Sec. II.10; coefficients as published in Hairer's
//! `dop853.f`, to 30 digits). The twelve stages k₁ … k₁₂ of a step give
//!
//! ```text
//! y₁ = y₀ + h Σ bᵢ kᵢ,
//! err₅ = h Σ eᵢ kᵢ,        err₃ = h (Σ bᵢ kᵢ − bhh₁ k₁ − bhh₂ k₉ − bhh₃ k₁₂),
//! ```
//!
//! and the step's error measure combines the two as HNW's code does (see `reference`). The
//! three extra stages of the dense output are not needed: the reference only reports step
//! endpoints.

/// An explicit Runge–Kutta tableau with two embedded error estimators.
#[derive(Debug)]
pub struct EmbeddedTableau {
    /// Stage coefficients: row i holds a_ij for j < i (zero beyond).
    pub a: [[f64; 11]; 12],
    /// Weights of the eighth-order solution.
    pub b: [f64; 12],
    /// Nodes c_i = Σ_j a_ij (the method is applied to autonomous fields; kept for the checks).
    pub c: [f64; 12],
    /// Weights of the fifth-order error estimate err₅.
    pub e: [f64; 12],
    /// Weights on k₁, k₉ and k₁₂ of the third-order estimate err₃.
    pub bhh: [f64; 3],
}

/// DOP853: Dormand–Prince 8(5,3), HNW I Sec. II.10.
#[allow(clippy::excessive_precision)] // as published (30 digits); the compiler rounds to f64
pub const DOP853: EmbeddedTableau = EmbeddedTableau {
    a: [
        [0.0; 11],
        [
            5.26001519587677318785587544488e-2,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            1.97250569845378994544595329183e-2,
            5.91751709536136983633785987549e-2,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            2.95875854768068491816892993775e-2,
            0.0,
            8.87627564304205475450678981324e-2,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            2.41365134159266685502369798665e-1,
            0.0,
            -8.84549479328286085344864962717e-1,
            9.24834003261792003115737966543e-1,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            3.7037037037037037037037037037e-2,
            0.0,
            0.0,
            1.70828608729473871279604482173e-1,
            1.25467687566822425016691814123e-1,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            3.7109375e-2,
            0.0,
            0.0,
            1.70252211019544039314978060272e-1,
            6.02165389804559606850219397283e-2,
            -1.7578125e-2,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            3.70920001185047927108779319836e-2,
            0.0,
            0.0,
            1.70383925712239993810214054705e-1,
            1.07262030446373284651809199168e-1,
            -1.53194377486244017527936158236e-2,
            8.27378916381402288758473766002e-3,
            0.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            6.24110958716075717114429577812e-1,
            0.0,
            0.0,
            -3.36089262944694129406857109825,
            -8.68219346841726006818189891453e-1,
            2.75920996994467083049415600797e1,
            2.01540675504778934086186788979e1,
            -4.34898841810699588477366255144e1,
            0.0,
            0.0,
            0.0,
        ],
        [
            4.77662536438264365890433908527e-1,
            0.0,
            0.0,
            -2.48811461997166764192642586468,
            -5.90290826836842996371446475743e-1,
            2.12300514481811942347288949897e1,
            1.52792336328824235832596922938e1,
            -3.32882109689848629194453265587e1,
            -2.03312017085086261358222928593e-2,
            0.0,
            0.0,
        ],
        [
            -9.3714243008598732571704021658e-1,
            0.0,
            0.0,
            5.18637242884406370830023853209,
            1.09143734899672957818500254654,
            -8.14978701074692612513997267357,
            -1.85200656599969598641566180701e1,
            2.27394870993505042818970056734e1,
            2.49360555267965238987089396762,
            -3.0467644718982195003823669022,
            0.0,
        ],
        [
            2.27331014751653820792359768449,
            0.0,
            0.0,
            -1.05344954667372501984066689879e1,
            -2.00087205822486249909675718444,
            -1.79589318631187989172765950534e1,
            2.79488845294199600508499808837e1,
            -2.85899827713502369474065508674,
            -8.87285693353062954433549289258,
            1.23605671757943030647266201528e1,
            6.43392746015763530355970484046e-1,
        ],
    ],
    b: [
        5.42937341165687622380535766363e-2,
        0.0,
        0.0,
        0.0,
        0.0,
        4.45031289275240888144113950566,
        1.89151789931450038304281599044,
        -5.8012039600105847814672114227,
        3.1116436695781989440891606237e-1,
        -1.52160949662516078556178806805e-1,
        2.01365400804030348374776537501e-1,
        4.47106157277725905176885569043e-2,
    ],
    c: [
        0.0,
        0.526001519587677318785587544488e-1,
        0.789002279381515978178381316732e-1,
        0.118350341907227396726757197510,
        0.281649658092772603273242802490,
        0.333333333333333333333333333333,
        0.25,
        0.307692307692307692307692307692,
        0.651282051282051282051282051282,
        0.6,
        0.857142857142857142857142857142,
        1.0,
    ],
    e: [
        0.1312004499419488073250102996e-1,
        0.0,
        0.0,
        0.0,
        0.0,
        -0.1225156446376204440720569753e1,
        -0.4957589496572501915214079952,
        0.1664377182454986536961530415e1,
        -0.3503288487499736816886487290,
        0.3341791187130174790297318841,
        0.8192320648511571246570742613e-1,
        -0.2235530786388629525884427845e-1,
    ],
    bhh: [
        0.244094488188976377952755905512,
        0.733846688281611857341361741547,
        0.220588235294117647058823529412e-1,
    ],
};

/// A vector a step's stages are made of: the state (the adaptive reference), or the state with
/// its time (Hénon's step in `sections`).
pub trait StageVector {
    /// self ← x.
    fn assign(&mut self, x: &Self);
    /// self ← self + x·c, component by component.
    fn add_scaled(&mut self, x: &Self, c: f64);
    /// self ← x·c, component by component.
    fn assign_scaled(&mut self, x: &Self, c: f64);
}

impl EmbeddedTableau {
    /// The stages k₂ … k₁₂ of a step of size `h` from `y`, with k₁ in `k[0]` and `field(x, out)`
    /// writing f(x): stage s is y + Σⱼ (h aₛⱼ) kⱼ, summed left to right over every j < s, the
    /// zero coefficients included (the adaptive reference reproduces an implementation that adds
    /// them; a term (h·0)·kⱼ of finite kⱼ can change no more than the sign of a zero).
    #[inline(always)]
    pub fn stages<V: StageVector>(
        &self,
        y: &V,
        h: f64,
        k: &mut [V],
        stage: &mut V,
        mut field: impl FnMut(&V, &mut V),
    ) {
        for s in 1..self.b.len() {
            stage.assign(y);
            let (known, next) = k.split_at_mut(s);
            for (kj, a) in known.iter().zip(&self.a[s]) {
                stage.add_scaled(kj, h * a);
            }
            field(stage, &mut next[0]);
        }
    }

    /// The slope Σ bᵢ kᵢ over the non-zero weights b₁, b₆ … b₁₂ (b₂ … b₅ vanish), summed left
    /// to right.
    #[inline(always)]
    pub fn slope<V: StageVector>(&self, k: &[V], slope: &mut V) {
        slope.assign_scaled(&k[0], self.b[0]);
        for (ki, b) in k.iter().zip(&self.b).skip(5) {
            slope.add_scaled(ki, *b);
        }
    }

    /// The third-order error estimate err₃/h = Σ bᵢ kᵢ − bhh₁ k₁ − bhh₂ k₉ − bhh₃ k₁₂, from the
    /// `slope` Σ bᵢ kᵢ.
    #[inline(always)]
    pub fn third_order_error<V: StageVector>(&self, k: &[V], slope: &V, err3: &mut V) {
        err3.assign(slope);
        err3.add_scaled(&k[0], -self.bhh[0]);
        err3.add_scaled(&k[8], -self.bhh[1]);
        err3.add_scaled(&k[11], -self.bhh[2]);
    }
}
