//! `tilting plan margins`: what the paper's stabilised orbit (`k = 500`) survives, mapped over
//! constant delay × loss, over the control rate, and over the robot's imperfections (sensor
//! noise, arm-mass error; see `tilting_planner::margins` for the criteria).

use super::{bar, emit, usage};
use anyhow::Context as _;
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use tilting_planner::margins::{self, Criteria, ImperfectPoint, Imperfection, Point};
use tilting_planner::CommandError;
use tilting_sim::{LoopOptions, Predict, Scenario};

/// Most points of one map.
const MAX_POINTS: usize = 10_000;

/// Flags of `tilting plan margins`.
#[derive(Debug, Clone, Args)]
pub struct MarginsArgs {
    /// Total constant delays, state and torque together (s), comma-separated, each in [0, 60]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.002,0.004,0.006,0.008,0.010,0.015,0.020",
        allow_negative_numbers = true
    )]
    pub delays: Vec<f64>,
    /// Loss probabilities of each direction, comma-separated, each in [0, 1]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.05,0.1,0.2,0.3,0.5",
        allow_negative_numbers = true
    )]
    pub losses: Vec<f64>,
    /// Control rate of the delay × loss map (Hz), in [1, 10000]
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub rate: f64,
    /// Control rates of the rate map (Hz), comma-separated, each in [1, 10000]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1000,500,250,200,150,100,75,60,50",
        allow_negative_numbers = true
    )]
    pub rates: Vec<f64>,
    /// Tilts a point must complete, in [10, 100000]
    #[arg(long, default_value_t = 200)]
    pub tilts: u64,
    /// Largest relative deviation of the last peaks from the nominal orbit's, in (0, 10]
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub tolerance: f64,
    /// Longest stretch of periods without a new torque (the plant's --watchdog), in [1, 1e6]
    #[arg(long, default_value_t = 50)]
    pub watchdog: u64,
    /// Seed of the links' random streams
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The robot's imperfections to map (at --rate, perfect network).
    #[command(flatten)]
    pub robot: RobotMapArgs,
    /// Draw the maps (heat map with the survival boundary, and the rate map) into this PNG
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object instead of the tables
    #[arg(long)]
    pub json: bool,
}

/// The imperfection maps of `plan margins`: one imperfection at a time, at `--rate` over a
/// perfect network, the noise seeded with `--seed`.
#[derive(Debug, Clone, Args)]
pub struct RobotMapArgs {
    /// Sensor noise of both angles, alpha and beta: standard deviations (rad), comma-separated,
    /// each in [0, 10]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.001,0.003,0.005,0.007,0.01,0.02",
        allow_negative_numbers = true
    )]
    pub angle_noises: Vec<f64>,
    /// Sensor noise of both rates, alpha_dot and beta_dot: standard deviations (rad/s),
    /// comma-separated, each in [0, 10]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.01,0.02,0.03,0.04,0.05,0.1",
        allow_negative_numbers = true
    )]
    pub rate_noises: Vec<f64>,
    /// Arm-mass errors of the plant against the controller's model (relative),
    /// comma-separated, each in (-1, 10]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "-0.1,-0.05,-0.03,-0.02,-0.01,0,0.01,0.02,0.05,0.1",
        allow_negative_numbers = true
    )]
    pub mass_errors: Vec<f64>,
}

/// The imperfection maps in the JSON of `plan margins`.
#[derive(Debug, Serialize)]
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

impl RobotMapArgs {
    fn check(&self) -> Result<usize, CommandError> {
        check_list("--angle-noises", &self.angle_noises, 0.0, 10.0)?;
        check_list("--rate-noises", &self.rate_noises, 0.0, 10.0)?;
        check_list("--mass-errors", &self.mass_errors, -1.0, 10.0)?;
        if let Some(&e) = self.mass_errors.iter().find(|&&e| e <= -1.0) {
            return Err(usage(format!(
                "invalid `--mass-errors` value {e}: allowed (-1, 10]"
            )));
        }
        let n = self.angle_noises.len() + self.rate_noises.len() + self.mass_errors.len();
        if n > MAX_POINTS {
            return Err(usage(format!(
                "too many points: {n} imperfection values, at most {MAX_POINTS}"
            )));
        }
        Ok(n)
    }

    fn run(
        &self,
        sc: &Scenario,
        rate: f64,
        seed: u64,
        c: &Criteria,
        nominal: f64,
        tick: &(dyn Fn() + Sync),
    ) -> RobotMargins {
        let map = |which, values: &[f64]| {
            margins::imperfection_map(sc, rate, which, values, seed, c, nominal, tick)
        };
        let angle_noise = map(Imperfection::AngleNoise, &self.angle_noises);
        let rate_noise = map(Imperfection::RateNoise, &self.rate_noises);
        let mass_error = map(Imperfection::MassError, &self.mass_errors);
        RobotMargins {
            rate,
            largest_angle_noise: margins::imperfection_range(&angle_noise).map(|r| r.1),
            largest_rate_noise: margins::imperfection_range(&rate_noise).map(|r| r.1),
            mass_error_range: margins::imperfection_range(&mass_error),
            angle_noise,
            rate_noise,
            mass_error,
        }
    }
}

impl RobotMargins {
    fn text(&self) -> String {
        let mut s = format!(
            "\nthe robot is not the model, at {} Hz over a perfect network (one imperfection at a \
             time)\n",
            self.rate
        );
        for map in [&self.angle_noise, &self.rate_noise, &self.mass_error] {
            let Some(first) = map.first() else { continue };
            s += &format!("  {}\n", first.imperfection.describe());
            for p in map {
                s += &format!(
                    "  {:>10}: {}{}\n",
                    p.value,
                    if p.survived { "survives" } else { "fails" },
                    if p.why.is_empty() {
                        format!(" (last peaks {:.4} rad)", p.last_peak)
                    } else {
                        format!(" ({})", p.why)
                    }
                );
            }
        }
        let f = |v: Option<f64>, unit: &str| {
            v.map_or("none of the grid".into(), |v| format!("{v} {unit}"))
        };
        s += &format!(
            "largest angle noise survived: {}\nlargest rate noise survived: {}\narm-mass errors \
             survived: {}\n",
            f(self.largest_angle_noise, "rad"),
            f(self.largest_rate_noise, "rad/s"),
            self.mass_error_range
                .map_or("none of the grid".into(), |(a, b)| format!("{a} to {b}")),
        );
        s
    }
}

/// The PNG of the imperfection maps beside `--plot FILE.png`: `FILE-robot.png`.
pub fn robot_plot_path(plot: &std::path::Path) -> PathBuf {
    let stem = plot
        .file_stem()
        .map_or("margins".into(), |s| s.to_string_lossy());
    plot.with_file_name(format!("{stem}-robot.png"))
}

/// The JSON of `plan margins`.
#[derive(Debug, Serialize)]
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

fn check_list(flag: &str, v: &[f64], lo: f64, hi: f64) -> Result<(), CommandError> {
    if v.is_empty() {
        return Err(usage(format!("invalid `{flag}`: give at least one value")));
    }
    for &x in v {
        if !(x.is_finite() && (lo..=hi).contains(&x)) {
            return Err(usage(format!(
                "invalid `{flag}` value {x}: allowed {lo} to {hi}"
            )));
        }
    }
    Ok(())
}

/// `tilting plan margins`.
pub fn margins(args: &MarginsArgs) -> Result<(), CommandError> {
    check_list("--delays", &args.delays, 0.0, 60.0)?;
    check_list("--losses", &args.losses, 0.0, 1.0)?;
    check_list("--rates", &args.rates, 1.0, 10_000.0)?;
    check_list("--rate", &[args.rate], 1.0, 10_000.0)?;
    if !(10..=100_000).contains(&args.tilts) {
        return Err(usage(format!(
            "invalid `--tilts` = {}: allowed 10 to 100000",
            args.tilts
        )));
    }
    if !(args.tolerance.is_finite() && args.tolerance > 0.0 && args.tolerance <= 10.0) {
        return Err(usage(format!(
            "invalid `--tolerance` = {}: allowed (0, 10]",
            args.tolerance
        )));
    }
    if !(1..=1_000_000).contains(&args.watchdog) {
        return Err(usage(format!(
            "invalid `--watchdog` = {}: allowed 1 to 1000000 periods",
            args.watchdog
        )));
    }
    let n_robot = args.robot.check()?;
    let n = args.delays.len() * args.losses.len();
    if n > MAX_POINTS || args.rates.len() > MAX_POINTS {
        return Err(usage(format!(
            "too many points: {n} delay × loss and {} rates, at most {MAX_POINTS} each",
            args.rates.len()
        )));
    }
    if let Some(p) = &args.plot {
        if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            return Err(usage(format!(
                "invalid `--plot` = {}: must be a file name ending in .png",
                p.display()
            )));
        }
    }
    let c = Criteria {
        tilts: args.tilts,
        watchdog: args.watchdog,
        tolerance: args.tolerance,
    };
    let sc = Scenario::default();
    let b = bar(
        (2 * (n + args.rates.len()) + n_robot + 1) as u64,
        "margins",
        args.json,
    );
    let nominal = margins::nominal_peak(&sc, &c);
    b.inc(1);
    if nominal <= 0.0 {
        return Err(CommandError::Failed(anyhow::anyhow!(
            "the nominal loop did not complete {} tilts",
            c.tilts
        )));
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
    let tick = || b.inc(1);
    let map = |opts: &LoopOptions| {
        margins::delay_loss_map(
            &sc,
            args.rate,
            &args.delays,
            &args.losses,
            args.seed,
            opts,
            &c,
            nominal,
            &tick,
        )
    };
    let (delay_loss, delay_loss_predict) = (map(&plain), map(&predict));
    let rates = margins::rate_map(&sc, &args.rates, &plain, &c, nominal, &tick);
    let rates_events = margins::rate_map(&sc, &args.rates, &events, &c, nominal, &tick);
    let robot = args
        .robot
        .run(&sc, args.rate, args.seed, &c, nominal, &tick);
    b.finish_and_clear();
    let (largest_delay, largest_loss, lowest_rate) = margins::boundaries(&delay_loss, &rates);
    let (largest_delay_predict, largest_loss_predict, lowest_rate_events) =
        margins::boundaries(&delay_loss_predict, &rates_events);
    let report = MarginsReport {
        criteria: c,
        survives_means: format!(
            "{} tilts completed, alternating sides; no fault and never {} periods without a new \
             torque (the plant's safe mode); mean |peak| of the last 10 tilts within {:.0} % of \
             the nominal {nominal:.4} rad (1 kHz, perfect network)",
            c.tilts,
            c.watchdog,
            100.0 * c.tolerance
        ),
        nominal_peak: nominal,
        rate: args.rate,
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
    };
    if let Some(p) = &args.plot {
        let maps = tilting_viz::margins::Maps {
            delay_loss: &report.delay_loss,
            delay_loss_predict: &report.delay_loss_predict,
            rates: &report.rates,
            rates_events: &report.rates_events,
        };
        tilting_viz::margins::plot(p, &maps, nominal, &c)
            .with_context(|| format!("cannot draw {}", p.display()))
            .map_err(CommandError::Failed)?;
        let rp = robot_plot_path(p);
        let r = &report.robot;
        tilting_viz::margins::plot_imperfections(
            &rp,
            &[&r.angle_noise, &r.rate_noise, &r.mass_error],
            nominal,
            &c,
        )
        .with_context(|| format!("cannot draw {}", rp.display()))
        .map_err(CommandError::Failed)?;
    }
    emit(args.json, &report, || {
        let mut s = format!("survives = {}\n", report.survives_means);
        for (name, map) in [
            ("plain controller", &report.delay_loss),
            ("--predict auto", &report.delay_loss_predict),
        ] {
            s += &format!(
                "\ndelay × loss at {} Hz, {name} (rows: total delay, columns: loss of each direction)\n{:>12}",
                report.rate, "delay \\ loss"
            );
            for l in &args.losses {
                s += &format!("{l:>8}");
            }
            s += "\n";
            for d in &args.delays {
                s += &format!("{:>10.4} s ", d);
                for l in &args.losses {
                    let p = map.iter().find(|p| p.delay == *d && p.loss == *l);
                    s += &format!(
                        "{:>8}",
                        p.map_or("?", |p| if p.survived { "yes" } else { "no" })
                    );
                }
                s += "\n";
            }
        }
        for (name, rates) in [
            ("periodic samples", &report.rates),
            ("--sample-on-event", &report.rates_events),
        ] {
            s += &format!("\ncontrol rate (perfect network), {name}\n");
            for p in rates.iter() {
                s += &format!(
                    "  {:>7.1} Hz: {}{}\n",
                    p.rate,
                    if p.survived { "survives" } else { "fails" },
                    if p.why.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", p.why)
                    }
                );
            }
        }
        let f = |v: Option<f64>, unit: &str| {
            v.map_or("none of the grid".into(), |v| format!("{v} {unit}"))
        };
        s += &format!(
            "\n{:<38}{:>18}{:>22}\n{:<38}{:>18}{:>22}\n{:<38}{:>18}{:>22}\n",
            "",
            "plain",
            "--predict auto",
            "largest delay survived (no loss)",
            f(report.largest_delay, "s"),
            f(report.largest_delay_predict, "s"),
            "largest loss survived (no delay)",
            f(report.largest_loss, ""),
            f(report.largest_loss_predict, ""),
        );
        s += &format!(
            "{:<38}{:>18}{:>22}\n{:<38}{:>18}{:>22}\n",
            "",
            "periodic",
            "--sample-on-event",
            "lowest rate survived",
            f(report.lowest_rate, "Hz"),
            f(report.lowest_rate_events, "Hz"),
        );
        s += &report.robot.text();
        if let Some(p) = &args.plot {
            s += &format!(
                "plot: {} and {}\n",
                p.display(),
                robot_plot_path(p).display()
            );
        }
        s
    })
}
