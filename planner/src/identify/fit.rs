//! The fit check: the recorded motion re-simulated with a set of parameters, under the
//! recorded torques, beside the recording.
//!
//! A tilting robot under its recorded torques alone (open loop) drifts off within a tilt or
//! two whatever the parameters (the motion is unstable without its controller), so the
//! re-simulation restarts from the recorded state every `window` seconds (a multiple-shooting
//! check): in each window the plant with the given parameters starts from the state the fit
//! saw at the window's first sample (the smoothed angles and their rates), in the recorded
//! mode, and is driven by the recorded torques held over their intervals; its angles are
//! compared with the recorded ones at every sample of the window. The RMS of the differences
//! is the fit's figure: with the true parameters it is the sensor noise; a wrong parameter
//! adds its drift.

use serde::Serialize;
use tilting_plant::{Mode, Params, Plant, SimConfig};
use tilting_record::{Sample, Trace};

/// Default re-simulation window (s).
pub const WINDOW: f64 = 0.25;

/// The re-simulation's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitCheck {
    /// Restart interval (s).
    pub window_s: f64,
    /// Windows re-simulated (a window without a usable start, or whose re-simulation faults,
    /// is left out).
    pub windows: usize,
    /// Samples compared.
    pub samples: usize,
    /// RMS of `alpha` re-simulated minus recorded (rad).
    pub rms_alpha: f64,
    /// RMS of `beta` re-simulated minus recorded (rad).
    pub rms_beta: f64,
    /// Largest `|difference|` of either angle (rad).
    pub max_error: f64,
}

/// The re-simulated samples (at the recorded sample times) and the figures.
#[derive(Debug, Clone)]
pub struct Resimulation {
    /// One sample per compared recorded sample; a window's first sample starts a new piece.
    pub samples: Vec<Sample>,
    /// Index into `samples` where each window starts.
    pub starts: Vec<usize>,
    /// The figures.
    pub check: FitCheck,
}

/// Re-simulates `trace` (torques `tau` held over the sample intervals) with the parameters
/// `p`, restarting every `window` s from `states` (the fit's state of each sample, `None`
/// where it has none).
pub fn resimulate(
    trace: &Trace,
    tau: &[Option<f64>],
    states: &[Option<[f64; 4]>],
    p: &Params,
    window: f64,
) -> Resimulation {
    let s = &trace.samples;
    let cfg = SimConfig {
        params: *p,
        impact: p.impact,
        ..SimConfig::default()
    };
    let mut out = Vec::new();
    let mut starts = Vec::new();
    let (mut se_a, mut se_b, mut max) = (0.0, 0.0, 0.0f64);
    let mut k = 0;
    while k + 1 < s.len() {
        let Some(x0) = states.get(k).copied().flatten() else {
            k += 1;
            continue;
        };
        let t_stop = s[k].t + window;
        let x0 = match s[k].mode {
            Mode::Flat => [0.0, x0[1], 0.0, x0[3]],
            _ => x0,
        };
        let Ok(mut plant) = Plant::new(cfg, s[k].t, s[k].mode, x0.into()) else {
            k += 1;
            continue;
        };
        let mut piece = vec![Sample {
            t: s[k].t,
            mode: s[k].mode,
            x: x0,
        }];
        let mut j = k;
        while j + 1 < s.len() && s[j + 1].t <= t_stop + 1e-9 {
            let Some(u) = tau.get(j).copied().flatten() else {
                break;
            };
            if plant.advance_held(u, s[j + 1].t, &mut ()).is_err() {
                break;
            }
            j += 1;
            piece.push(Sample {
                t: s[j].t,
                mode: plant.mode(),
                x: plant.state().into(),
            });
        }
        if piece.len() > 1 {
            starts.push(out.len());
            for (q, r) in piece.iter().zip(&s[k..]).skip(1) {
                let (da, db) = (q.x[0] - r.x[0], q.x[1] - r.x[1]);
                se_a += da * da;
                se_b += db * db;
                max = max.max(da.abs()).max(db.abs());
            }
            out.extend(piece);
        }
        k = j.max(k + 1);
    }
    let n = out.len() - starts.len();
    let rms = |se: f64| {
        if n == 0 {
            f64::NAN
        } else {
            (se / n as f64).sqrt()
        }
    };
    Resimulation {
        check: FitCheck {
            window_s: window,
            windows: starts.len(),
            samples: n,
            rms_alpha: rms(se_a),
            rms_beta: rms(se_b),
            max_error: max,
        },
        samples: out,
        starts,
    }
}
