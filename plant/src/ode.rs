//! Dormand–Prince 8(5,3) explicit Runge–Kutta with step-size control and a 7th-order dense
//! output (Hairer, Nørsett & Wanner, *Solving ODEs I*, 2nd ed., Sec. II.10), for small
//! fixed-size systems on `nalgebra::SVector`.
//!
//! Written here rather than taken from a crate because the hybrid simulator needs three things
//! together that no crate we measured offers on this system at this cost: the dense output is
//! built lazily (three extra stages only for steps that contain an event), a step can be cut
//! to end exactly on a sample instant, and the step-size memory is plain data the plant carries
//! across zero-order-hold periods so that a lockstep run reproduces an offline one bit for bit.
//! See `bench/decisions-2026-11-28.md` for the comparison with `diffsol`.

// The coefficients are quoted with all the digits published for them.
#![allow(clippy::excessive_precision)]

use nalgebra::SVector;

/// Errors of the integrator.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OdeError {
    /// The step size fell below the resolution of `t`.
    #[error("step size underflow at t = {t} s (h = {h:e} s)")]
    StepUnderflow {
        /// Time of the failure (s).
        t: f64,
        /// The rejected step (s).
        h: f64,
    },
    /// The right-hand side returned a non-finite value.
    #[error("non-finite derivative at t = {t} s")]
    NonFinite {
        /// Time of the failure (s).
        t: f64,
    },
}

/// Relative and absolute error tolerances of the step-size control.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Tolerance {
    /// Relative tolerance (dimensionless).
    pub rtol: f64,
    /// Absolute tolerance (units of the state).
    pub atol: f64,
}

impl Default for Tolerance {
    /// `rtol = 3e-11`, `atol = 3e-13`: keeps the global error near 1e-10 relative over tens of
    /// seconds (measured: energy drift of a whirling passive double pendulum over 10 s is
    /// 3e-10 relative at these settings, 1.3e-9 at `rtol = 1e-10`).
    fn default() -> Self {
        Self {
            rtol: 3e-11,
            atol: 3e-13,
        }
    }
}

// Coefficients of DOP853 (Hairer's published values).
const C2: f64 = 0.526_001_519_587_677_3e-1;
const C3: f64 = 0.789_002_279_381_516e-1;
const C4: f64 = 0.118_350_341_907_227_4;
const C5: f64 = 0.281_649_658_092_772_6;
const C6: f64 = 1.0 / 3.0;
const C7: f64 = 0.25;
const C8: f64 = 0.307_692_307_692_307_7;
const C9: f64 = 0.651_282_051_282_051_3;
const C10: f64 = 0.6;
const C11: f64 = 0.857_142_857_142_857_1;
const C14: f64 = 0.1;
const C15: f64 = 0.2;
const C16: f64 = 0.777_777_777_777_777_8;

const B1: f64 = 5.429_373_411_656_876e-2;
const B6: f64 = 4.450_312_892_752_409;
const B7: f64 = 1.891_517_899_314_500_3;
const B8: f64 = -5.801_203_960_010_585;
const B9: f64 = 3.111_643_669_578_199e-1;
const B10: f64 = -1.521_609_496_625_160_8e-1;
const B11: f64 = 2.013_654_008_040_303_4e-1;
const B12: f64 = 4.471_061_572_777_259e-2;

const BHH1: f64 = 0.244_094_488_188_976_38;
const BHH2: f64 = 0.733_846_688_281_611_9;
const BHH3: f64 = 0.220_588_235_294_117_65e-1;

const ER1: f64 = 0.131_200_449_941_948_8e-1;
const ER6: f64 = -0.122_515_644_637_620_44e1;
const ER7: f64 = -0.495_758_949_657_250_2;
const ER8: f64 = 0.166_437_718_245_498_65e1;
const ER9: f64 = -0.350_328_848_749_973_7;
const ER10: f64 = 0.334_179_118_713_017_5;
const ER11: f64 = 0.819_232_064_851_157_1e-1;
const ER12: f64 = -0.223_553_078_638_862_95e-1;

const A21: f64 = 5.260_015_195_876_773e-2;
const A31: f64 = 1.972_505_698_453_79e-2;
const A32: f64 = 5.917_517_095_361_37e-2;
const A41: f64 = 2.958_758_547_680_685e-2;
const A43: f64 = 8.876_275_643_042_055e-2;
const A51: f64 = 2.413_651_341_592_666_8e-1;
const A53: f64 = -8.845_494_793_282_861e-1;
const A54: f64 = 9.248_340_032_617_92e-1;
const A61: f64 = 3.703_703_703_703_703_5e-2;
const A64: f64 = 1.708_286_087_294_738_6e-1;
const A65: f64 = 1.254_676_875_668_224_2e-1;
const A71: f64 = 3.710_937_5e-2;
const A74: f64 = 1.702_522_110_195_440_4e-1;
const A75: f64 = 6.021_653_898_045_596e-2;
const A76: f64 = -1.757_812_5e-2;
const A81: f64 = 3.709_200_011_850_479e-2;
const A84: f64 = 1.703_839_257_122_4e-1;
const A85: f64 = 1.072_620_304_463_732_8e-1;
const A86: f64 = -1.531_943_774_862_440_2e-2;
const A87: f64 = 8.273_789_163_814_023e-3;
const A91: f64 = 6.241_109_587_160_757e-1;
const A94: f64 = -3.360_892_629_446_941;
const A95: f64 = -8.682_193_468_417_26e-1;
const A96: f64 = 2.759_209_969_944_671e1;
const A97: f64 = 2.015_406_755_047_789_4e1;
const A98: f64 = -4.348_988_418_106_996e1;
const A101: f64 = 4.776_625_364_382_643_6e-1;
const A104: f64 = -2.488_114_619_971_667_7;
const A105: f64 = -5.902_908_268_368_43e-1;
const A106: f64 = 2.123_005_144_818_119_3e1;
const A107: f64 = 1.527_923_363_288_242_4e1;
const A108: f64 = -3.328_821_096_898_486e1;
const A109: f64 = -2.033_120_170_850_862_6e-2;
const A111: f64 = -9.371_424_300_859_873e-1;
const A114: f64 = 5.186_372_428_844_064;
const A115: f64 = 1.091_437_348_996_729_6;
const A116: f64 = -8.149_787_010_746_927;
const A117: f64 = -1.852_006_565_999_696e1;
const A118: f64 = 2.273_948_709_935_050_5e1;
const A119: f64 = 2.493_605_552_679_652_3;
const A1110: f64 = -3.046_764_471_898_219_6;
const A121: f64 = 2.273_310_147_516_538;
const A124: f64 = -1.053_449_546_673_725e1;
const A125: f64 = -2.000_872_058_224_862_5;
const A126: f64 = -1.795_893_186_311_88e1;
const A127: f64 = 2.794_888_452_941_996e1;
const A128: f64 = -2.858_998_277_135_023_5;
const A129: f64 = -8.872_856_933_530_63;
const A1210: f64 = 1.236_056_717_579_430_3e1;
const A1211: f64 = 6.433_927_460_157_636e-1;

const A141: f64 = 5.616_750_228_304_795_4e-2;
const A147: f64 = 2.535_002_102_166_248e-1;
const A148: f64 = -2.462_390_374_708_025e-1;
const A149: f64 = -1.241_914_232_638_163_7e-1;
const A1410: f64 = 1.532_917_982_787_657e-1;
const A1411: f64 = 8.201_052_295_634_69e-3;
const A1412: f64 = 7.567_897_660_545_7e-3;
const A1413: f64 = -8.298e-3;
const A151: f64 = 3.183_464_816_350_214e-2;
const A156: f64 = 2.830_090_967_236_677_6e-2;
const A157: f64 = 5.354_198_830_743_856_6e-2;
const A158: f64 = -5.492_374_857_139_099e-2;
const A1511: f64 = -1.083_473_286_972_493_2e-4;
const A1512: f64 = 3.825_710_908_356_584e-4;
const A1513: f64 = -3.404_650_086_874_045_6e-4;
const A1514: f64 = 1.413_124_436_746_325e-1;
const A161: f64 = -4.288_963_015_837_919_4e-1;
const A166: f64 = -4.697_621_415_361_164;
const A167: f64 = 7.683_421_196_062_599;
const A168: f64 = 4.068_989_818_397_11;
const A169: f64 = 3.567_271_874_552_811e-1;
const A1613: f64 = -1.399_024_165_159_014_5e-3;
const A1614: f64 = 2.947_514_789_152_772_4;
const A1615: f64 = -9.150_958_472_179_87;

const D41: f64 = -0.842_893_827_610_901_3e1;
const D46: f64 = 0.566_714_953_519_377_8;
const D47: f64 = -0.306_894_994_594_989_17e1;
const D48: f64 = 0.238_466_765_651_206_98e1;
const D49: f64 = 0.211_703_458_244_502_83e1;
const D410: f64 = -0.871_391_583_777_973;
const D411: f64 = 0.224_043_743_026_078_83e1;
const D412: f64 = 0.631_578_778_769_468_8;
const D413: f64 = -0.889_903_364_513_333_1e-1;
const D414: f64 = 0.181_485_055_208_547_27e2;
const D415: f64 = -0.919_463_239_247_835_5e1;
const D416: f64 = -0.443_603_638_759_489_4e1;
const D51: f64 = 0.104_275_086_425_791_35e2;
const D56: f64 = 0.242_283_491_775_258_2e3;
const D57: f64 = 0.165_200_451_717_270_28e3;
const D58: f64 = -0.374_546_754_722_690_2e3;
const D59: f64 = -0.221_136_668_531_253_06e2;
const D510: f64 = 0.773_343_266_847_226_4e1;
const D511: f64 = -0.306_740_847_310_893_98e2;
const D512: f64 = -0.933_213_052_643_022_8e1;
const D513: f64 = 0.156_972_381_217_708_44e2;
const D514: f64 = -0.311_394_032_195_651_8e2;
const D515: f64 = -0.935_292_435_884_447_8e1;
const D516: f64 = 0.358_168_414_863_940_84e2;
const D61: f64 = 0.199_850_532_420_024_34e2;
const D66: f64 = -0.387_037_308_749_351_8e3;
const D67: f64 = -0.189_178_138_195_167_57e3;
const D68: f64 = 0.527_808_159_205_423_6e3;
const D69: f64 = -0.115_739_025_399_596_3e2;
const D610: f64 = 0.688_123_269_469_63e1;
const D611: f64 = -0.100_060_509_669_108_38e1;
const D612: f64 = 0.777_713_779_805_344_3;
const D613: f64 = -0.277_820_575_235_350_84e1;
const D614: f64 = -0.601_966_952_312_641_2e2;
const D615: f64 = 0.843_204_055_066_771_6e2;
const D616: f64 = 0.119_922_911_361_827_9e2;
const D71: f64 = -0.256_939_334_627_037_5e2;
const D76: f64 = -0.154_189_748_690_236_43e3;
const D77: f64 = -0.231_529_379_176_045_5e3;
const D78: f64 = 0.357_639_117_910_614_1e3;
const D79: f64 = 0.934_053_241_836_243e2;
const D710: f64 = -0.374_583_231_364_516_3e2;
const D711: f64 = 0.104_099_649_508_962_3e3;
const D712: f64 = 0.298_402_934_266_605_03e2;
const D713: f64 = -0.435_334_565_900_111_44e2;
const D714: f64 = 0.963_245_539_591_882_8e2;
const D715: f64 = -0.391_772_616_756_154_4e2;
const D716: f64 = -0.149_726_836_257_985_63e3;

/// An accepted step: enough to continue (FSAL) and to build the dense output on demand.
#[derive(Debug, Clone)]
pub struct Step<const N: usize> {
    /// Start time (s).
    pub t0: f64,
    /// Step size (s); the step ends at `t0 + h` (exactly `t_end` when the step was cut there).
    pub h: f64,
    /// End time (s).
    pub t1: f64,
    /// State at `t0`.
    pub y0: SVector<f64, N>,
    /// State at `t1`.
    pub y1: SVector<f64, N>,
    /// Stages `k1..k13`; `k[12] = f(t1, y1)` starts the next step.
    k: [SVector<f64, N>; 13],
}

impl<const N: usize> Step<N> {
    /// Derivative at the end of the step, `f(t1, y1)`.
    pub fn f1(&self) -> &SVector<f64, N> {
        &self.k[12]
    }
    /// Derivative at the start of the step, `f(t0, y0)`.
    pub fn f0(&self) -> &SVector<f64, N> {
        &self.k[0]
    }
}

/// The 7th-order continuous extension of one step.
#[derive(Debug, Clone)]
pub struct Dense<const N: usize> {
    t0: f64,
    h: f64,
    r: [SVector<f64, N>; 8],
}

impl<const N: usize> Dense<N> {
    /// State at time `t` in `[t0, t0 + h]`.
    #[inline]
    pub fn eval(&self, t: f64) -> SVector<f64, N> {
        let s = (t - self.t0) / self.h;
        let s1 = 1.0 - s;
        let r = &self.r;
        r[0] + (r[1] + (r[2] + (r[3] + (r[4] + (r[5] + (r[6] + r[7] * s) * s1) * s) * s1) * s) * s1)
            * s
    }
}

/// Counters of the work done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OdeStats {
    /// Right-hand-side evaluations.
    pub evals: u64,
    /// Accepted steps.
    pub steps: u64,
    /// Rejected step attempts.
    pub rejected: u64,
    /// Dense outputs built.
    pub dense: u64,
}

/// The step-size controller shared by the embedded Runge–Kutta pairs ([`Dop853`],
/// [`Dopri5`]): tolerances, the step-size memory carried from step to step (plain data, so a
/// plant carries it across zero-order-hold periods), and the work counters. One accepted step
/// ([`StepControl::drive`]):
///
/// - the first step: the pair's own guess ([`Stepper::initial`]), kept as the memory, or the
///   whole span, not kept;
/// - the trial step `h = min(memory, h_max)`, stretched to end exactly on `t_end` when it would
///   end within `1e-12` relative of it (or past it); a step below `16 eps max(|t|, 1)` is an
///   underflow;
/// - a trial whose new state is not finite is retried at a quarter of its size (down to
///   `1e-9 s`, then it fails) and counts as a rejection;
/// - the error norm `err` ([`Stepper::error`]) accepts at `err <= 1`; the next step is
///   `h * clamp(0.9 err^(-1/q), MIN, MAX)` (`MAX` for `err = 0`, no growth right after a
///   rejection), and a rejected one is retried at `h * max(0.9 err^(-1/q), MIN)`
///   ([`Pair`]: `q`, `MIN`, `MAX`);
/// - a step cut short at `t_end` keeps the larger of its suggestion and the memory (a sample
///   instant does not shrink the next period's step); when the memory is already `MAX h` or
///   more the norm's value is not needed, only whether it is at most 1, which a pair may
///   decide more cheaply (`exact = false`).
#[derive(Debug, Clone)]
pub struct StepControl<P> {
    /// Error tolerances.
    pub tol: Tolerance,
    /// Largest step allowed (s); `f64::INFINITY` for none.
    pub h_max: f64,
    /// Suggested size of the next step (s); 0 means none yet.
    pub h_next: f64,
    reject: bool,
    /// Work counters.
    pub stats: OdeStats,
    pair: std::marker::PhantomData<P>,
}

/// The constants of an embedded pair's step-size factor (see [`StepControl`]).
pub trait Pair {
    /// `-1/q`: the exponent of the error norm, `q` the order of the error estimate plus one.
    const EXPONENT: f64;
    /// Smallest factor of one step.
    const MIN_FACTOR: f64;
    /// Largest factor of one step.
    const MAX_FACTOR: f64;
}

/// One step being taken by an embedded pair from a given `(t, y, f(t, y))`: what
/// [`StepControl::drive`] asks of it.
pub trait Stepper<P: Pair> {
    /// A trial step (its stages and new state).
    type Trial;
    /// The accepted step handed to the caller.
    type Accepted;
    /// The first step size when the controller has no memory, to be kept as the memory
    /// (`None`: try the whole span and keep nothing). `span`: `t_end - t` (s).
    fn initial(&mut self, tol: &Tolerance, stats: &mut OdeStats, span: f64) -> Option<f64>;
    /// A trial step of size `h` (s) ending at `t1` (s); `None` if its new state is not finite.
    fn trial(&mut self, h: f64, t1: f64, stats: &mut OdeStats) -> Option<Self::Trial>;
    /// The trial's error norm (accepted at `<= 1`). With `exact` false only whether it is at
    /// most 1 matters: any value at most 1 (0, say) may stand for an acceptable one.
    fn error(&self, trial: &Self::Trial, tol: &Tolerance, exact: bool) -> f64;
    /// The accepted trial as the caller's step (or a failure found at its end).
    fn accept(
        &mut self,
        trial: Self::Trial,
        stats: &mut OdeStats,
    ) -> Result<Self::Accepted, OdeError>;
}

impl<P: Pair> StepControl<P> {
    /// A controller with tolerances `tol` and no step memory.
    pub fn new(tol: Tolerance) -> Self {
        Self {
            tol,
            h_max: f64::INFINITY,
            h_next: 0.0,
            reject: false,
            stats: OdeStats::default(),
            pair: std::marker::PhantomData,
        }
    }

    /// Forgets the step-size memory (after a discontinuity of the right-hand side the last
    /// step size remains a good guess, so this is rarely needed).
    pub fn reset(&mut self) {
        self.h_next = 0.0;
        self.reject = false;
    }

    /// Takes one accepted step of `stepper` from `t` towards `t_end > t` (s), never past it.
    #[inline]
    pub fn drive<S: Stepper<P>>(
        &mut self,
        stepper: &mut S,
        t: f64,
        t_end: f64,
    ) -> Result<S::Accepted, OdeError> {
        let span = t_end - t;
        debug_assert!(span > 0.0);
        if self.h_next <= 0.0 {
            if let Some(h0) = stepper.initial(&self.tol, &mut self.stats, span) {
                self.h_next = h0;
            }
        }
        let mut h = if self.h_next > 0.0 { self.h_next } else { span }.min(self.h_max);
        loop {
            let mut t1 = t + h;
            if h >= span * (1.0 - 1e-12) || t1 >= t_end {
                h = span;
                t1 = t_end;
            }
            if h <= 16.0 * f64::EPSILON * t.abs().max(1.0) {
                return Err(OdeError::StepUnderflow { t, h });
            }
            let Some(trial) = stepper.trial(h, t1, &mut self.stats) else {
                if h > 1e-9 {
                    // A non-finite trial: shrink and retry before giving up.
                    h *= 0.25;
                    self.stats.rejected += 1;
                    self.reject = true;
                    continue;
                }
                return Err(OdeError::NonFinite { t });
            };
            let keep = self.h_next.min(self.h_max);
            let cut = t1 == t_end;
            let exact = !(cut && keep >= P::MAX_FACTOR * h);
            let err = stepper.error(&trial, &self.tol, exact);
            if err <= 1.0 {
                self.h_next = if exact {
                    let scale = if err == 0.0 {
                        P::MAX_FACTOR
                    } else {
                        (0.9 * err.powf(P::EXPONENT)).clamp(P::MIN_FACTOR, P::MAX_FACTOR)
                    };
                    let h_sugg = if self.reject {
                        h * scale.min(1.0)
                    } else {
                        h * scale
                    };
                    if cut {
                        h_sugg.max(keep)
                    } else {
                        h_sugg
                    }
                } else {
                    // The suggestion is at most MAX_FACTOR h <= keep.
                    keep
                };
                self.reject = false;
                self.stats.steps += 1;
                return stepper.accept(trial, &mut self.stats);
            }
            self.stats.rejected += 1;
            self.reject = true;
            h *= (0.9 * err.powf(P::EXPONENT)).max(P::MIN_FACTOR);
        }
    }
}

/// The DOP853 pair: 8th order, error estimate of orders 5 and 3 combined (Hairer's).
#[derive(Debug, Clone, Copy)]
pub struct Dp853;

impl Pair for Dp853 {
    const EXPONENT: f64 = -0.125;
    const MIN_FACTOR: f64 = 0.333;
    const MAX_FACTOR: f64 = 6.0;
}

/// The DOP853 stepper: [`StepControl`] over the 8(5,3) pair, with a lazily built 7th-order
/// dense output ([`Dop853::dense`]).
pub type Dop853 = StepControl<Dp853>;

/// One step in progress from `(t, y)` with `f0` the derivative there, `f` the right-hand
/// side: the [`Stepper`] of either pair (DOP853's `f(t, y)`, DOPRI5's `f(t, y, end)`, whose
/// derivative at `(t, y)` is `f(t, y, true).0`).
struct StepFrom<'a, const N: usize, F> {
    f: &'a mut F,
    t: f64,
    y: &'a SVector<f64, N>,
    f0: &'a SVector<f64, N>,
}

/// A DOP853 trial: `(h, t1, y1, (y1 - y) / h, k1..k12)`.
type Trial853<const N: usize> = (
    f64,
    f64,
    SVector<f64, N>,
    SVector<f64, N>,
    [SVector<f64, N>; 12],
);

impl<const N: usize, F> Stepper<Dp853> for StepFrom<'_, N, F>
where
    F: FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
{
    type Trial = Trial853<N>;
    type Accepted = Step<N>;

    fn initial(&mut self, tol: &Tolerance, stats: &mut OdeStats, span: f64) -> Option<f64> {
        let (t, y, f0) = (self.t, self.y, self.f0);
        let sk = y.map(|v| tol.atol + tol.rtol * v.abs());
        let d0 = y.component_div(&sk).norm() / (N as f64).sqrt();
        let d1 = f0.component_div(&sk).norm() / (N as f64).sqrt();
        let h0 = if d0 < 1e-10 || d1 < 1e-10 {
            1e-6
        } else {
            0.01 * d0 / d1
        }
        .min(span);
        let y1 = y + f0 * h0;
        let f1 = (self.f)(t + h0, &y1);
        stats.evals += 1;
        let d2 = (f1 - f0).component_div(&sk).norm() / (N as f64).sqrt() / h0;
        let h1 = if d1.max(d2) <= 1e-15 {
            (h0 * 1e-3).max(1e-6)
        } else {
            (0.01 / d1.max(d2)).powf(1.0 / 8.0)
        };
        Some((100.0 * h0).min(h1).min(span))
    }

    #[inline]
    fn trial(&mut self, h: f64, t1: f64, stats: &mut OdeStats) -> Option<Trial853<N>> {
        let (t, y) = (self.t, self.y);
        let k1 = *self.f0;
        let f = &mut *self.f;
        let mut ev = |tt: f64, yy: SVector<f64, N>| f(tt, &yy);
        let k2 = ev(t + C2 * h, y + k1 * (h * A21));
        let k3 = ev(t + C3 * h, y + (k1 * A31 + k2 * A32) * h);
        let k4 = ev(t + C4 * h, y + (k1 * A41 + k3 * A43) * h);
        let k5 = ev(t + C5 * h, y + (k1 * A51 + k3 * A53 + k4 * A54) * h);
        let k6 = ev(t + C6 * h, y + (k1 * A61 + k4 * A64 + k5 * A65) * h);
        let k7 = ev(
            t + C7 * h,
            y + (k1 * A71 + k4 * A74 + k5 * A75 + k6 * A76) * h,
        );
        let k8 = ev(
            t + C8 * h,
            y + (k1 * A81 + k4 * A84 + k5 * A85 + k6 * A86 + k7 * A87) * h,
        );
        let k9 = ev(
            t + C9 * h,
            y + (k1 * A91 + k4 * A94 + k5 * A95 + k6 * A96 + k7 * A97 + k8 * A98) * h,
        );
        let k10 = ev(
            t + C10 * h,
            y + (k1 * A101 + k4 * A104 + k5 * A105 + k6 * A106 + k7 * A107 + k8 * A108 + k9 * A109)
                * h,
        );
        let k11 = ev(
            t + C11 * h,
            y + (k1 * A111
                + k4 * A114
                + k5 * A115
                + k6 * A116
                + k7 * A117
                + k8 * A118
                + k9 * A119
                + k10 * A1110)
                * h,
        );
        let k12 = ev(
            t1,
            y + (k1 * A121
                + k4 * A124
                + k5 * A125
                + k6 * A126
                + k7 * A127
                + k8 * A128
                + k9 * A129
                + k10 * A1210
                + k11 * A1211)
                * h,
        );
        stats.evals += 11;
        let inc =
            k1 * B1 + k6 * B6 + k7 * B7 + k8 * B8 + k9 * B9 + k10 * B10 + k11 * B11 + k12 * B12;
        let y1 = y + inc * h;
        if !y1.iter().all(|v| v.is_finite()) {
            return None;
        }
        Some((
            h,
            t1,
            y1,
            inc,
            [k1, k2, k3, k4, k5, k6, k7, k8, k9, k10, k11, k12],
        ))
    }

    #[inline]
    fn error(&self, trial: &Trial853<N>, tol: &Tolerance, _exact: bool) -> f64 {
        let (h, _, y1, inc, k) = trial;
        let y = self.y;
        let [k1, _, _, _, _, k6, k7, k8, k9, k10, k11, k12] = k;
        let e3 = inc - k1 * BHH1 - k9 * BHH2 - k12 * BHH3;
        let e5 = k1 * ER1
            + k6 * ER6
            + k7 * ER7
            + k8 * ER8
            + k9 * ER9
            + k10 * ER10
            + k11 * ER11
            + k12 * ER12;
        let (mut err5, mut err3) = (0.0, 0.0);
        for i in 0..N {
            let sk = tol.atol + tol.rtol * y[i].abs().max(y1[i].abs());
            err3 += (e3[i] / sk).powi(2);
            err5 += (e5[i] / sk).powi(2);
        }
        let mut deno = err5 + 0.01 * err3;
        if deno <= 0.0 {
            deno = 1.0;
        }
        h.abs() * err5 * (1.0 / (N as f64 * deno)).sqrt()
    }

    #[inline]
    fn accept(&mut self, trial: Trial853<N>, stats: &mut OdeStats) -> Result<Step<N>, OdeError> {
        let (h, t1, y1, _, k) = trial;
        let k13 = (self.f)(t1, &y1);
        stats.evals += 1;
        if !k13.iter().all(|v| v.is_finite()) {
            return Err(OdeError::NonFinite { t: t1 });
        }
        let [k1, k2, k3, k4, k5, k6, k7, k8, k9, k10, k11, k12] = k;
        Ok(Step {
            t0: self.t,
            h,
            t1,
            y0: *self.y,
            y1,
            k: [k1, k2, k3, k4, k5, k6, k7, k8, k9, k10, k11, k12, k13],
        })
    }
}

impl Dop853 {
    /// Takes one accepted step from `(t, y)` with `f0 = f(t, y)` towards `t_end > t`, never
    /// past it; a step that would end within a hair of `t_end` ends on it exactly.
    pub fn step<const N: usize, F>(
        &mut self,
        f: &mut F,
        t: f64,
        y: &SVector<f64, N>,
        f0: &SVector<f64, N>,
        t_end: f64,
    ) -> Result<Step<N>, OdeError>
    where
        F: FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    {
        self.drive(&mut StepFrom { f, t, y, f0 }, t, t_end)
    }

    /// Builds the continuous extension of `s` (three more evaluations of `f`).
    // long: the DOP853 dense-output tableau (Hairer's contd8): three stages and four rows of
    // coefficients, one a line.
    pub fn dense<const N: usize, F>(&mut self, f: &mut F, s: &Step<N>) -> Dense<N>
    where
        F: FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    {
        let (t, h, y) = (s.t0, s.h, s.y0);
        let k = &s.k;
        let k14 = f(
            t + C14 * h,
            &(y + (k[0] * A141
                + k[6] * A147
                + k[7] * A148
                + k[8] * A149
                + k[9] * A1410
                + k[10] * A1411
                + k[11] * A1412
                + k[12] * A1413)
                * h),
        );
        let k15 = f(
            t + C15 * h,
            &(y + (k[0] * A151
                + k[5] * A156
                + k[6] * A157
                + k[7] * A158
                + k[10] * A1511
                + k[11] * A1512
                + k[12] * A1513
                + k14 * A1514)
                * h),
        );
        let k16 = f(
            t + C16 * h,
            &(y + (k[0] * A161
                + k[5] * A166
                + k[6] * A167
                + k[7] * A168
                + k[8] * A169
                + k[12] * A1613
                + k14 * A1614
                + k15 * A1615)
                * h),
        );
        self.stats.evals += 3;
        self.stats.dense += 1;
        let ydiff = s.y1 - y;
        let bspl = k[0] * h - ydiff;
        let r4 = (k[0] * D41
            + k[5] * D46
            + k[6] * D47
            + k[7] * D48
            + k[8] * D49
            + k[9] * D410
            + k[10] * D411
            + k[11] * D412
            + k[12] * D413
            + k14 * D414
            + k15 * D415
            + k16 * D416)
            * h;
        let r5 = (k[0] * D51
            + k[5] * D56
            + k[6] * D57
            + k[7] * D58
            + k[8] * D59
            + k[9] * D510
            + k[10] * D511
            + k[11] * D512
            + k[12] * D513
            + k14 * D514
            + k15 * D515
            + k16 * D516)
            * h;
        let r6 = (k[0] * D61
            + k[5] * D66
            + k[6] * D67
            + k[7] * D68
            + k[8] * D69
            + k[9] * D610
            + k[10] * D611
            + k[11] * D612
            + k[12] * D613
            + k14 * D614
            + k15 * D615
            + k16 * D616)
            * h;
        let r7 = (k[0] * D71
            + k[5] * D76
            + k[6] * D77
            + k[7] * D78
            + k[8] * D79
            + k[9] * D710
            + k[10] * D711
            + k[11] * D712
            + k[12] * D713
            + k14 * D714
            + k15 * D715
            + k16 * D716)
            * h;
        Dense {
            t0: t,
            h,
            r: [y, ydiff, bspl, ydiff - k[12] * h - bspl, r4, r5, r6, r7],
        }
    }
}

// Coefficients of the Dormand–Prince 5(4) pair (Hairer, Nørsett & Wanner, Table II.5.2).
const P_C2: f64 = 1.0 / 5.0;
const P_C3: f64 = 3.0 / 10.0;
const P_C4: f64 = 4.0 / 5.0;
const P_C5: f64 = 8.0 / 9.0;
const P_A21: f64 = 1.0 / 5.0;
const P_A31: f64 = 3.0 / 40.0;
const P_A32: f64 = 9.0 / 40.0;
const P_A41: f64 = 44.0 / 45.0;
const P_A42: f64 = -56.0 / 15.0;
const P_A43: f64 = 32.0 / 9.0;
const P_A51: f64 = 19372.0 / 6561.0;
const P_A52: f64 = -25360.0 / 2187.0;
const P_A53: f64 = 64448.0 / 6561.0;
const P_A54: f64 = -212.0 / 729.0;
const P_A61: f64 = 9017.0 / 3168.0;
const P_A62: f64 = -355.0 / 33.0;
const P_A63: f64 = 46732.0 / 5247.0;
const P_A64: f64 = 49.0 / 176.0;
const P_A65: f64 = -5103.0 / 18656.0;
// The 5th-order weights (also the last stage's row: first same as last).
const P_B1: f64 = 35.0 / 384.0;
const P_B3: f64 = 500.0 / 1113.0;
const P_B4: f64 = 125.0 / 192.0;
const P_B5: f64 = -2187.0 / 6784.0;
const P_B6: f64 = 11.0 / 84.0;
// Error weights: 5th-order minus embedded 4th-order weights.
const P_E1: f64 = 71.0 / 57600.0;
const P_E3: f64 = -71.0 / 16695.0;
const P_E4: f64 = 71.0 / 1920.0;
const P_E5: f64 = -17253.0 / 339200.0;
const P_E6: f64 = 22.0 / 525.0;
const P_E7: f64 = -1.0 / 40.0;

/// An accepted step of [`Dopri5`]: the end point, its derivative and what the right-hand side
/// returned beside it there.
#[derive(Debug, Clone, Copy)]
pub struct Step5<const N: usize, A> {
    /// Start time (s).
    pub t0: f64,
    /// Step size (s).
    pub h: f64,
    /// End time (s); exactly `t_end` when the step was cut there.
    pub t1: f64,
    /// State at `t1`.
    pub y1: SVector<f64, N>,
    /// Derivative at the end, `f(t1, y1)` (starts the next step).
    pub f1: SVector<f64, N>,
    /// The auxiliary value the right-hand side returned at `(t1, y1)`.
    pub aux1: A,
}

/// The Dormand–Prince 5(4) pair (`DOPRI5`, 7 stages, first same as last).
#[derive(Debug, Clone, Copy)]
pub struct Dp54;

impl Pair for Dp54 {
    const EXPONENT: f64 = -0.2;
    // Hairer's factors: at most 10x growth, 0.2x shrinkage, safety 0.9.
    const MIN_FACTOR: f64 = 0.2;
    const MAX_FACTOR: f64 = 10.0;
}

/// The Dormand–Prince 5(4) stepper (`DOPRI5`, 7 stages, first same as last: 6 new evaluations
/// per step): [`StepControl`] over the 5(4) pair, with no dense output. Its first step tries
/// the whole span (capped by `h_max`) and the error control shrinks it if needed.
///
/// It costs half of a [`Dop853`] step. The hybrid plant uses it for held-torque intervals that
/// one such step covers within the tolerance (a 1 ms zero-order-hold period), where the
/// 8th-order method is held back to one step per period anyway; any step that contains an event
/// is taken again by [`Dop853`] to locate the event on its 7th-order dense output.
///
/// The right-hand side `f(t, y, end)` returns the derivative and an auxiliary value `A`
/// (anything computed on the way that the caller wants to keep; `()` for nothing): the value at
/// the step's end comes back in [`Step5::aux1`]. `end` is `true` for that evaluation, at
/// `(t1, y1)`, and `false` for the inner stages, so a caller may spend more accuracy on the
/// point the next step starts from (the plant computes the inner stages' sines from the step's
/// start by the angle-sum formulas, and those of the end point directly).
pub type Dopri5 = StepControl<Dp54>;

/// A DOPRI5 trial: the step, its stages `k1..k7` (`k7 = f(t1, y1)`) and the auxiliary value
/// at its end.
struct Trial54<const N: usize, A> {
    step: Step5<N, A>,
    k: [SVector<f64, N>; 6],
}

impl<const N: usize, A, F> Stepper<Dp54> for StepFrom<'_, N, F>
where
    F: FnMut(f64, &SVector<f64, N>, bool) -> (SVector<f64, N>, A),
{
    type Trial = Trial54<N, A>;
    type Accepted = Step5<N, A>;

    #[inline]
    fn initial(&mut self, _tol: &Tolerance, _stats: &mut OdeStats, _span: f64) -> Option<f64> {
        None
    }

    #[inline]
    fn trial(&mut self, h: f64, t1: f64, stats: &mut OdeStats) -> Option<Trial54<N, A>> {
        let (t, y, f) = (self.t, self.y, &mut *self.f);
        let k1 = *self.f0;
        let k2 = f(t + P_C2 * h, &(y + k1 * (h * P_A21)), false).0;
        let k3 = f(t + P_C3 * h, &(y + (k1 * P_A31 + k2 * P_A32) * h), false).0;
        let k4 = f(
            t + P_C4 * h,
            &(y + (k1 * P_A41 + k2 * P_A42 + k3 * P_A43) * h),
            false,
        )
        .0;
        let k5 = f(
            t + P_C5 * h,
            &(y + (k1 * P_A51 + k2 * P_A52 + k3 * P_A53 + k4 * P_A54) * h),
            false,
        )
        .0;
        let k6 = f(
            t1,
            &(y + (k1 * P_A61 + k2 * P_A62 + k3 * P_A63 + k4 * P_A64 + k5 * P_A65) * h),
            false,
        )
        .0;
        let y1 = y + (k1 * P_B1 + k3 * P_B3 + k4 * P_B4 + k5 * P_B5 + k6 * P_B6) * h;
        stats.evals += 5;
        if !y1.iter().all(|v| v.is_finite()) {
            return None;
        }
        let (k7, aux1) = f(t1, &y1, true);
        stats.evals += 1;
        Some(Trial54 {
            step: Step5 {
                t0: t,
                h,
                t1,
                y1,
                f1: k7,
                aux1,
            },
            k: [k1, k2, k3, k4, k5, k6],
        })
    }

    #[inline]
    fn error(&self, trial: &Trial54<N, A>, tol: &Tolerance, exact: bool) -> f64 {
        let [k1, _, k3, k4, k5, k6] = &trial.k;
        let (h, y, y1, k7) = (trial.step.h, self.y, &trial.step.y1, &trial.step.f1);
        let e = (k1 * P_E1 + k3 * P_E3 + k4 * P_E4 + k5 * P_E5 + k6 * P_E6 + k7 * P_E7) * h;
        let scale =
            SVector::<f64, N>::from_fn(|i, _| tol.atol + tol.rtol * y[i].abs().max(y1[i].abs()));
        // When only whether the norm is at most 1 matters (most short steps), every component
        // within its own scale guarantees it: comparisons instead of divisions and a root.
        if !exact && (0..N).all(|i| e[i].abs() <= scale[i]) {
            return 0.0;
        }
        let mut sum = 0.0;
        for i in 0..N {
            sum += (e[i] / scale[i]).powi(2);
        }
        (sum / N as f64).sqrt()
    }

    #[inline]
    fn accept(
        &mut self,
        trial: Trial54<N, A>,
        _stats: &mut OdeStats,
    ) -> Result<Step5<N, A>, OdeError> {
        if !trial.step.f1.iter().all(|v| v.is_finite()) {
            return Err(OdeError::NonFinite { t: trial.step.t1 });
        }
        Ok(trial.step)
    }
}

impl Dopri5 {
    /// Takes one accepted step from `(t, y)` with `f0 = f(t, y, true).0` towards `t_end > t`,
    /// never past it; a step that would end within a hair of `t_end` ends on it exactly.
    #[inline]
    pub fn step<const N: usize, A, F>(
        &mut self,
        f: &mut F,
        t: f64,
        y: &SVector<f64, N>,
        f0: &SVector<f64, N>,
        t_end: f64,
    ) -> Result<Step5<N, A>, OdeError>
    where
        F: FnMut(f64, &SVector<f64, N>, bool) -> (SVector<f64, N>, A),
    {
        self.drive(&mut StepFrom { f, t, y, f0 }, t, t_end)
    }
}

#[cfg(test)]
mod tests;
