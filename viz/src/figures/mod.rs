//! The paper's Figs. 4 to 8 as PNG files, computed from scratch with the planner and the
//! closed loop and drawn with plotters. [`Figures::draw`] draws one; the `tilting figures`
//! command draws them all with a progress bar (fed by a callback).
//!
//! - Fig. 4 ([`sinusoid`]): the partition of the `(A, w)` plane: the pairs whose ideal arm
//!   motion never tilts the plate, and the curves `t_l = T/2 + s t_t` for `s = -1, 0, 1`;
//! - Fig. 5: the closed loop (PD, `K_P = 100`, `K_D = 14.14`, impacts) tracking the sinusoid of
//!   four planned `(A, w)` pairs, the simulated tilt against the planned one;
//! - Fig. 6 ([`gains`]): the maximal tilt of the periodic orbits of approach 2 over `(K_P, K_D)`;
//! - Fig. 7: the unstable orbit left alone (perturbed up and down) and stabilised by the energy
//!   adaptation `k = 500`;
//! - Fig. 8 ([`bifurcation`]): the tilt peaks over the adaptation gain `k`, with `k*`, and three
//!   peak series;
//! - Fig. 8b (issue 19, [`crate::continuation::cascade_figure`]): the continued period-1, 2, 4,
//!   ... orbits over the sweep, and the largest Lyapunov exponent below;
//! - Fig. 8c (issue 19, [`crate::continuation::draw_stability`]): the stability region of the
//!   period-1 orbit in `(k, K_D)`.
//!
//! Figures are named by strings: `"4"` to `"8"`, `"8b"`, `"8c"` ([`ALL`]).

mod fig4;
mod fig5;
mod fig6;
mod fig7;
mod fig8;
mod fig8bc;
mod report;
mod style;

pub use fig4::{Fig4Curve, Fig4Summary};
pub use fig5::{Fig5Panel, Fig5Summary};
pub use fig6::Fig6Summary;
pub use fig7::{Fig7Run, Fig7Summary};
pub use fig8::Fig8Summary;
pub use fig8bc::{Fig8bSummary, Fig8cSummary};
pub use report::{FigureReport, FiguresProgress, FiguresReport};

use crate::plot::register_fonts;
use anyhow::{anyhow, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};
use style::{
    clip, legend, star_points, style_mesh, symmetric, tick3, Area, Chart, BLUE, FONT, GREEN, GREY,
    PALETTE, RED,
};
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec, PlannableLaw, Trajectory};
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::gains;
use tilting_planner::orbit::{self, OrbitProblem, OrbitSolution};
use tilting_planner::sinusoid::{self, Search};
use tilting_plant::paper::{ORBIT_KD as KD, ORBIT_KP as KP};
use tilting_plant::{Fault, ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, TiltPeak};

/// The figures there are, in drawing order: the paper's 4 to 8, and issue 19's 8b and 8c.
pub const ALL: [&str; 7] = ["4", "5", "6", "7", "8", "8b", "8c"];

/// The id in [`ALL`] that `s` names (surrounding spaces ignored), or an error listing them.
pub fn figure_id(s: &str) -> Result<&'static str, String> {
    let t = s.trim();
    ALL.iter().copied().find(|&n| n == t).ok_or_else(|| {
        format!(
            "no figure `{s}`: the figures are {} (e.g. --only 4,8b)",
            ALL.join(", ")
        )
    })
}

/// Grid sizes and run lengths; [`Settings::quick`] for previews and tests.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Fig. 4: amplitude step of the curves (rad).
    a_step: f64,
    /// Fig. 4: amplitude step of the no-tilt grid (rad).
    grid_a_step: f64,
    /// Fig. 4: frequency step of the no-tilt grid (rad/s).
    grid_w_step: f64,
    /// Fig. 4: scan points above the no-tilt boundary.
    scan: usize,
    /// Fig. 5: periods simulated.
    periods: f64,
    /// Fig. 6: steps of K_P and K_D.
    kp_step: f64,
    kd_step: f64,
    /// Fig. 7: duration of each run (s).
    fig7_duration: f64,
    /// Fig. 8: step of k, tilts per k, tilts kept.
    k_step: f64,
    tilts: usize,
    keep: usize,
    /// Fig. 8: tilts per time series, and how many of the last are shown.
    series_tilts: usize,
    series_keep: usize,
    /// Fig. 8b: the highest period continued, where the branches end, the Lyapunov curve's
    /// step in `k` with its transient and averaged tilts, and the sweep under the branches.
    cascade_period: usize,
    cascade_to: f64,
    lyapunov_step: f64,
    lyapunov_transient: usize,
    lyapunov_tilts: usize,
    cascade_sweep: crate::continuation::CascadeSweep,
    /// Fig. 8b: the step in `k` of the 1 kHz sampled loop's exponents (0: none).
    sampled_step: f64,
    /// Fig. 8c: the range of K_D (1/s).
    kd_range: (f64, f64),
}

impl Settings {
    /// The grids and run lengths of the published figures (minutes on 2 cores).
    pub fn full() -> Self {
        Self {
            a_step: 0.01,
            grid_a_step: 0.02,
            grid_w_step: 0.25,
            scan: 90,
            periods: 3.0,
            kp_step: 10.0,
            kd_step: 0.5,
            fig7_duration: 15.0,
            k_step: 5.0,
            tilts: 600,
            keep: 150,
            series_tilts: 600,
            series_keep: 60,
            // `plan continuation`'s defaults.
            cascade_period: 16,
            cascade_to: 2400.0,
            lyapunov_step: 9.5,
            lyapunov_transient: 200,
            lyapunov_tilts: 400,
            cascade_sweep: crate::continuation::CascadeSweep::FULL,
            sampled_step: 38.0,
            // `plan stability`'s default.
            kd_range: (8.0, 18.0),
        }
    }

    /// Coarse grids and short runs: a preview in seconds.
    pub fn quick() -> Self {
        Self {
            a_step: 0.05,
            grid_a_step: 0.05,
            grid_w_step: 1.0,
            scan: 40,
            periods: 2.0,
            kp_step: 40.0,
            kd_step: 3.0,
            fig7_duration: 6.0,
            k_step: 100.0,
            tilts: 150,
            keep: 40,
            series_tilts: 150,
            series_keep: 30,
            cascade_period: 4,
            cascade_to: 2250.0,
            lyapunov_step: 175.0,
            lyapunov_transient: 30,
            lyapunov_tilts: 60,
            cascade_sweep: crate::continuation::CascadeSweep {
                k_step: 50.0,
                tilts: 150,
                keep: 40,
                k_min: 1500.0,
            },
            sampled_step: 0.0,
            kd_range: (13.0, 15.5),
        }
    }
}

/// Amplitude range of Fig. 4 (rad) and the frequency range of its no-tilt grid (rad/s).
const FIG4_A: (f64, f64) = (0.02, 0.6);
const FIG4_W: (f64, f64) = (0.5, 16.0);
/// Fig. 5: amplitude and landing offsets (the paper's).
const FIG5_A: f64 = 0.33;
const FIG5_S: [(f64, &str); 4] = [
    (-0.5, "1/2"),
    (-0.25, "1/4"),
    (-1.0 / 6.0, "1/6"),
    (-0.125, "1/8"),
];
/// The paper's gains.
/// Fig. 7: adaptation gain and the perturbation of `beta_dot0` (rad/s).
const FIG7_K: f64 = 500.0;
const FIG7_PERTURBATION: f64 = 1e-3;
/// Fig. 8: range of k and the three gains of the time series.
const FIG8_K: (f64, f64) = (1500.0, 2500.0);
const FIG8_SERIES: [f64; 3] = [1900.0, 2210.0, 2300.0];

/// What every figure needs: the model, the grids and where the PNGs go.
pub struct Figures {
    /// Model parameters.
    pub params: Params,
    /// Landing impact law.
    pub impact: ImpactLaw,
    /// Grids and run lengths.
    pub set: Settings,
    /// Output directory (it must exist).
    pub out: PathBuf,
}

/// The figures' own name for their context.
type Ctx = Figures;

impl Figures {
    /// The file of figure `n` (an id of [`ALL`]): `{out}/fig{n}.png`.
    pub fn path(&self, n: &str) -> PathBuf {
        self.out.join(format!("fig{n}.png"))
    }

    fn amplitudes(&self) -> Vec<f64> {
        gains::range(FIG4_A.0, FIG4_A.1, self.set.a_step)
    }

    fn kps(&self) -> Vec<f64> {
        gains::range(60.0, 140.0, self.set.kp_step)
    }

    fn kds(&self) -> Vec<f64> {
        gains::range(8.0, 20.0, self.set.kd_step)
    }

    fn ks(&self) -> Vec<f64> {
        gains::range(FIG8_K.0, FIG8_K.1, self.set.k_step)
    }

    /// Progress units of figure `n` (the ticks [`Figures::draw`] gives; for 8b and 8c, whose
    /// continuation step counts are not known beforehand, an upper bound).
    pub fn units(&self, n: &str) -> u64 {
        (match n {
            "4" => self.amplitudes().len() + 1,
            "5" => FIG5_S.len(),
            "6" => self.kps().len() + 1,
            "7" => 4,
            "8" => self.ks().len() + FIG8_SERIES.len() + 2,
            "8b" => fig8bc::units_8b(self),
            "8c" => fig8bc::units_8c(),
            _ => 0,
        }) as u64
    }

    fn sim_config(&self) -> SimConfig {
        SimConfig {
            params: self.params,
            impact: self.impact,
            // Small steps: the samples are drawn as a polyline.
            h_max: 2e-3,
            ..SimConfig::default()
        }
    }

    fn orbit_problem(&self) -> OrbitProblem {
        OrbitProblem::new(self.params, self.impact, KP, KD)
    }

    /// Computes and draws figure `n` (an id of [`ALL`]) into [`Figures::path`], calling `tick`
    /// once per unit of progress (about [`Figures::units`] in all; from several threads);
    /// returns its summary: a one-line `text` and the figure's numbers.
    pub fn draw(&self, n: &str, tick: &(dyn Fn() + Sync)) -> Result<Summary> {
        register_fonts()?;
        Ok(match n {
            "4" => Summary::Fig4(fig4::fig4(self, tick)?),
            "5" => Summary::Fig5(fig5::fig5(self, tick)?),
            "6" => Summary::Fig6(fig6::fig6(self, tick)?),
            "7" => Summary::Fig7(fig7::fig7(self, tick)?),
            "8" => Summary::Fig8(fig8::fig8(self, tick)?),
            "8b" => Summary::Fig8b(fig8bc::fig8b(self, tick)?),
            "8c" => Summary::Fig8c(fig8bc::fig8c(self, tick)?),
            _ => return Err(anyhow!(figure_id(n).err().unwrap_or_default())),
        })
    }
}

/// What [`Figures::draw`] reports about one figure. In JSON the figure's own object (the
/// variant is not written; each figure's fields tell it apart when read back).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Summary {
    /// Fig. 4.
    Fig4(Fig4Summary),
    /// Fig. 5.
    Fig5(Fig5Summary),
    /// Fig. 6.
    Fig6(Fig6Summary),
    /// Fig. 7.
    Fig7(Fig7Summary),
    /// Fig. 8.
    Fig8(Fig8Summary),
    /// Fig. 8b.
    Fig8b(Fig8bSummary),
    /// Fig. 8c.
    Fig8c(Fig8cSummary),
}

impl Summary {
    /// The one-line description of what the figure shows.
    pub fn text(&self) -> &str {
        match self {
            Summary::Fig4(s) => &s.text,
            Summary::Fig5(s) => &s.text,
            Summary::Fig6(s) => &s.text,
            Summary::Fig7(s) => &s.text,
            Summary::Fig8(s) => &s.text,
            Summary::Fig8b(s) => &s.text,
            Summary::Fig8c(s) => &s.text,
        }
    }
}
