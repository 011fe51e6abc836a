//! The regressor rows of a recording: one or two equations per sample interval, linear in the
//! seven base parameters of docs/model.md ("Linear in the parameters") and the plate's inertia
//! `i_f` (`pi8`, whose column is `alpha_ddot` in the plate's row alone: it enters `M11` only).
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

use super::smooth::Savgol;
use tilting_proto::Mode;
use tilting_record::Trace;

/// Number of base parameters.
pub const N_BASE: usize = 8;

/// Rows of the regressor and the right-hand side, with what each mode contributed.
#[derive(Debug, Clone, Default)]
pub struct Rows {
    /// Regressor rows (one per equation), columns `pi1..pi8`.
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
    /// Each row's distance (samples) from the nearest mode change bordering its segment: from
    /// the change to the window's near end ([`build_from_angles`]); `usize::MAX` when its
    /// segment borders none, or for [`build`]'s rows.
    pub edge: Vec<usize>,
    /// Each row is the plate's equation of a tilted mode (right-hand side 0).
    pub plate: Vec<bool>,
}

impl Rows {
    fn push(&mut self, y: [f64; N_BASE], rhs: f64, edge: usize, plate: bool) {
        self.y.push(y);
        self.rhs.push(rhs);
        self.edge.push(edge);
        self.plate.push(plate);
    }
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
                    r.push(flat_row(&x, acc, g, sign), torque, usize::MAX, false);
                    r.flat += 1;
                }
            }
            m => {
                let fs = if m == Mode::Left { f } else { -f };
                let (row1, row2) = tilted_rows(&x, acc, fs, g, sign);
                r.push(row1, 0.0, usize::MAX, true);
                if sliding {
                    r.push(row2, torque, usize::MAX, false);
                }
                r.tilted += 1;
            }
        }
    }
    r
}

/// Builds the rows of `trace` from its angles alone (the recorded velocities are not read),
/// in the weak form (modulating functions): each equation `d/dt P(q, q_dot) pi + S(q,
/// q_dot) pi = rhs` of a contact mode, multiplied by a test function `phi` that vanishes
/// with its derivative at both ends of a window inside a segment, and integrated; by parts,
/// `integral (phi'' F(q) - phi' P1(q, q_dot) + phi S(q, q_dot)) dt pi = integral phi rhs
/// dt`, where `P = d/dt F(q) + P1`. No acceleration is needed, the angles enter mostly
/// through `F` (no derivative at all), and the equation holds exactly for any window: the
/// window's length smooths the noise without a bias. The velocities in `P1` and `S` come
/// from the differentiator `sg` ([`super::smooth`]). `w.len` (`window` below): samples per window (a
/// segment shorter than half of it is skipped, one between half and whole is one window);
/// windows overlap by three quarters. A torque row needs `|beta_dot| >= v_min` (rad/s), one
/// sign, over the whole window (`w.v_min`). Each row is divided by `integral phi dt`: its right-hand
/// side is a weighted mean torque (N m). `w.settle`: samples left out at each end of a segment
/// that borders a mode change (a landing or a lift-off: on a compliant contact the plate
/// sinks, rocks and bounces there for a few of the contact's time constants, which neither
/// mode's equations describe); 0 for a rigid contact.
///
/// Returns the rows and the smoothed state of each sample (`None` outside the segments).
pub fn build_from_angles(
    trace: &Trace,
    tau: &[Option<f64>],
    f: f64,
    g: f64,
    sg: &Savgol,
    w: Windows,
) -> (Rows, Vec<Option<[f64; 4]>>) {
    let Windows {
        len: window,
        settle,
        ..
    } = w;
    let mut r = Rows::default();
    let s = &trace.samples;
    let mut states = vec![None; s.len()];
    for (a0, b0) in segments(trace, tau) {
        // The segment's ends at a mode change are cut by `settle` samples.
        let starts_at_change = a0 > 0 && s[a0 - 1].mode != s[a0].mode;
        let ends_at_change = b0 < s.len() && s[b0].mode != s[b0 - 1].mode;
        let cut = |on: bool| if on { settle } else { 0 };
        let (a, b) = (
            a0 + cut(starts_at_change),
            b0.saturating_sub(cut(ends_at_change)),
        );
        if b <= a + 1 {
            r.skipped += b0 - a0;
            continue;
        }
        r.skipped += (b0 - a0) - (b - a);
        let n = b - a;
        if n < sg.len().max(MIN_WINDOW) {
            r.skipped += n;
            continue;
        }
        let h = (s[b - 1].t - s[a].t) / (n - 1) as f64;
        let x = smooth_states(&s[a..b], h, sg);
        let len = window.min(n);
        let hop = (len / 4).max(1);
        let count = 1 + (n - len).div_ceil(hop);
        let mut covered = vec![false; n];
        for c in 0..count {
            let lo = if count == 1 {
                0
            } else {
                c * (n - len) / (count - 1)
            };
            let win = lo..lo + len;
            let tq: Vec<f64> = tau[a + lo..a + lo + len - 1]
                .iter()
                .map(|t| t.unwrap_or(0.0))
                .collect();
            let edge = match (starts_at_change, ends_at_change) {
                (false, false) => usize::MAX,
                (true, false) => lo + settle,
                (false, true) => n - lo - len + settle,
                (true, true) => (lo + settle).min(n - lo - len + settle),
            };
            if !window_rows(&mut r, &x[win.clone()], &tq, h, s[a].mode, [f, g], w, edge) {
                continue;
            }
            covered[win].iter_mut().for_each(|c| *c = true);
        }
        let used = covered.iter().filter(|c| **c).count();
        if s[a].mode == Mode::Flat {
            r.flat += used;
        } else {
            r.tilted += used;
        }
        r.skipped += n - used;
        for (i, xi) in x.into_iter().enumerate() {
            states[a + i] = Some(xi);
        }
    }
    (r, states)
}

/// The smoothed states `(alpha, beta, alpha_dot, beta_dot)` (rad, rad/s) of the samples `seg`
/// of one segment (evenly spaced by `h`, s) by the differentiator `sg` on their angles.
fn smooth_states(seg: &[tilting_record::Sample], h: f64, sg: &Savgol) -> Vec<[f64; 4]> {
    let n = seg.len();
    let angle = |i: usize| -> Vec<f64> { seg.iter().map(|x| x.x[i]).collect() };
    let (al, be) = (angle(0), angle(1));
    (0..n)
        .map(|i| {
            let (lo, p) = sg.window(i, n);
            let w = lo..lo + sg.len();
            let (ea, eb) = (sg.at(&al[w.clone()], p, h), sg.at(&be[w], p, h));
            [ea.q, eb.q, ea.dq, eb.dq]
        })
        .collect()
}

/// Pushes onto `r` the weak-form rows of one window of [`build_from_angles`]: the smoothed
/// states `x` of its samples (spacing `h`, s) in contact mode `mode`, the torques `tq` (N m)
/// held over its intervals, the arm's friction and gravity constants `[f, g]`, `edge` samples
/// from the nearest mode change. The plate's row always (in a tilt), the arm's when the joint
/// slides through the window (slower than `w.v_min` at no more than one sample in
/// `SLOW_SHARE`). Returns whether the window was used (a flat window where the joint does not
/// slide is not).
#[allow(clippy::too_many_arguments)]
fn window_rows(
    r: &mut Rows,
    x: &[[f64; 4]],
    tq: &[f64],
    h: f64,
    mode: Mode,
    [f, g]: [f64; 2],
    w: Windows,
    edge: usize,
) -> bool {
    let len = x.len();
    // The joint slides through the window: slower than v_min at no more than one
    // sample in SLOW_SHARE (a reversal passed at speed, where the sign of the
    // estimated beta_dot is wrong for a moment at most). Where the joint lingers it
    // may stick, and Coulomb friction is not tau_c sign(beta_dot) there.
    let sign = x[len / 2][3].signum();
    let slow = x.iter().filter(|v| v[3].abs() < w.v_min).count();
    let sliding = slow * SLOW_SHARE <= len;
    let mut rows = weak_rows(x, tq, h, mode, f, g);
    // A row's noise grows as its window shrinks (the phi'' F(q) term: about
    // (W / len)^2.5 for white angle noise): a window cut short by its segment counts
    // for less, so that the few long windows are not drowned.
    let weight = (len as f64 / w.len as f64).min(1.0).powf(2.5);
    for (row, rhs) in rows.iter_mut() {
        row.iter_mut().for_each(|v| *v *= weight);
        *rhs *= weight;
    }
    match (mode, rows) {
        (Mode::Flat, [_, (arm, rhs)]) => {
            if !sliding {
                return false;
            }
            r.push(arm, rhs, edge, false);
        }
        (_, [(plate, zero), (arm, rhs)]) => {
            r.push(plate, zero, edge, true);
            if sliding {
                r.push(arm, rhs, edge, false);
            }
        }
    }
    if sliding {
        if sign > 0.0 {
            r.sliding_fwd += 1;
        } else {
            r.sliding_bwd += 1;
        }
    }
    true
}

/// How [`build_from_angles`] places its windows.
#[derive(Debug, Clone, Copy)]
pub struct Windows {
    /// Samples per window.
    pub len: usize,
    /// Slowest joint speed (rad/s) of a torque row.
    pub v_min: f64,
    /// Samples left out at each end of a segment that borders a mode change.
    pub settle: usize,
}

/// Shortest window (samples) of a segment: a segment shorter than this gives no row.
const MIN_WINDOW: usize = 50;

/// A window's torque row is used when at most one of this many samples is slower than
/// `v_min` (a reversal passed at speed).
const SLOW_SHARE: usize = 50;

/// The test function's power: `phi` and its first `PHI_POWER - 1` derivatives vanish at the
/// window's ends, so the trapezoid sums over the samples are exact to about
/// `(h / W)^(PHI_POWER - 2)` (Euler-Maclaurin): with a power of 4 a constant angle of 1 rad
/// left 1e-3 in a 0.1 s window's row; with 8, 1e-9.
const PHI_POWER: i32 = 8;

/// The test function `phi(s) = (1 - s^2)^PHI_POWER` on `s` in `[-1, 1]` and its first two
/// derivatives in `s`.
fn phi(s: f64) -> [f64; 3] {
    let (u, p) = (1.0 - s * s, PHI_POWER as f64);
    [
        u.powi(PHI_POWER),
        -2.0 * p * s * u.powi(PHI_POWER - 1),
        -2.0 * p * u.powi(PHI_POWER - 1) + 4.0 * p * (p - 1.0) * s * s * u.powi(PHI_POWER - 2),
    ]
}

/// The weak-form rows of one window of smoothed states `x` (spaced `h` s) with the torques
/// `tau` held over its intervals: `[(plate's row, 0), (arm's row, filtered torque)]` for a
/// tilted mode; for the flat mode the first is unused. Divided by `integral phi dt`.
fn weak_rows(
    x: &[[f64; 4]],
    tau: &[f64],
    h: f64,
    mode: Mode,
    f: f64,
    g: f64,
) -> [([f64; N_BASE], f64); 2] {
    let n = x.len();
    let span = (n - 1) as f64 * h;
    // s = 2 (t - t_mid) / span; d/dt = (2 / span) d/ds.
    let ds = 2.0 / span;
    let fs = if mode == Mode::Right { -f } else { f };
    let (mut plate, mut arm) = ([0.0; N_BASE], [0.0; N_BASE]);
    let mut norm = 0.0;
    for (k, &[al, be, ad, bd]) in x.iter().enumerate() {
        let sk = -1.0 + k as f64 * ds * h;
        let [p0, p1, p2] = phi(sk);
        let (w0, w1, w2) = (h * p0, -h * p1 * ds, h * p2 * ds * ds);
        norm += h * p0;
        let (sb, cb) = be.sin_cos();
        let gab = g * (al + be).cos();
        if mode == Mode::Flat {
            // The plate rocking about the joint (a compliant contact under the arm's reaction;
            // the recorded alpha, 0 on a rigid one): the arm's tilted equation with the pivot
            // at the joint (f = 0).
            arm[1] += w0 * gab;
            arm[2] += w2 * (al + be);
            arm[3] += w2 * al;
            arm[4] += w2 * be;
            arm[5] += w1 * be;
            arm[6] += w0 * bd.signum();
            continue;
        }
        plate[0] += w2 * fs * fs * al + w0 * g * fs * al.cos();
        plate[1] += w2 * fs * sb + w1 * 2.0 * fs * cb * ad + w0 * gab;
        plate[2] += w2 * (al + be);
        plate[3] += w2 * be;
        plate[7] += w2 * al;
        arm[1] += w1 * fs * cb * ad + w0 * (fs * sb * ad * (ad + bd) + gab);
        arm[2] += w2 * (al + be);
        arm[3] += w2 * al;
        arm[4] += w2 * be;
        arm[5] += w1 * be;
        arm[6] += w0 * bd.signum();
    }
    // The torque held over each interval against phi: 3-point Gauss-Legendre per interval
    // (exact to degree 5; phi is a polynomial, smooth over an interval of h).
    const GL: [(f64, f64); 3] = [
        (-0.774_596_669_241_483_4, 5.0 / 9.0),
        (0.0, 8.0 / 9.0),
        (0.774_596_669_241_483_4, 5.0 / 9.0),
    ];
    let mut rhs = 0.0;
    for (i, t) in tau.iter().enumerate() {
        let mid = -1.0 + (i as f64 + 0.5) * ds * h;
        let q: f64 = GL
            .iter()
            .map(|(u, w)| w * phi(mid + 0.5 * u * ds * h)[0])
            .sum();
        rhs += t * 0.5 * h * q;
    }
    for v in plate.iter_mut().chain(arm.iter_mut()) {
        *v /= norm;
    }
    [(plate, 0.0), (arm, rhs / norm)]
}

/// The segments `[a, b)` of samples joined by intervals without an event, a mode change, a
/// torque that is not known, or a gap (a spacing over 1.5 times the smallest).
pub(super) fn segments(trace: &Trace, tau: &[Option<f64>]) -> Vec<(usize, usize)> {
    let s = &trace.samples;
    let h_min = s
        .windows(2)
        .map(|w| w[1].t - w[0].t)
        .filter(|&d| d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let mut ev = trace.events.iter().map(|e| e.t).peekable();
    let mut out = Vec::new();
    let mut start = 0;
    for k in 0..s.len().saturating_sub(1) {
        let (a, b) = (&s[k], &s[k + 1]);
        while ev.next_if(|&te| te <= a.t).is_some() {}
        let event_inside = ev.peek().is_some_and(|&te| te <= b.t);
        let known = tau.get(k).copied().flatten().is_some_and(f64::is_finite);
        let dt = b.t - a.t;
        let joined = !event_inside && a.mode == b.mode && known && dt > 0.0 && dt <= 1.5 * h_min;
        if !joined {
            out.push((start, k + 1));
            start = k + 1;
        }
    }
    if start < s.len() {
        out.push((start, s.len()));
    }
    out
}

/// Flat: `(pi3 + pi5) beta_ddot + g cos(beta) pi2 + beta_dot pi6 + sign pi7 = tau` on a
/// plate at rest. A compliant contact lets the plate rock about its centre (the joint) under
/// the arm's reaction, by the recorded `alpha` (1e-4 to 3e-3 rad on MuJoCo's softer contacts):
/// then the arm's tilted equation with the pivot at the joint (`f = 0`), `pi3 (alpha_ddot +
/// beta_ddot) + pi4 alpha_ddot + pi5 beta_ddot + g cos(alpha + beta) pi2 + ...`, which is the
/// former when `alpha` is 0.
fn flat_row(x: &[f64; 4], acc: [f64; 2], g: f64, sign: f64) -> [f64; N_BASE] {
    tilted_rows(x, acc, 0.0, g, sign).1
}

/// Tilted (`fs` = `f` left, `-f` right): the plate's row (= 0) and the torque row (= tau).
/// The plate's inertia `i_f` (`pi8`) turns with `alpha` only: `+ i_f alpha_ddot` in the plate's
/// row, nothing in the arm's.
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
        add,
    ];
    let row2 = [
        0.0,
        fs * cb * add + fs * sb * ad * ad + gab,
        add + bdd,
        add,
        bdd,
        bd,
        sign,
        0.0,
    ];
    (row1, row2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rotor's structural limit, from the regressor itself: in every flat row the columns
    /// of `pi3` and `pi5` are the same number (`beta_ddot`, or its weak form), so no flat
    /// recording separates them (only `pi3 + pi5` is fixed); in the tilted rows they differ as
    /// soon as `alpha_ddot != 0`, and `pi4` has a column of its own.
    #[test]
    fn flat_rows_carry_pi3_and_pi5_in_one_column() {
        let x = [0.0, 1.3, 0.0, 0.4];
        let r = flat_row(&x, [0.0, 0.7], 9.81, 1.0);
        assert_eq!(r[2], r[4]);
        assert_eq!((r[0], r[3]), (0.0, 0.0));
        let xs: Vec<[f64; 4]> = (0..101)
            .map(|k| {
                let t = k as f64 * 1e-3;
                [0.0, 1.3 + 0.4 * t + 2.0 * t * t, 0.0, 0.4 + 4.0 * t]
            })
            .collect();
        let tau = vec![1.0; 100];
        let [_, (arm, _)] = weak_rows(&xs, &tau, 1e-3, Mode::Flat, 0.5, 9.81);
        assert_eq!(arm[2], arm[4]);
        assert_eq!((arm[0], arm[3]), (0.0, 0.0));
        // Tilted: the plate's row has pi4 (beta_ddot) and no pi5; the arm's row has pi3
        // (alpha_ddot + beta_ddot), pi4 (alpha_ddot) and pi5 (beta_ddot), all different.
        let (plate, arm) = tilted_rows(&[0.02, 1.3, 0.1, 0.4], [0.8, 0.7], 0.5, 9.81, 1.0);
        assert_eq!((plate[2], plate[3], plate[4]), (0.8 + 0.7, 0.7, 0.0));
        assert_eq!((arm[2], arm[3], arm[4]), (0.8 + 0.7, 0.8, 0.7));
    }

    /// The weak form of a smooth tilted motion equals the pointwise equations (with the
    /// exact accelerations) integrated against the test function, column by column: the
    /// arm's row against the torque held at each interval's midpoint value, the plate's row
    /// against its own trapezoid integral.
    #[test]
    fn weak_rows_hold_for_a_smooth_motion() {
        for col in 0..N_BASE {
            let mut pi = [0.0; N_BASE];
            pi[col] = 1.0;
            let (f, g, h) = (0.5, 9.81, 1e-3);
            let q = |t: f64| {
                [
                    0.05 * (3.0 * t).sin(),
                    1.2 + 0.5 * (2.0 * t).sin() + 0.3 * t,
                    0.15 * (3.0 * t).cos(),
                    1.0 * (2.0 * t).cos() + 0.3,
                    -0.45 * (3.0 * t).sin(),
                    -2.0 * (2.0 * t).sin(),
                ]
            };
            let dot = |r: &[f64; N_BASE]| r.iter().zip(&pi).map(|(a, b)| a * b).sum::<f64>();
            let n = 101;
            let x: Vec<[f64; 4]> = (0..n)
                .map(|k| {
                    let v = q(k as f64 * h);
                    [v[0], v[1], v[2], v[3]]
                })
                .collect();
            let tau: Vec<f64> = (0..n - 1)
                .map(|k| {
                    let v = q((k as f64 + 0.5) * h);
                    let (p, a) = tilted_rows(&[v[0], v[1], v[2], v[3]], [v[4], v[5]], f, g, 1.0);
                    // The plate's equation is not zero for an arbitrary motion: it is checked
                    // against its own integral below.
                    let _ = p;
                    dot(&a)
                })
                .collect();
            let plate_int: f64 = (0..n)
                .map(|k| {
                    let v = q(k as f64 * h);
                    let (p, _) = tilted_rows(&[v[0], v[1], v[2], v[3]], [v[4], v[5]], f, g, 1.0);
                    let s = -1.0 + 2.0 * k as f64 / (n - 1) as f64;
                    h * phi(s)[0] * dot(&p)
                })
                .sum();
            let norm: f64 = (0..n)
                .map(|k| h * phi(-1.0 + 2.0 * k as f64 / (n - 1) as f64)[0])
                .sum();
            let [(plate, _), (arm, rhs)] = weak_rows(&x, &tau, h, Mode::Left, f, g);
            // Tolerance: the test's own torque (the midpoint value held) is O(h^2) off the
            // held mean, 1e-7 of the row here; the weak form itself is exact to 1e-9.
            let want_plate = plate_int / norm;
            for (got, want) in [(dot(&arm), rhs), (dot(&plate), want_plate)] {
                assert!(
                    (got - want).abs() < 1e-6 * want.abs().max(1e-2),
                    "column {col}: {got} vs {want}"
                );
            }
        }
    }
}
