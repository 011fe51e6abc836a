//! The paper's Fig. 6: the maximal tilt angle of the periodic orbits of approach 2 over a grid
//! of gains `(K_P, K_D)`. Each row of constant `K_P` is solved by continuation in `K_D` from
//! the orbits found at its first cell, with a full search every fifth cell; rows run in
//! parallel.

use crate::orbit::{self, OrbitProblem, OrbitSolution};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tilting_plant::{ImpactLaw, Params};

/// One grid cell.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Cell {
    /// Stiffness gain `K_P` (1/s^2).
    pub kp: f64,
    /// Damping gain `K_D` (1/s).
    pub kd: f64,
    /// Maximal tilt angle (rad) of each orbit found (several branches are possible).
    pub max_tilt: Vec<f64>,
    /// Whether each orbit is stable (all multipliers inside the unit circle).
    pub stable: Vec<bool>,
}

/// How many values [`range`] gives, computed without allocating them (a float, so that an
/// absurd step reads as a huge count instead of overflowing): check it against a limit first.
pub fn range_len(from: f64, to: f64, step: f64) -> f64 {
    ((to - from) / step + 0.5).floor().max(0.0) + 1.0
}

/// Evenly spaced values from `from` to `to` (inclusive, within half a step).
pub fn range(from: f64, to: f64, step: f64) -> Vec<f64> {
    let n = ((to - from) / step + 0.5).floor().max(0.0) as usize;
    (0..=n).map(|i| from + step * i as f64).collect()
}

fn dedup(mut v: Vec<OrbitSolution>) -> Vec<OrbitSolution> {
    v.sort_by(|a, b| a.max_tilt.total_cmp(&b.max_tilt));
    v.dedup_by(|a, b| (a.max_tilt - b.max_tilt).abs() < 1e-7 && (a.t_end - b.t_end).abs() < 1e-7);
    v
}

/// Solves one row `K_P = kp` over `kds`.
pub fn row(params: Params, impact: ImpactLaw, kp: f64, kds: &[f64]) -> Vec<Cell> {
    let mut out = Vec::with_capacity(kds.len());
    let mut prev: Vec<OrbitSolution> = Vec::new();
    for (i, &kd) in kds.iter().enumerate() {
        let pb = OrbitProblem::new(params, impact, kp, kd);
        let mut sols: Vec<OrbitSolution> = prev
            .iter()
            .filter_map(|s| orbit::solve(&pb, [s.beta0, s.beta_dot0, s.t_end]).ok())
            .collect();
        // A full search at every fifth cell (and whenever the branches are lost) catches
        // branches that appear along the row.
        if sols.is_empty() || i % 5 == 0 {
            sols.extend(orbit::find_all(&pb));
        }
        let sols = dedup(sols);
        out.push(Cell {
            kp,
            kd,
            max_tilt: sols.iter().map(|s| s.max_tilt).collect(),
            stable: sols.iter().map(|s| s.stable).collect(),
        });
        prev = sols;
    }
    out
}

/// The whole grid, rows of constant `K_P` in parallel; `tick` is called after each row.
pub fn grid(
    params: Params,
    impact: ImpactLaw,
    kps: &[f64],
    kds: &[f64],
    tick: &(dyn Fn() + Sync),
) -> Vec<Cell> {
    kps.par_iter()
        .map(|&kp| {
            let r = row(params, impact, kp, kds);
            tick();
            r
        })
        .flatten()
        .collect()
}
