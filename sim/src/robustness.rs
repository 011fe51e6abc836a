//! Robustness to a robot that is not the model: one physical parameter of the plant off by a
//! relative error ([`Parameter::perturbed`]), and the goal of issue 17 §5 judged on a run
//! ([`Goal::of`]): `tilts` tilts, alternating sides, the mean |peak| of the last 10 within a
//! tolerance of the nominal orbit's. `cargo run --release -p tilting-sim --example
//! robust_table` prints the table of every parameter at -10/-5/+5/+10 %, plain law against
//! the robust option (`--orbit-peak`).

use crate::closed_loop::SimulationReport;
use serde::{Deserialize, Serialize};
use tilting_plant::{Mode, Params};

/// Peaks compared with the nominal orbit: the mean |peak| of the last `LAST_PEAKS` tilts (as
/// `plan margins`).
pub const LAST_PEAKS: usize = 10;

/// A physical parameter of the plant ([`Params`]) that may be off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Parameter {
    /// Plate mass `m_f` (kg).
    MF,
    /// Arm mass `m_l` (kg).
    ML,
    /// Arm length `l` (m); the centre of mass stays at the tip.
    L,
    /// Half the plate's length `f` (m).
    F,
    /// Gravity `g` (m/s^2).
    G,
    /// Distance `l_c` (m) from the joint to the arm's centre of mass (at most `l`).
    LC,
}

impl Parameter {
    /// Every parameter, in the table's order.
    pub const ALL: [Parameter; 6] = [
        Parameter::MF,
        Parameter::ML,
        Parameter::L,
        Parameter::F,
        Parameter::G,
        Parameter::LC,
    ];

    /// The key of the parameter files (`m_l`, ...).
    pub fn key(self) -> &'static str {
        match self {
            Parameter::MF => "m_f",
            Parameter::ML => "m_l",
            Parameter::L => "l",
            Parameter::F => "f",
            Parameter::G => "g",
            Parameter::LC => "l_c",
        }
    }

    /// `p` with this parameter times `1 + rel`, or `None` if that is not a valid robot (`l_c`
    /// above `l`).
    pub fn perturbed(self, p: &Params, rel: f64) -> Option<Params> {
        let mut q = *p;
        let s = 1.0 + rel;
        match self {
            Parameter::MF => q.m_f *= s,
            Parameter::ML => q.m_l *= s,
            Parameter::L => q.l *= s,
            Parameter::F => q.f *= s,
            Parameter::G => q.g *= s,
            Parameter::LC => q.l_c = Some(p.l_c.unwrap_or(p.l) * s),
        }
        q.validate().ok().map(|_| q)
    }
}

/// The goal judged on one run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Goal {
    /// Tilts completed (landings).
    pub tilts: u64,
    /// Every tilt went to the other side than the one before.
    pub alternate: bool,
    /// Mean |peak| of the last [`LAST_PEAKS`] tilts (rad); 0 with fewer.
    pub last_peak: f64,
    /// `last_peak` relative to the nominal one, minus 1.
    pub deviation: f64,
    /// The run ended on a fault of the model.
    pub fault: bool,
    /// All of it holds: at least the tilts asked for, alternating, no fault, peaks within the
    /// tolerance.
    pub holds: bool,
}

impl Goal {
    /// The goal on `r`: at least `tilts` tilts, alternating, no fault, the last peaks within
    /// `tolerance` (relative) of `nominal` (rad).
    pub fn of(r: &SimulationReport, tilts: u64, nominal: f64, tolerance: f64) -> Self {
        let sides: Vec<Mode> = r
            .events
            .iter()
            .filter(|e| e.to.is_tilted())
            .map(|e| e.to)
            .collect();
        let alternate = sides.windows(2).all(|w| w[0] != w[1]);
        let n = r.tilt_peaks.len();
        let last_peak = if n >= LAST_PEAKS {
            r.tilt_peaks[n - LAST_PEAKS..]
                .iter()
                .map(|p| p.alpha.abs())
                .sum::<f64>()
                / LAST_PEAKS as f64
        } else {
            0.0
        };
        let deviation = last_peak / nominal - 1.0;
        let fault = r.fault.is_some();
        Goal {
            tilts: r.stats.tilts,
            alternate,
            last_peak,
            deviation,
            fault,
            holds: r.stats.tilts >= tilts && alternate && !fault && deviation.abs() <= tolerance,
        }
    }
}
