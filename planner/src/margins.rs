//! What the stabilised orbit survives: the sampled loop over an emulated network
//! (`tilting_sim::network`) on a grid of constant delay × Bernoulli loss, over a range of
//! control rates, and on a robot that is not the model ([`imperfection_map`]: sensor noise on the
//! angles or on the rates, an arm-mass error).
//!
//! A point **survives** when all of these hold (stated in every report):
//!
//! - `tilts` tilts (default 200) are completed, and they alternate sides;
//! - no fault of the model (fall, contact loss, Zeno, integrator failure) and no stretch of
//!   `watchdog` periods (default 50, the plant's `--watchdog`) without a new torque, which would
//!   put the plant into its safe mode;
//! - the mean |peak| of the last 10 tilts is within `tolerance` (default 25 %) of the nominal
//!   orbit's: the same loop at 1 kHz over a perfect network.
//!
//! [`Survey`] runs all the maps of `tilting plan margins` and reads their boundaries off.
//!
//! Each point is one run of up to `tilts × 0.6 s` of plant time (the orbit tilts every 0.435 s),
//! stopped early at the first fault; points run in parallel (rayon).

mod bands;
mod survey;
mod text;

pub use bands::{band_point, search, BandPoint, Bands, Edge, Knob, Search};
pub use survey::{
    Base, InvalidSurvey, MarginsReport, RobotMargins, Survey, SurveyError, SurveyShard, UnitResult,
    MAX_POINTS,
};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tilting_link::{Impairment, LinkSpec};
use tilting_plant::imperfect::Imperfections;
use tilting_plant::{Mode, Plant, SimConfig, TiltPeak, Transition};
use tilting_sim::{run_sampled_over, LoopOptions, Scenario};

/// Plant time allowed per requested tilt (s): the orbit tilts every 0.435 s.
pub const SECONDS_PER_TILT: f64 = 0.6;
/// Tilts whose peaks are compared with the nominal orbit: the mean |peak| of the last
/// `LAST_PEAKS` tilts.
pub const LAST_PEAKS: usize = 10;

/// The survival criteria.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Criteria {
    /// Tilts to complete.
    pub tilts: u64,
    /// Longest run of periods without a new torque (the plant's watchdog).
    pub watchdog: u64,
    /// Largest relative deviation of the last peaks from the nominal ones.
    pub tolerance: f64,
}

impl Default for Criteria {
    fn default() -> Self {
        Self {
            tilts: 200,
            watchdog: 50,
            tolerance: 0.25,
        }
    }
}

/// One point of a map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// Total constant delay, state and torque together (s).
    pub delay: f64,
    /// Loss probability of each direction.
    pub loss: f64,
    /// Control rate (Hz).
    pub rate: f64,
    /// All criteria hold.
    pub survived: bool,
    /// Tilts completed.
    pub tilts: u64,
    /// Mean |peak| of the last 10 tilts (rad); 0 with fewer tilts.
    pub last_peak: f64,
    /// Why it did not survive (empty if it did).
    pub why: String,
}

#[derive(Default)]
struct Watch {
    tilts: u64,
    last_side: Option<Mode>,
    alternate: bool,
    peaks: Vec<f64>,
}

impl tilting_plant::Observer for Watch {
    fn transition(&mut self, ev: &Transition) {
        if ev.from == Mode::Flat && ev.to != Mode::Flat {
            if self.last_side == Some(ev.to) {
                self.alternate = false;
            }
            self.last_side = Some(ev.to);
            self.tilts += 1;
        }
    }
    fn tilt_peak(&mut self, p: &TiltPeak) {
        if self.peaks.len() == LAST_PEAKS {
            self.peaks.remove(0);
        }
        self.peaks.push(p.alpha.abs());
    }
}

/// Mean |peak| of the last tilts of the loop at `rate` over `imp` on the robot `robot` (a run
/// of `tilts` tilts), or the reason it failed.
fn run(
    sc: &Scenario,
    rate: f64,
    imp: &Impairment,
    opts: &LoopOptions,
    robot: &Imperfections,
    c: &Criteria,
) -> (u64, f64, String) {
    let Ok(law) = sc.controller() else {
        return (0, 0.0, "invalid scenario".into());
    };
    let mut cfg = sc.sim_config();
    cfg.params = robot.plant_params(&cfg.params);
    let Ok(mut plant) = Plant::new(cfg, 0.0, sc.mode, sc.initial_state()) else {
        return (0, 0.0, "invalid initial state".into());
    };
    let mut w = Watch {
        alternate: true,
        ..Watch::default()
    };
    let t_end = c.tilts as f64 * SECONDS_PER_TILT;
    let (r, _, net) = run_sampled_over(
        &mut plant,
        &law,
        1.0 / rate,
        t_end,
        imp,
        &LoopOptions {
            // The controller's model: the scenario's `params`, whatever the plant's.
            model: Some(SimConfig {
                params: sc.params,
                ..sc.sim_config()
            }),
            ..*opts
        },
        &mut robot.hardware(),
        &mut w,
        &mut |_| {},
    );
    let peak = if w.peaks.len() == LAST_PEAKS {
        w.peaks.iter().sum::<f64>() / LAST_PEAKS as f64
    } else {
        0.0
    };
    let why = if let Err(f) = r {
        format!("fault after {} tilts: {f}", w.tilts)
    } else if net.longest_gap >= c.watchdog {
        format!(
            "{} periods without a new torque (watchdog {})",
            net.longest_gap, c.watchdog
        )
    } else if w.tilts < c.tilts {
        format!("{} tilts of {}", w.tilts, c.tilts)
    } else if !w.alternate {
        "tilts do not alternate".into()
    } else {
        String::new()
    };
    (w.tilts, peak, why)
}

/// The peak criterion: `last_peak`, the mean |peak| of the last [`LAST_PEAKS`] tilts (rad), is
/// within `c.tolerance` of `nominal` (rad); otherwise the reason, with both peaks.
pub fn peaks_hold(last_peak: f64, nominal: f64, c: &Criteria) -> Result<(), String> {
    let rel = last_peak / nominal - 1.0;
    if rel.abs() <= c.tolerance {
        Ok(())
    } else {
        Err(format!(
            "last peaks {last_peak:.4} rad, {:+.0} % from the nominal {nominal:.4} rad",
            100.0 * rel
        ))
    }
}

/// The nominal last peak: the loop at 1 kHz over a perfect network (rad).
pub fn nominal_peak(sc: &Scenario, c: &Criteria) -> f64 {
    run(
        sc,
        1000.0,
        &Impairment::default(),
        &LoopOptions::default(),
        &Imperfections::default(),
        c,
    )
    .1
}

#[allow(clippy::too_many_arguments)]
fn point(
    sc: &Scenario,
    rate: f64,
    delay: f64,
    loss: f64,
    seed: u64,
    opts: &LoopOptions,
    c: &Criteria,
    nominal: f64,
) -> Point {
    let imp = Impairment {
        state: LinkSpec {
            loss,
            ..LinkSpec::default()
        },
        torque: LinkSpec {
            delay,
            loss,
            ..LinkSpec::default()
        },
        seed,
        // Any age: the delay is what is measured, not the plant's age rule.
        max_age: u64::MAX,
    };
    let (tilts, last_peak, why) = run(sc, rate, &imp, opts, &Imperfections::default(), c);
    let why = judge_peak(why, last_peak, nominal, c);
    Point {
        delay,
        loss,
        rate,
        survived: why.is_empty(),
        tilts,
        last_peak,
        why,
    }
}

/// `why`, or the peaks' deviation from `nominal` if beyond the tolerance.
fn judge_peak(why: String, last_peak: f64, nominal: f64, c: &Criteria) -> String {
    if why.is_empty() {
        if let Err(e) = peaks_hold(last_peak, nominal, c) {
            return e;
        }
    }
    why
}

/// The delay × loss map at `rate` (Hz) with the loop options `opts` (prediction, sampling on
/// events): every `(delay, loss)` pair, in row order (delays outer); `tick` is called after
/// each point.
#[allow(clippy::too_many_arguments)]
pub fn delay_loss_map(
    sc: &Scenario,
    rate: f64,
    delays: &[f64],
    losses: &[f64],
    seed: u64,
    opts: &LoopOptions,
    c: &Criteria,
    nominal: f64,
    tick: &(dyn Fn() + Sync),
) -> Vec<Point> {
    let pairs: Vec<(f64, f64)> = delays
        .iter()
        .flat_map(|&d| losses.iter().map(move |&l| (d, l)))
        .collect();
    pairs
        .par_iter()
        .map(|&(d, l)| {
            let p = point(sc, rate, d, l, seed, opts, c, nominal);
            tick();
            p
        })
        .collect()
}

/// The control-rate map over a perfect network with the loop options `opts`: one point per
/// rate (Hz).
pub fn rate_map(
    sc: &Scenario,
    rates: &[f64],
    opts: &LoopOptions,
    c: &Criteria,
    nominal: f64,
    tick: &(dyn Fn() + Sync),
) -> Vec<Point> {
    rates
        .par_iter()
        .map(|&r| {
            let p = point(sc, r, 0.0, 0.0, 0, opts, c, nominal);
            tick();
            p
        })
        .collect()
}

/// The largest delay that survives with no loss, the largest loss that survives with no delay
/// (of the grid's values, `None` if none does), and the lowest surviving rate.
pub fn boundaries(map: &[Point], rates: &[Point]) -> (Option<f64>, Option<f64>, Option<f64>) {
    let d = map
        .iter()
        .filter(|p| p.loss == 0.0 && p.survived)
        .map(|p| p.delay)
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
    let l = map
        .iter()
        .filter(|p| p.delay == 0.0 && p.survived)
        .map(|p| p.loss)
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
    let r = rates
        .iter()
        .filter(|p| p.survived)
        .map(|p| p.rate)
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.min(v))));
    (d, l, r)
}

/// An imperfection of the robot mapped by [`imperfection_map`], one at a time, over a perfect
/// network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Imperfection {
    /// Gaussian sensor noise of both angles, `alpha` and `beta`: the value is their standard
    /// deviation (rad).
    AngleNoise,
    /// Gaussian sensor noise of both rates, `alpha_dot` and `beta_dot`: the value is their
    /// standard deviation (rad/s).
    RateNoise,
    /// Model mismatch: the plant's arm mass is `(1 + value)` times the controller's model's.
    MassError,
}

impl Imperfection {
    /// The robot with this imperfection at `value` (noise drawn from `seed`).
    pub fn robot(self, value: f64, seed: u64) -> Imperfections {
        let mut r = Imperfections {
            seed,
            ..Imperfections::default()
        };
        match self {
            Imperfection::AngleNoise => r.noise = [value, value, 0.0, 0.0],
            Imperfection::RateNoise => r.noise = [0.0, 0.0, value, value],
            Imperfection::MassError => r.mass_error = value,
        }
        r
    }

    /// What the value is, with its unit.
    pub fn describe(self) -> &'static str {
        match self {
            Imperfection::AngleNoise => "sensor noise of alpha and beta, standard deviation (rad)",
            Imperfection::RateNoise => {
                "sensor noise of alpha_dot and beta_dot, standard deviation (rad/s)"
            }
            Imperfection::MassError => {
                "arm-mass error of the plant against the controller's model (relative)"
            }
        }
    }
}

/// One point of an imperfection map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImperfectPoint {
    /// The imperfection.
    pub imperfection: Imperfection,
    /// Its level: rad, rad/s or relative ([`Imperfection`]).
    pub value: f64,
    /// All criteria hold.
    pub survived: bool,
    /// Tilts completed.
    pub tilts: u64,
    /// Mean |peak| of the last 10 tilts (rad); 0 with fewer tilts.
    pub last_peak: f64,
    /// Why it did not survive (empty if it did).
    pub why: String,
}

/// Survival on a robot with one imperfection at each of `values`, at `rate` (Hz) over a perfect
/// network, with the same criteria as the network maps; `tick` is called after each point.
#[allow(clippy::too_many_arguments)]
pub fn imperfection_map(
    sc: &Scenario,
    rate: f64,
    which: Imperfection,
    values: &[f64],
    seed: u64,
    c: &Criteria,
    nominal: f64,
    tick: &(dyn Fn() + Sync),
) -> Vec<ImperfectPoint> {
    values
        .par_iter()
        .map(|&v| {
            let p = imperfect_point(sc, rate, which, v, seed, c, nominal);
            tick();
            p
        })
        .collect()
}

/// One point of an imperfection map: the robot with `which` at `value`, at `rate` (Hz) over a
/// perfect network.
fn imperfect_point(
    sc: &Scenario,
    rate: f64,
    which: Imperfection,
    value: f64,
    seed: u64,
    c: &Criteria,
    nominal: f64,
) -> ImperfectPoint {
    let robot = which.robot(value, seed);
    let (tilts, last_peak, why) = if let Err(e) = robot.validate() {
        (0, 0.0, e.to_string())
    } else {
        run(
            sc,
            rate,
            &Impairment::default(),
            &LoopOptions::default(),
            &robot,
            c,
        )
    };
    let why = judge_peak(why, last_peak, nominal, c);
    ImperfectPoint {
        imperfection: which,
        value,
        survived: why.is_empty(),
        tilts,
        last_peak,
        why,
    }
}

/// One point of a Monte-Carlo study: every imperfection at once, at one seed. Its result
/// depends on these values only (the link's random streams and the sensor noise are drawn from
/// `seed`), never on which other points run or in what order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Total constant delay, state and torque together (s), in [0, 60].
    pub delay: f64,
    /// Loss probability of each direction, in [0, 1].
    pub loss: f64,
    /// Sensor noise of both angles: standard deviation (rad), in [0, 10].
    pub angle_noise: f64,
    /// Sensor noise of both rates: standard deviation (rad/s), in [0, 10].
    pub rate_noise: f64,
    /// Arm-mass error of the plant against the controller's model (relative), in (-1, 10].
    pub mass_error: f64,
    /// Control rate (Hz), in [1, 10000].
    pub rate: f64,
    /// The controller predicts over the delay it measures (`--predict auto`).
    pub predict: bool,
    /// Seed of the links' random streams and of the sensor noise.
    pub seed: u64,
}

/// The verdict on one [`Sample`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleResult {
    /// All criteria hold.
    pub survived: bool,
    /// Tilts completed.
    pub tilts: u64,
    /// Mean |peak| of the last 10 tilts (rad); 0 with fewer tilts.
    pub last_peak: f64,
    /// Why it did not survive (empty if it did).
    pub why: String,
}

impl Sample {
    /// Checks every value is finite and in its range; the message names the field.
    pub fn check(&self) -> Result<(), String> {
        for (name, v, lo, hi) in [
            ("delay", self.delay, 0.0, 60.0),
            ("loss", self.loss, 0.0, 1.0),
            ("angle_noise", self.angle_noise, 0.0, 10.0),
            ("rate_noise", self.rate_noise, 0.0, 10.0),
            ("mass_error", self.mass_error, -1.0, 10.0),
            ("rate", self.rate, 1.0, 10_000.0),
        ] {
            if !(v.is_finite() && (lo..=hi).contains(&v)) || (name == "mass_error" && v <= -1.0) {
                return Err(format!("invalid `{name}` = {v}: allowed {lo} to {hi}"));
            }
        }
        Ok(())
    }

    /// Runs the point on the paper's loop against the `nominal` peak (rad, [`nominal_peak`]).
    pub fn run(&self, sc: &Scenario, c: &Criteria, nominal: f64) -> SampleResult {
        let imp = Impairment {
            state: LinkSpec {
                loss: self.loss,
                ..LinkSpec::default()
            },
            torque: LinkSpec {
                delay: self.delay,
                loss: self.loss,
                ..LinkSpec::default()
            },
            seed: self.seed,
            max_age: u64::MAX,
        };
        let robot = Imperfections {
            seed: self.seed,
            noise: [
                self.angle_noise,
                self.angle_noise,
                self.rate_noise,
                self.rate_noise,
            ],
            mass_error: self.mass_error,
            ..Imperfections::default()
        };
        let opts = LoopOptions {
            predict: self.predict.then_some(tilting_sim::Predict::Estimated),
            ..LoopOptions::default()
        };
        let (tilts, last_peak, why) = match (self.check(), robot.validate()) {
            (Err(e), _) => (0, 0.0, e),
            (_, Err(e)) => (0, 0.0, e.to_string()),
            _ => run(sc, self.rate, &imp, &opts, &robot, c),
        };
        let why = judge_peak(why, last_peak, nominal, c);
        SampleResult {
            survived: why.is_empty(),
            tilts,
            last_peak,
            why,
        }
    }
}

/// The surviving range around the perfect robot: the smallest and largest value of the map
/// such that every value of the map between it and 0 survives (`None` if 0 is not in the map
/// or does not survive). For noise the upper end is the largest noise survived.
pub fn imperfection_range(map: &[ImperfectPoint]) -> Option<(f64, f64)> {
    let mut pts: Vec<&ImperfectPoint> = map.iter().collect();
    pts.sort_by(|a, b| a.value.total_cmp(&b.value));
    let zero = pts.iter().position(|p| p.value == 0.0)?;
    if !pts[zero].survived {
        return None;
    }
    let mut hi = zero;
    while hi + 1 < pts.len() && pts[hi + 1].survived {
        hi += 1;
    }
    let mut lo = zero;
    while lo > 0 && pts[lo - 1].survived {
        lo -= 1;
    }
    Some((pts[lo].value, pts[hi].value))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Short runs (20 tilts) bracket what `simulate` shows: no delay survives, a 20 ms delay
    /// (far past the 9 ms at which the orbit falls) does not; a loss of everything leaves no
    /// torque and trips the watchdog.
    #[test]
    fn a_short_map_separates_survival_from_failure() {
        let sc = Scenario::default();
        let c = Criteria {
            tilts: 20,
            ..Criteria::default()
        };
        let nominal = nominal_peak(&sc, &c);
        assert!((0.035..0.05).contains(&nominal), "{nominal}");
        let map = delay_loss_map(
            &sc,
            1000.0,
            &[0.0, 0.02],
            &[0.0, 1.0],
            1,
            &LoopOptions::default(),
            &c,
            nominal,
            &|| {},
        );
        assert_eq!(map.len(), 4);
        assert!(map[0].survived, "{:?}", map[0]);
        assert!(
            !map[1].survived && map[1].why.contains("watchdog"),
            "{:?}",
            map[1]
        );
        assert!(!map[2].survived, "{:?}", map[2]);
        let (d, l, _) = boundaries(&map, &[]);
        assert_eq!((d, l), (Some(0.0), Some(0.0)));
    }

    /// Short runs (20 tilts): the perfect robot survives, and so do tiny imperfections; angle
    /// noise of 0.2 rad (a tenth of the arm's swing) and an arm twice as heavy as modelled do
    /// not. The range is read off around 0.
    #[test]
    fn imperfection_maps_separate_survival_from_failure() {
        let sc = Scenario::default();
        let c = Criteria {
            tilts: 20,
            ..Criteria::default()
        };
        let nominal = nominal_peak(&sc, &c);
        let noise = imperfection_map(
            &sc,
            1000.0,
            Imperfection::AngleNoise,
            &[0.0, 1e-6, 0.2],
            3,
            &c,
            nominal,
            &|| {},
        );
        assert!(noise[0].survived && noise[1].survived, "{noise:?}");
        assert!(!noise[2].survived, "{:?}", noise[2]);
        assert_eq!(imperfection_range(&noise), Some((0.0, 1e-6)));
        let mass = imperfection_map(
            &sc,
            1000.0,
            Imperfection::MassError,
            &[-0.001, 0.0, 0.001, 1.0],
            0,
            &c,
            nominal,
            &|| {},
        );
        assert!(!mass[3].survived, "{:?}", mass[3]);
        assert_eq!(imperfection_range(&mass), Some((-0.001, 0.001)));
        // The perfect robot's point is the nominal run itself.
        assert_eq!(mass[1].last_peak, nominal);
    }
}
