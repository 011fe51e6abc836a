//! The regressor rows of a recording: one or two equations per sample interval, linear in the
//! seven base parameters of docs/model.md ("Linear in the parameters").
//!
//! **Accelerations.** A recorded torque is held over a sample interval `[t_k, t_{k+1}]`, so the
//! acceleration jumps at every sample and is smooth only inside an interval. Each interval gives
//! its own row: the dynamics averaged over the interval, with the mean acceleration
//! `(v_{k+1} - v_k) / (t_{k+1} - t_k)` exactly (no smoothing across a torque step), the other
//! terms at the interval's mean state (the midpoint rule, error `O(h^2)`), and the held torque
//! `tau_k` exactly. An interval is skipped when it could straddle an impact or a mode
//! transition (its two samples' modes differ, or an event lies in `(t_k, t_{k+1}]`), or when
//! its torque is not known. The torque row is also skipped when the joint may stick or reverse
//! inside it (`beta_dot` is zero or changes sign), since Coulomb friction is not `tau_c
//! sign(beta_dot)` there; the plate's row (no torque, no friction) is kept.

use tilting_proto::Mode;
use tilting_record::Trace;

/// Number of base parameters.
pub const N_BASE: usize = 7;

/// Rows of the regressor and the right-hand side, with what each mode contributed.
#[derive(Debug, Clone, Default)]
pub struct Rows {
    /// Regressor rows (one per equation), columns `pi1..pi7`.
    pub y: Vec<[f64; N_BASE]>,
    /// Right-hand side (N m): the held torque for a torque row, 0 for the plate's row.
    pub rhs: Vec<f64>,
    /// Torque rows from flat intervals.
    pub flat: usize,
    /// Intervals in a tilted mode (each gives the plate's row, and a torque row when sliding).
    pub tilted: usize,
    /// Intervals skipped (a mode change or an event inside, a torque missing or not finite).
    pub skipped: usize,
    /// Torque rows (flat or tilted) with `beta_dot` both ways: Coulomb friction `pi7` needs both
    /// signs, else its column is the constant `+-1` of one sign.
    pub sliding_fwd: usize,
    /// Torque rows with `beta_dot < 0`.
    pub sliding_bwd: usize,
}

/// Builds the rows of `trace` with `tau[k]` the torque (N m) held over `[t_k, t_{k+1}]`
/// (`None` where it is not known), for the plate's half length `f` (m) and gravity `g`
/// (m/s^2).
pub fn build(trace: &Trace, tau: &[Option<f64>], f: f64, g: f64) -> Rows {
    let mut r = Rows::default();
    let s = &trace.samples;
    let mut ev = trace.events.iter().map(|e| e.t).peekable();
    for k in 0..s.len().saturating_sub(1) {
        let (a, b) = (&s[k], &s[k + 1]);
        while ev.next_if(|&te| te <= a.t).is_some() {}
        let event_inside = ev.peek().is_some_and(|&te| te <= b.t);
        let h = b.t - a.t;
        let torque = tau.get(k).copied().flatten().filter(|t| t.is_finite());
        let (Some(torque), false, true) = (torque, event_inside || a.mode != b.mode, h > 0.0)
        else {
            r.skipped += 1;
            continue;
        };
        let x: [f64; 4] = std::array::from_fn(|i| 0.5 * (a.x[i] + b.x[i]));
        let acc = [(b.x[2] - a.x[2]) / h, (b.x[3] - a.x[3]) / h];
        let sliding = a.x[3] * b.x[3] > 0.0;
        let sign = x[3].signum();
        if sliding {
            if sign > 0.0 {
                r.sliding_fwd += 1;
            } else {
                r.sliding_bwd += 1;
            }
        }
        match a.mode {
            Mode::Flat => {
                if sliding {
                    r.y.push(flat_row(&x, acc[1], g, sign));
                    r.rhs.push(torque);
                    r.flat += 1;
                }
            }
            m => {
                let fs = if m == Mode::Left { f } else { -f };
                let (row1, row2) = tilted_rows(&x, acc, fs, g, sign);
                r.y.push(row1);
                r.rhs.push(0.0);
                if sliding {
                    r.y.push(row2);
                    r.rhs.push(torque);
                }
                r.tilted += 1;
            }
        }
    }
    r
}

/// Flat: `(pi3 + pi5) beta_ddot + g cos(beta) pi2 + beta_dot pi6 + sign pi7 = tau`.
fn flat_row(x: &[f64; 4], bdd: f64, g: f64, sign: f64) -> [f64; N_BASE] {
    [0.0, g * x[1].cos(), bdd, 0.0, bdd, x[3], sign]
}

/// Tilted (`fs` = `f` left, `-f` right): the plate's row (= 0) and the torque row (= tau).
fn tilted_rows(
    x: &[f64; 4],
    acc: [f64; 2],
    fs: f64,
    g: f64,
    sign: f64,
) -> ([f64; N_BASE], [f64; N_BASE]) {
    let [al, be, ad, bd] = *x;
    let [add, bdd] = acc;
    let (sb, cb) = be.sin_cos();
    let gab = g * (al + be).cos();
    let row1 = [
        fs * fs * add + g * fs * al.cos(),
        2.0 * fs * cb * add + fs * cb * bdd - fs * sb * (2.0 * ad * bd + bd * bd) + gab,
        add + bdd,
        bdd,
        0.0,
        0.0,
        0.0,
    ];
    let row2 = [
        0.0,
        fs * cb * add + fs * sb * ad * ad + gab,
        add + bdd,
        add,
        bdd,
        bd,
        sign,
    ];
    (row1, row2)
}
