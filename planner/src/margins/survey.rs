//! The whole survey of `tilting plan margins`: the nominal orbit, the delay × loss maps of the
//! plain and the predicting controller, the rate maps with and without samples on events, the
//! robot's imperfection maps, and the boundaries read off them ([`Survey::run`]).

use super::bands::{self, Bands, Edge};
use super::{
    boundaries, delay_loss_map, imperfect_point, imperfection_map, imperfection_range,
    nominal_peak, point, rate_map, Criteria, ImperfectPoint, Imperfection, Point,
};
use crate::shard::{self, Shard, ShardError};
use serde::{Deserialize, Serialize};
use tilting_sim::{LoopOptions, Predict, Scenario};

/// What a survey maps: the grids, the criteria, the seed and the loop ([`Survey::base`]; the
/// paper's stabilised orbit, [`Scenario::default`], unless given). Its JSON identifies the
/// grid of a shard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Survey {
    /// Total constant delays, state and torque together (s).
    pub delays: Vec<f64>,
    /// Loss probabilities of each direction.
    pub losses: Vec<f64>,
    /// Control rate of the delay × loss maps and of the imperfection maps (Hz).
    pub rate: f64,
    /// Control rates of the rate maps (Hz).
    pub rates: Vec<f64>,
    /// Sensor noise of both angles: standard deviations (rad).
    pub angle_noises: Vec<f64>,
    /// Sensor noise of both rates: standard deviations (rad/s).
    pub rate_noises: Vec<f64>,
    /// Arm-mass errors of the plant against the controller's model (relative).
    pub mass_errors: Vec<f64>,
    /// Seed of the links' random streams and of the sensor noise.
    pub seed: u64,
    /// What a point must meet.
    pub criteria: Criteria,
    /// The robot rows searched by bisection (parameter bands, friction, estimators); absent
    /// from the grid of a survey written before they existed, which then has none.
    #[serde(default, skip_serializing_if = "Bands::is_none")]
    pub bands: Bands,
    /// The loop surveyed, when not the paper's stabilised orbit: the robot's model (its
    /// `impact` is the landing law) and the law, such as a planned orbit of the physical law
    /// (`tilting plan margins --params robot.toml --plan plan.json`); left out of the JSON
    /// for the paper's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<Base>,
}

/// A loop to survey other than the paper's: the model and the law (the plant is the model;
/// the points perturb it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Base {
    /// The robot's parameters; `impact` is its landing law.
    pub params: tilting_plant::Params,
    /// The law; with an `orbit_start` the runs start at that lift-off (as `simulate`).
    pub law: tilting_controller::LawSpec,
}

impl Base {
    /// The scenario of this loop: the paper's settings otherwise ([`Scenario::default`]).
    pub fn scenario(&self) -> Scenario {
        let mut sc = Scenario {
            params: self.params,
            impact: self.params.impact,
            law: self.law,
            ..Scenario::default()
        };
        if let (Some([beta, beta_dot]), true) = (self.law.orbit_start, self.law.reference.adapts())
        {
            sc.x0 = [0.0, beta, 0.0, beta_dot];
            sc.mode = tilting_plant::Mode::Left;
        }
        sc
    }
}

/// Most points of one map.
pub const MAX_POINTS: usize = 10_000;

/// An invalid survey: the message names the flag of `tilting plan margins` (the keyword of
/// the Python package's `margins` without the dashes) and the allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidSurvey(pub String);

fn check_list(flag: &str, v: &[f64], lo: f64, hi: f64) -> Result<(), InvalidSurvey> {
    if v.is_empty() {
        return Err(InvalidSurvey(format!(
            "invalid `{flag}`: give at least one value"
        )));
    }
    for &x in v {
        if !(x.is_finite() && (lo..=hi).contains(&x)) {
            return Err(InvalidSurvey(format!(
                "invalid `{flag}` value {x}: allowed {lo} to {hi}"
            )));
        }
    }
    Ok(())
}

/// Why a survey could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurveyError {
    /// The nominal loop (1 kHz, perfect network) did not complete the criteria's tilts: there
    /// is no orbit to compare with.
    #[error("the nominal loop did not complete {0} tilts")]
    NoNominalOrbit(u64),
}

/// The imperfection maps of a survey.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotMargins {
    /// Control rate (Hz); the network is perfect.
    pub rate: f64,
    /// Survival against the sensor noise of the angles.
    pub angle_noise: Vec<ImperfectPoint>,
    /// Survival against the sensor noise of the rates.
    pub rate_noise: Vec<ImperfectPoint>,
    /// Survival against the arm-mass error.
    pub mass_error: Vec<ImperfectPoint>,
    /// Largest angle noise (rad) survived, with every smaller one of the grid.
    pub largest_angle_noise: Option<f64>,
    /// Largest rate noise (rad/s) survived, with every smaller one of the grid.
    pub largest_rate_noise: Option<f64>,
    /// The range of mass errors around 0 survived, every grid value inside it too.
    pub mass_error_range: Option<(f64, f64)>,
    /// The robot rows searched by bisection (`tilting_planner::margins::Bands`), in the order
    /// of [`Bands::searches`]: parameter bands, friction, estimators.
    #[serde(default)]
    pub edges: Vec<Edge>,
}

/// The result of a survey (the JSON of `plan margins`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarginsReport {
    /// The criteria a point must meet.
    pub criteria: Criteria,
    /// The survival criteria in words.
    pub survives_means: String,
    /// Nominal mean |peak| of the last 10 tilts, 1 kHz, perfect network (rad).
    pub nominal_peak: f64,
    /// Control rate of the delay × loss maps (Hz).
    pub rate: f64,
    /// The delay × loss map of the plain controller (delays outer).
    pub delay_loss: Vec<Point>,
    /// The delay × loss map of the predicting controller, delay estimated online from the
    /// ages of the applied torques (`--predict auto`).
    pub delay_loss_predict: Vec<Point>,
    /// The rate map (perfect network), periodic samples only.
    pub rates: Vec<Point>,
    /// The rate map (perfect network) with an extra sample at each mode transition
    /// (`--sample-on-event`).
    pub rates_events: Vec<Point>,
    /// Largest surviving delay with no loss (s), plain controller.
    pub largest_delay: Option<f64>,
    /// Largest surviving loss with no delay, plain controller.
    pub largest_loss: Option<f64>,
    /// Largest surviving delay with no loss (s), predicting controller.
    pub largest_delay_predict: Option<f64>,
    /// Largest surviving loss with no delay, predicting controller.
    pub largest_loss_predict: Option<f64>,
    /// Lowest surviving control rate (Hz), periodic samples.
    pub lowest_rate: Option<f64>,
    /// Lowest surviving control rate (Hz), with samples on events.
    pub lowest_rate_events: Option<f64>,
    /// The robot's imperfections (sensor noise, arm-mass error).
    pub robot: RobotMargins,
}

impl Survey {
    /// Checks the survey: every grid value in range, not too many points.
    pub fn check(&self) -> Result<(), InvalidSurvey> {
        let bad = |m: String| Err(InvalidSurvey(m));
        check_list("--delays", &self.delays, 0.0, 60.0)?;
        check_list("--losses", &self.losses, 0.0, 1.0)?;
        check_list("--rates", &self.rates, 1.0, 10_000.0)?;
        check_list("--rate", &[self.rate], 1.0, 10_000.0)?;
        let c = &self.criteria;
        if !(10..=100_000).contains(&c.tilts) {
            return bad(format!(
                "invalid `--tilts` = {}: allowed 10 to 100000",
                c.tilts
            ));
        }
        if !(c.tolerance.is_finite() && c.tolerance > 0.0 && c.tolerance <= 10.0) {
            return bad(format!(
                "invalid `--tolerance` = {}: allowed (0, 10]",
                c.tolerance
            ));
        }
        if !(1..=1_000_000).contains(&c.watchdog) {
            return bad(format!(
                "invalid `--watchdog` = {}: allowed 1 to 1000000 periods",
                c.watchdog
            ));
        }
        check_list("--angle-noises", &self.angle_noises, 0.0, 10.0)?;
        check_list("--rate-noises", &self.rate_noises, 0.0, 10.0)?;
        check_list("--mass-errors", &self.mass_errors, -1.0, 10.0)?;
        if let Some(&e) = self.mass_errors.iter().find(|&&e| e <= -1.0) {
            return bad(format!(
                "invalid `--mass-errors` value {e}: allowed (-1, 10]"
            ));
        }
        let n = self.angle_noises.len() + self.rate_noises.len() + self.mass_errors.len();
        if n > MAX_POINTS {
            return bad(format!(
                "too many points: {n} imperfection values, at most {MAX_POINTS}"
            ));
        }
        self.bands.check().map_err(InvalidSurvey)?;
        let n = self.delays.len() * self.losses.len();
        if n > MAX_POINTS || self.rates.len() > MAX_POINTS {
            return bad(format!(
                "too many points: {n} delay × loss and {} rates, at most {MAX_POINTS} each",
                self.rates.len()
            ));
        }
        Ok(())
    }

    /// Points of the survey with the nominal run: the number of `tick`s [`Survey::run`] gives.
    pub fn units(&self) -> u64 {
        let network = self.delays.len() * self.losses.len() + self.rates.len();
        let robot = self.angle_noises.len() + self.rate_noises.len() + self.mass_errors.len();
        let searches = self.bands.searches(&self.scenario().params).len();
        (2 * network + robot + searches + 1) as u64
    }

    /// The loop surveyed: [`Survey::base`]'s, or the paper's stabilised orbit.
    pub fn scenario(&self) -> Scenario {
        self.base.map_or_else(Scenario::default, |b| b.scenario())
    }

    /// Runs the survey on its loop ([`Survey::scenario`]), the points in parallel; `tick` is called after the
    /// nominal run and after each point ([`Survey::units`] in all, from several threads).
    pub fn run(&self, tick: &(dyn Fn() + Sync)) -> Result<MarginsReport, SurveyError> {
        let (sc, c) = (self.scenario(), self.criteria);
        let nominal = nominal_peak(&sc, &c);
        tick();
        if nominal <= 0.0 {
            return Err(SurveyError::NoNominalOrbit(c.tilts));
        }
        let plain = LoopOptions::default();
        let predict = LoopOptions {
            predict: Some(Predict::Estimated),
            ..plain
        };
        let events = LoopOptions {
            sample_on_event: true,
            ..plain
        };
        let (rate, seed) = (self.rate, self.seed);
        let map = |opts: &LoopOptions| {
            let (d, l) = (&self.delays, &self.losses);
            delay_loss_map(&sc, rate, d, l, seed, opts, &c, nominal, tick)
        };
        let (delay_loss, delay_loss_predict) = (map(&plain), map(&predict));
        let rates = rate_map(&sc, &self.rates, &plain, &c, nominal, tick);
        let rates_events = rate_map(&sc, &self.rates, &events, &c, nominal, tick);
        let (rate, seed, c) = (self.rate, self.seed, &self.criteria);
        let robot = |which, values: &[f64]| {
            imperfection_map(&sc, rate, which, values, seed, c, nominal, tick)
        };
        let searches = self.bands.searches(&self.scenario().params);
        let b = self.bands.bisections;
        let maps = Maps {
            angle_noise: robot(Imperfection::AngleNoise, &self.angle_noises),
            rate_noise: robot(Imperfection::RateNoise, &self.rate_noises),
            mass_error: robot(Imperfection::MassError, &self.mass_errors),
            edges: bands::edges(&sc, &searches, b, rate, seed, c, nominal, tick),
            delay_loss,
            delay_loss_predict,
            rates,
            rates_events,
        };
        Ok(self.assemble(nominal, maps))
    }

    /// The report of the maps: the boundaries read off them.
    fn assemble(&self, nominal: f64, m: Maps) -> MarginsReport {
        let (c, rate) = (self.criteria, self.rate);
        let (largest_delay, largest_loss, lowest_rate) = boundaries(&m.delay_loss, &m.rates);
        let (largest_delay_predict, largest_loss_predict, lowest_rate_events) =
            boundaries(&m.delay_loss_predict, &m.rates_events);
        MarginsReport {
            criteria: c,
            survives_means: survives_means(&c, nominal),
            nominal_peak: nominal,
            rate,
            delay_loss: m.delay_loss,
            delay_loss_predict: m.delay_loss_predict,
            rates: m.rates,
            rates_events: m.rates_events,
            largest_delay,
            largest_loss,
            largest_delay_predict,
            largest_loss_predict,
            lowest_rate,
            lowest_rate_events,
            robot: RobotMargins {
                rate,
                largest_angle_noise: imperfection_range(&m.angle_noise).map(|r| r.1),
                largest_rate_noise: imperfection_range(&m.rate_noise).map(|r| r.1),
                mass_error_range: imperfection_range(&m.mass_error),
                angle_noise: m.angle_noise,
                rate_noise: m.rate_noise,
                mass_error: m.mass_error,
                edges: m.edges,
            },
        }
    }

    /// The survey's points in the report's order (the units of [`Survey::run_shard`]): the
    /// delay × loss map of the plain controller, of the predicting one, the rate maps without
    /// and with samples on events, the angle-noise, rate-noise and mass-error maps, and the
    /// searches of the robot rows (one unit each).
    fn unit_list(&self) -> Vec<Unit> {
        let pairs = || {
            self.delays
                .iter()
                .flat_map(|&d| self.losses.iter().map(move |&l| (d, l)))
        };
        let mut u: Vec<Unit> = pairs().map(|(d, l)| Unit::DelayLoss(d, l, false)).collect();
        u.extend(pairs().map(|(d, l)| Unit::DelayLoss(d, l, true)));
        u.extend(self.rates.iter().map(|&r| Unit::Rate(r, false)));
        u.extend(self.rates.iter().map(|&r| Unit::Rate(r, true)));
        for (which, values) in [
            (Imperfection::AngleNoise, &self.angle_noises),
            (Imperfection::RateNoise, &self.rate_noises),
            (Imperfection::MassError, &self.mass_errors),
        ] {
            u.extend(values.iter().map(|&v| Unit::Robot(which, v)));
        }
        u.extend(
            self.bands
                .searches(&self.scenario().params)
                .into_iter()
                .map(Unit::Band),
        );
        u
    }

    /// How many points the survey has (the units a shard takes its share of).
    pub fn points(&self) -> usize {
        self.unit_list().len()
    }

    /// Runs the points of one shard of the survey (all cores), after the nominal run; `tick` is
    /// called after each point. Each point is computed exactly as [`Survey::run`] computes it,
    /// so [`Survey::merge`] of all shards equals `run` bit for bit.
    pub fn run_shard(
        &self,
        shard: Shard,
        tick: &(dyn Fn() + Sync),
    ) -> Result<SurveyShard, SurveyError> {
        let (sc, c) = (self.scenario(), self.criteria);
        let nominal = nominal_peak(&sc, &c);
        if nominal <= 0.0 {
            return Err(SurveyError::NoNominalOrbit(c.tilts));
        }
        let units = self.unit_list();
        let (rate, seed) = (self.rate, self.seed);
        let points = shard::run(shard, units.len(), |j| {
            let r = match units[j] {
                Unit::DelayLoss(d, l, predict) => {
                    let opts = LoopOptions {
                        predict: predict.then_some(Predict::Estimated),
                        ..LoopOptions::default()
                    };
                    UnitResult::Network(point(&sc, rate, d, l, seed, &opts, &c, nominal))
                }
                Unit::Rate(r, events) => {
                    let opts = LoopOptions {
                        sample_on_event: events,
                        ..LoopOptions::default()
                    };
                    UnitResult::Network(point(&sc, r, 0.0, 0.0, 0, &opts, &c, nominal))
                }
                Unit::Robot(which, v) => {
                    UnitResult::Robot(imperfect_point(&sc, rate, which, v, seed, &c, nominal))
                }
                Unit::Band(s) => {
                    let b = self.bands.bisections;
                    UnitResult::Band(bands::search(&sc, &s, b, rate, seed, &c, nominal))
                }
            };
            tick();
            r
        });
        Ok(SurveyShard {
            shard,
            nominal_peak: nominal,
            points,
        })
    }

    /// The report of the whole survey from all its shards (in any order). Refused unless every
    /// shard of one split is there once, each with its own points of this survey, all with the
    /// same nominal peak.
    pub fn merge(&self, shards: Vec<SurveyShard>) -> Result<MarginsReport, ShardError> {
        let nominal = shards.first().map_or(0.0, |s| s.nominal_peak);
        if let Some(s) = shards
            .iter()
            .find(|s| s.nominal_peak.to_bits() != nominal.to_bits())
        {
            return Err(ShardError::Corrupt {
                shard: s.shard,
                why: format!(
                    "its nominal peak {} rad is not the other shards' {nominal} rad (another                      build of the simulator?)",
                    s.nominal_peak
                ),
            });
        }
        let units = self.unit_list();
        let count = shards.first().map_or(1, |s| s.shard.count);
        let parts = shards.into_iter().map(|s| (s.shard, s.points)).collect();
        let all = shard::gather(units.len(), parts)?;
        let mut maps = Maps::default();
        for (j, (&u, r)) in units.iter().zip(all).enumerate() {
            let bad = |why: &str| ShardError::Corrupt {
                shard: Shard {
                    index: j % count,
                    count,
                },
                why: format!("point {j}: {why}"),
            };
            match (u, r) {
                (Unit::DelayLoss(_, _, false), UnitResult::Network(p)) => maps.delay_loss.push(p),
                (Unit::DelayLoss(_, _, true), UnitResult::Network(p)) => {
                    maps.delay_loss_predict.push(p)
                }
                (Unit::Rate(_, false), UnitResult::Network(p)) => maps.rates.push(p),
                (Unit::Rate(_, true), UnitResult::Network(p)) => maps.rates_events.push(p),
                (Unit::Robot(which, _), UnitResult::Robot(p)) if p.imperfection == which => {
                    match which {
                        Imperfection::AngleNoise => maps.angle_noise.push(p),
                        Imperfection::RateNoise => maps.rate_noise.push(p),
                        Imperfection::MassError => maps.mass_error.push(p),
                    }
                }
                (Unit::Band(s), UnitResult::Band(e))
                    if e.knob == s.knob && e.robust == s.robust && e.end == s.end =>
                {
                    maps.edges.push(e)
                }
                _ => return Err(bad("not a point of this map")),
            }
        }
        Ok(self.assemble(nominal, maps))
    }
}

/// One point of a survey: which map, and where on it.
#[derive(Debug, Clone, Copy)]
enum Unit {
    /// Delay (s), loss, predicting controller.
    DelayLoss(f64, f64, bool),
    /// Rate (Hz), samples on events.
    Rate(f64, bool),
    /// The robot with one imperfection at a value.
    Robot(Imperfection, f64),
    /// One search of the robot rows.
    Band(bands::Search),
}

/// The maps of a survey, each in grid order.
#[derive(Default)]
struct Maps {
    delay_loss: Vec<Point>,
    delay_loss_predict: Vec<Point>,
    rates: Vec<Point>,
    rates_events: Vec<Point>,
    angle_noise: Vec<ImperfectPoint>,
    rate_noise: Vec<ImperfectPoint>,
    mass_error: Vec<ImperfectPoint>,
    edges: Vec<Edge>,
}

/// The result of one point of a survey.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum UnitResult {
    /// A point of a network map (delay × loss or rate).
    Network(Point),
    /// A point of an imperfection map.
    Robot(ImperfectPoint),
    /// A search of the robot rows.
    Band(Edge),
}

/// One shard of a survey ([`Survey::run_shard`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurveyShard {
    /// Which shard.
    pub shard: Shard,
    /// The nominal mean |peak| of the last 10 tilts (rad), which every shard computes.
    pub nominal_peak: f64,
    /// Its points: the number of the point in the survey, and its result.
    pub points: Vec<(usize, UnitResult)>,
}

/// The survival criteria in words, with the nominal peak (rad).
fn survives_means(c: &Criteria, nominal: f64) -> String {
    format!(
        "{} tilts completed, alternating sides; no fault and never {} periods without a new \
         torque (the plant's safe mode); mean |peak| of the last 10 tilts within {:.0} % of the \
         nominal {nominal:.4} rad (1 kHz, perfect network)",
        c.tilts,
        c.watchdog,
        100.0 * c.tolerance
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small survey: one tick per point and the nominal run, the maps in grid order, and
    /// the boundaries of its maps.
    #[test]
    fn a_small_survey_ticks_once_per_point() {
        let s = Survey {
            delays: vec![0.0, 0.02],
            losses: vec![0.0],
            rate: 1000.0,
            rates: vec![1000.0],
            angle_noises: vec![0.0],
            rate_noises: vec![],
            mass_errors: vec![0.0, 1.0],
            seed: 1,
            criteria: Criteria {
                tilts: 20,
                ..Criteria::default()
            },
            bands: Bands::default(),
            base: None,
        };
        let ticks = std::sync::atomic::AtomicU64::new(0);
        let r = s
            .run(&|| {
                ticks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            })
            .unwrap();
        assert_eq!(ticks.into_inner(), s.units());
        assert_eq!(s.units(), 2 * (2 + 1) + 3 + 1);
        let delays: Vec<f64> = r.delay_loss.iter().map(|p| p.delay).collect();
        assert_eq!(delays, [0.0, 0.02]);
        assert!(r.delay_loss[0].survived && !r.delay_loss[1].survived);
        assert_eq!(r.largest_delay, Some(0.0));
        assert_eq!(r.lowest_rate, Some(1000.0));
        assert_eq!(r.robot.mass_error_range, Some((0.0, 0.0)));
        assert!(
            r.survives_means.contains("20 tilts"),
            "{}",
            r.survives_means
        );
        assert!(r.robot.edges.is_empty());
    }

    /// The grid of a shard file written before the robot rows existed (no `bands` key) still
    /// parses, as a survey with no rows and the same units; a survey with no rows writes no
    /// `bands` key, so its grid is the old one, byte for byte; one with rows writes them and
    /// reads them back.
    #[test]
    fn a_survey_without_robot_rows_keeps_the_old_grid() {
        let old = r#"{"delays":[0.0],"losses":[0.0],"rate":1000.0,"rates":[1000.0],
            "angle_noises":[0.0],"rate_noises":[],"mass_errors":[0.0,0.01],"seed":3,
            "criteria":{"tilts":20,"watchdog":50,"tolerance":0.25}}"#;
        let s: Survey = serde_json::from_str(old).unwrap();
        assert_eq!(s.bands, Bands::default());
        assert_eq!(s.points(), 2 + 2 + 1 + 2);
        let text = serde_json::to_string(&s).unwrap();
        assert!(!text.contains("bands"), "{text}");
        let with = Survey {
            bands: Bands {
                parameters: vec![tilting_sim::robustness::Parameter::F],
                param_span: 0.2,
                coulomb_span: 1.0,
                bisections: 3,
                ..Bands::default()
            },
            ..s.clone()
        };
        assert_eq!(with.points(), s.points() + 4 + 2);
        let back: Survey = serde_json::from_str(&serde_json::to_string(&with).unwrap()).unwrap();
        assert_eq!(back, with);
    }
}
