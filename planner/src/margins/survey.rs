//! The whole survey of `tilting plan margins`: the nominal orbit, the delay × loss maps of the
//! plain and the predicting controller, the rate maps with and without samples on events, the
//! robot's imperfection maps, and the boundaries read off them ([`Survey::run`]).

use super::{
    boundaries, delay_loss_map, imperfection_map, imperfection_range, nominal_peak, rate_map,
    Criteria, ImperfectPoint, Imperfection, Point,
};
use serde::{Deserialize, Serialize};
use tilting_sim::{LoopOptions, Predict, Scenario};

/// What a survey maps: the grids, the criteria and the seed. The loop is the paper's
/// stabilised orbit ([`Scenario::default`]).
#[derive(Debug, Clone, PartialEq)]
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
    /// Points of the survey with the nominal run: the number of `tick`s [`Survey::run`] gives.
    pub fn units(&self) -> u64 {
        let network = self.delays.len() * self.losses.len() + self.rates.len();
        let robot = self.angle_noises.len() + self.rate_noises.len() + self.mass_errors.len();
        (2 * network + robot + 1) as u64
    }

    /// Runs the survey on the paper's loop, the points in parallel; `tick` is called after the
    /// nominal run and after each point ([`Survey::units`] in all, from several threads).
    pub fn run(&self, tick: &(dyn Fn() + Sync)) -> Result<MarginsReport, SurveyError> {
        let (sc, c) = (Scenario::default(), self.criteria);
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
        let robot = self.robot(&sc, nominal, tick);
        let (largest_delay, largest_loss, lowest_rate) = boundaries(&delay_loss, &rates);
        let (largest_delay_predict, largest_loss_predict, lowest_rate_events) =
            boundaries(&delay_loss_predict, &rates_events);
        Ok(MarginsReport {
            criteria: c,
            survives_means: survives_means(&c, nominal),
            nominal_peak: nominal,
            rate,
            delay_loss,
            delay_loss_predict,
            rates,
            rates_events,
            largest_delay,
            largest_loss,
            largest_delay_predict,
            largest_loss_predict,
            lowest_rate,
            lowest_rate_events,
            robot,
        })
    }

    /// The imperfection maps, one imperfection at a time at `rate` over a perfect network.
    fn robot(&self, sc: &Scenario, nominal: f64, tick: &(dyn Fn() + Sync)) -> RobotMargins {
        let (rate, seed, c) = (self.rate, self.seed, &self.criteria);
        let map = |which, values: &[f64]| {
            imperfection_map(sc, rate, which, values, seed, c, nominal, tick)
        };
        let angle_noise = map(Imperfection::AngleNoise, &self.angle_noises);
        let rate_noise = map(Imperfection::RateNoise, &self.rate_noises);
        let mass_error = map(Imperfection::MassError, &self.mass_errors);
        RobotMargins {
            rate,
            largest_angle_noise: imperfection_range(&angle_noise).map(|r| r.1),
            largest_rate_noise: imperfection_range(&rate_noise).map(|r| r.1),
            mass_error_range: imperfection_range(&mass_error),
            angle_noise,
            rate_noise,
            mass_error,
        }
    }
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
    }
}
