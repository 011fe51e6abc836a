//! The landings of a recording: which landing law the robot obeys, and its restitution.
//!
//! Every landing law of docs/model.md ("The landing laws") keeps `beta` and sets
//! `beta_dot+ = beta_dot- + c(beta) alpha_dot-`; they differ in `c` (the paper's `M11 / M12`,
//! the striking edge's, the physical `(1 + e) M12 / M22`) and in `alpha_dot+` (0, or `-e
//! alpha_dot-` for a physical rebound). So from each landing the state just before and just
//! after is what is needed.
//!
//! **The state at the landing instant.** The recording has the plant's states at its sample
//! times (1 kHz) and the mode changes; a landing falls between two samples. Each side is a
//! local least-squares polynomial of degree [`DEGREE`] in time through the angles of the
//! [`SIDE`] samples (at most) on that side, and through the recorded rates where they are
//! measured (`--measure angles` records none), extrapolated to the landing instant: the root of
//! the side before's `alpha` nearest the recorded event time (the event's own time when there is
//! no root between the two samples around it). The side before is the tilt the plate lands
//! from, back to the previous landing at most; the side after runs to the next landing at most
//! (a tilt started from rest after a landing keeps the state continuous, so a polynomial through
//! it holds).
//!
//! **The fit.** With `a = alpha_dot-`, `d = beta_dot+ - beta_dot-` and `r = alpha_dot+` of each
//! landing: the coefficient `c = sum a d / sum a^2` (the least squares of `d = c a` over the
//! landings); the restitution `e` of the physical law from the two rows of each landing,
//! `r = -e a` and `d - k a = e k a` (`k = M12 / M22` at the landing's `beta` with the
//! identified parameters), by least squares; and each law's residual RMS over both rows of
//! every landing (`alpha_dot+` and `beta_dot+` predicted minus estimated, rad/s), the physical
//! law's with the estimated `e`. The law with the smallest residual fits best. Standard errors
//! from the residual variance (white, independent landings).

use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use tilting_plant::dynamics::{accelerations, mass_matrix};
use tilting_plant::{ImpactLaw, Mode, Params, State};
use tilting_record::Trace;

/// Most samples fitted on each side of a landing from the angles alone (20 ms at 1 kHz).
pub const SIDE: usize = 20;
/// Most samples fitted on a side whose rates are recorded: the recorded rates fix the
/// slope, and a shorter polynomial spans fewer of the held torque's steps (each a jump of the
/// accelerations). Measured on the physical law with e = 0.3: per-landing e within 0.016
/// with 20 samples, within 0.003 with 6.
pub const SIDE_RATES: usize = 6;
/// Fewest samples on a side for a landing to be used.
pub const MIN_SIDE: usize = 6;
/// Degree of the local polynomials (2 on a side of fewer than 10 samples).
pub const DEGREE: usize = 3;
/// A landing slower than this (`|alpha_dot-|`, rad/s) gives no per-landing `c` or `e` (its
/// rows still enter the fits, weighted by the speed).
pub const MIN_SPEED: f64 = 1e-3;
/// The largest restitution written to a params file (`restitution` must be below 1).
pub const MAX_RESTITUTION: f64 = 0.99;

/// One landing as the recording shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LandingEstimate {
    /// The landing instant (s).
    pub t: f64,
    /// The tilt the plate lands from.
    pub from: Mode,
    /// The mode right after: flat, the same edge (a rebound) or the other edge.
    pub to: Mode,
    /// The arm angle at the landing (rad).
    pub beta: f64,
    /// `(alpha_dot-, beta_dot-)` (rad/s).
    pub before: [f64; 2],
    /// `(alpha_dot+, beta_dot+)` (rad/s).
    pub after: [f64; 2],
    /// `(beta_dot+ - beta_dot-) / alpha_dot-`; `None` below [`MIN_SPEED`].
    pub c: Option<f64>,
    /// `-alpha_dot+ / alpha_dot-`; `None` below [`MIN_SPEED`].
    pub e: Option<f64>,
}

/// One law against the landings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LawFit {
    /// The law.
    pub law: ImpactLaw,
    /// Its coefficient `c` at the landings, weighted as the regression weighs them
    /// (`alpha_dot-^2`); the physical law's with the estimated restitution.
    pub c: f64,
    /// RMS of its predictions of `alpha_dot+` and `beta_dot+` minus the estimates (rad/s).
    pub residual_rms: f64,
}

/// The landings' fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LandingFit {
    /// The landings used, in time order.
    pub landings: Vec<LandingEstimate>,
    /// Landings left out: too few samples on a side (a tilt or a flat spell shorter than
    /// [`MIN_SIDE`] samples, the recording's ends).
    pub skipped: usize,
    /// The regressed coefficient `c` in `beta_dot+ = beta_dot- + c alpha_dot-`.
    pub c: f64,
    /// Its standard error.
    pub c_std_error: f64,
    /// The physical law's restitution `e`, as estimated (may be below 0 within its noise).
    pub restitution: f64,
    /// Its standard error.
    pub restitution_std_error: f64,
    /// Landings after which the plate tilted again over the same edge (rebounds).
    pub rebounds: usize,
    /// The restitution that makes the model's next tilt as high as the recorded one
    /// ([`restitution_by_tilts`]): how a compliant contact's landings act on the orbit, where
    /// the landing's own instant is a few milliseconds of spring motion that no sample
    /// resolves. `None` without a landing followed by a recorded tilt.
    pub by_tilts: Option<TiltRestitution>,
    /// The flat spells the contact reports at the landings that pass on into the other tilt
    /// ([`contact_dwell`]); `None` without such a landing.
    pub contact_dwell: Option<ContactDwell>,
    /// The three laws, paper, striking-edge, physical.
    pub laws: Vec<LawFit>,
    /// The law with the smallest residual.
    pub best: ImpactLaw,
}

impl LandingFit {
    /// The best law when the landings tell it from the others: its residual RMS at most
    /// [`DECISIVE`] times every other law's. Under sensor noise (angles only, 1 mrad) the
    /// rates around a landing are too noisy for that (all three laws' residuals within 10 %
    /// of each other on the README's robot) and the prior's law should stay.
    pub fn decisive(&self) -> Option<ImpactLaw> {
        let best = self.laws.iter().find(|l| l.law == self.best)?;
        self.laws
            .iter()
            .filter(|l| l.law != self.best)
            .all(|l| best.residual_rms <= DECISIVE * l.residual_rms)
            .then_some(self.best)
    }

    /// The restitution to write: with rebounds, the rows' estimate in `[0,
    /// MAX_RESTITUTION]`; without, a pass-through the tilts show ([`LandingFit::by_tilts`],
    /// below 0 by more than twice its standard error and [`MIN_PASS_THROUGH`]) in
    /// `[-MAX_RESTITUTION, 0]`; otherwise 0.
    pub fn restitution_written(&self) -> f64 {
        if self.rebounds > 0 && self.restitution.is_finite() {
            return self.restitution.clamp(0.0, MAX_RESTITUTION);
        }
        match &self.by_tilts {
            Some(t) if t.e < -MIN_PASS_THROUGH && t.e + 2.0 * t.std_error < 0.0 => {
                t.e.max(-MAX_RESTITUTION)
            }
            _ => 0.0,
        }
    }

    /// The [`tilting_plant::Params::contact_dwell`] to write (s): with a pass-through written
    /// ([`LandingFit::restitution_written`] below 0), the longest flat spell the contact
    /// reported between two tilts ([`ContactDwell::longest`]); otherwise 0 (a rigid model's
    /// plastic landing is itself flat for a while, and a rebound's stays on its edge).
    pub fn contact_dwell_written(&self) -> f64 {
        match &self.contact_dwell {
            Some(d) if self.restitution_written() < 0.0 => d.longest,
            _ => 0.0,
        }
    }
}

/// The flat spells of a recording's contact sensing at pass-through landings: a tilt, a flat
/// report, and a tilt on the other side within [`tilting_plant::params::MAX_CONTACT_DWELL`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactDwell {
    /// The longest spell (s), from the event into flat to the event out of it, outliers
    /// left out ([`DWELL_OUTLIER`]).
    pub longest: f64,
    /// The spells' mean (s).
    pub mean: f64,
    /// Spells measured (a pass-through with no flat report counts, as 0 s).
    pub spells: usize,
    /// Spells over [`DWELL_OUTLIER`] times the median, left out of `longest` (counted in
    /// `mean` and `spells`).
    pub outliers: usize,
}

/// The flat spells of `events` between a tilt and a tilt on the other side, no longer than
/// [`tilting_plant::params::MAX_CONTACT_DWELL`] (a longer one is the plate at rest, not a
/// landing's spring motion); `None` without one. A compliant contact (MuJoCo's, a real
/// robot's) reports the plate flat for a few milliseconds while it carries it from one edge
/// to the other: both edges bear load. A direct tilt-to-tilt event is a spell of 0 s.
pub fn contact_dwell(events: &[tilting_record::EventRecord]) -> Option<ContactDwell> {
    let max = tilting_plant::params::MAX_CONTACT_DWELL;
    let mut spells = Vec::new();
    for (i, e) in events.iter().enumerate() {
        if e.from == Mode::Flat {
            continue;
        }
        if e.to == e.from.mirrored() {
            spells.push(0.0);
        } else if let Some(n) = events.get(i + 1) {
            let gap = n.t - e.t;
            if e.to == Mode::Flat && n.from == Mode::Flat && n.to == e.from.mirrored() && gap <= max
            {
                spells.push(gap.max(0.0));
            }
        }
    }
    if spells.is_empty() {
        return None;
    }
    // A spell over DWELL_OUTLIER times the median is the plate at rest for a moment, not a
    // landing's spring motion (measured on MuJoCo, a tilting run starved of CPU: 140 spells of
    // 2.5 ms on average and one of 47 ms; taken as the dwell, the controller read 47 ms of
    // flat reports as a tilt and the loop ran 16 % high).
    let mut sorted = spells.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let typical = |d: &&f64| **d <= DWELL_OUTLIER * median.max(MIN_DWELL_SCALE);
    let kept: Vec<f64> = spells.iter().filter(typical).copied().collect();
    Some(ContactDwell {
        longest: kept.iter().copied().fold(0.0, f64::max),
        mean: spells.iter().sum::<f64>() / spells.len() as f64,
        spells: spells.len(),
        outliers: spells.len() - kept.len(),
    })
}

/// A flat spell longer than this many times the median spell is left out of
/// [`ContactDwell::longest`] (one landing in a hundred may hold the plate a moment longer; a
/// real contact's spells vary by less: 1.5 to 2.2 ms on MuJoCo's stiff contact).
pub const DWELL_OUTLIER: f64 = 3.0;
/// The median spell taken as at least this (s) for [`DWELL_OUTLIER`]: with mostly direct
/// pass-throughs (0 s) a rare 1 ms spell is still a landing's.
pub const MIN_DWELL_SCALE: f64 = 0.001;

/// The landings of `trace` and the law they follow, with the identified parameters `p`
/// (their mass matrix predicts each law's `c`); `None` without a usable landing.
/// `tau[k]` is the torque (N m) held over sample `k`'s interval (`None` where unknown).
pub fn fit(trace: &Trace, tau: &[Option<f64>], p: &Params) -> Option<LandingFit> {
    let clusters = clusters(&trace.events);
    let mut landings = Vec::new();
    let mut skipped = 0;
    for c in 0..clusters.len() {
        match one(trace, tau, p, &clusters, c) {
            Some(l) => landings.push(l),
            None => skipped += 1,
        }
    }
    let by_tilts = restitution_by_tilts(trace, tau, p, &landings);
    let mut fit = regress(landings, skipped, p)?;
    fit.by_tilts = by_tilts;
    fit.contact_dwell = contact_dwell(&trace.events);
    Some(fit)
}

/// A restitution estimated from the tilts that follow the landings ([`restitution_by_tilts`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TiltRestitution {
    /// The mean of the landings' restitutions (1): below 0, the plate passes on into the next
    /// tilt.
    pub e: f64,
    /// Its standard error (the landings' spread over the root of their number).
    pub std_error: f64,
    /// Landings whose restitution was found.
    pub landings: usize,
}

/// The smallest pass-through [`LandingFit::restitution_written`] writes: below it the
/// physical law's threshold (a striking edge leaving slower than 1 cm/s is plastic) makes
/// the orbit's landings plastic anyway.
pub const MIN_PASS_THROUGH: f64 = 0.02;

/// A landing's next tilt as the model runs it: from the state just before the landing
/// (`alpha = 0`), the physical law with restitution `e`, the recorded torques held over their
/// sample intervals up to `t_next` (s). The largest `|alpha|` (rad) of the motion.
fn next_peak(
    trace: &Trace,
    tau: &[Option<f64>],
    p: &Params,
    l: &LandingEstimate,
    t_next: f64,
    e: f64,
) -> Option<f64> {
    use tilting_plant::{Observer, Plant, SimConfig, TiltPeak};
    struct Peak(f64);
    impl Observer for Peak {
        fn tilt_peak(&mut self, p: &TiltPeak) {
            self.0 = self.0.max(p.alpha.abs());
        }
    }
    let params = Params {
        impact: ImpactLaw::Physical,
        restitution: e,
        ..*p
    };
    let cfg = SimConfig {
        params,
        impact: ImpactLaw::Physical,
        ..SimConfig::default()
    };
    let x0 = State::new(0.0, l.beta, l.before[0], l.before[1]);
    let mut plant = Plant::new(cfg, l.t, l.from, x0).ok()?;
    let s = &trace.samples;
    let mut k = s.partition_point(|x| x.t <= l.t).checked_sub(1)?;
    let mut obs = Peak(0.0);
    while k + 1 < s.len() && s[k].t < t_next {
        let u = tau.get(k).copied().flatten()?;
        plant
            .advance_held(u, s[k + 1].t.min(t_next), &mut obs)
            .ok()?;
        k += 1;
    }
    let open = plant.peak_in_progress().map_or(0.0, |p| p.alpha.abs());
    Some(obs.0.max(open))
}

/// The restitution of the physical law that makes the model's next tilt after each landing as
/// high as the recorded one: for each landing followed by a recorded tilt before the next
/// landing, the root in `e` of (model's peak - recorded peak) by the secant method from 0 and
/// -0.1 ([`next_peak`]: the model started from the state just before the landing, the
/// recorded torques replayed), to 0.1 % of the peak; the mean over the landings with a root in
/// `(-0.95, 0.95)`. Where a contact is compliant its landing takes a few milliseconds of spring
/// motion between two samples, and the state just after it cannot be read off the samples
/// (its estimate scatters with the landing's phase in the sample period); the next tilt,
/// which the rigid model follows, can.
pub fn restitution_by_tilts(
    trace: &Trace,
    tau: &[Option<f64>],
    p: &Params,
    landings: &[LandingEstimate],
) -> Option<TiltRestitution> {
    let s = &trace.samples;
    let mut es = Vec::new();
    for (i, l) in landings.iter().enumerate() {
        if l.before[0].abs() < MIN_SPEED {
            continue;
        }
        let t_next = landings.get(i + 1).map_or(trace.end, |n| n.t);
        let recorded = s
            .iter()
            .filter(|x| x.t > l.t && x.t < t_next && x.mode != Mode::Flat)
            .map(|x| x.x[0].abs())
            .fold(0.0, f64::max);
        if recorded < 10.0 * MIN_SPEED {
            continue;
        }
        let g = |e: f64| next_peak(trace, tau, p, l, t_next, e).map(|m| m - recorded);
        let (mut e0, mut e1) = (0.0, -0.1);
        let (Some(mut g0), Some(mut g1)) = (g(e0), g(e1)) else {
            continue;
        };
        let mut found = None;
        for _ in 0..12 {
            if g1.abs() <= 1e-3 * recorded {
                found = Some(e1);
                break;
            }
            if g1 == g0 {
                break;
            }
            let e2 = (e1 - g1 * (e1 - e0) / (g1 - g0)).clamp(-0.95, 0.95);
            let Some(g2) = g(e2) else { break };
            (e0, g0, e1, g1) = (e1, g1, e2, g2);
        }
        if let Some(e) = found.filter(|e| e.abs() < 0.95) {
            es.push(e);
        }
    }
    if es.is_empty() {
        return None;
    }
    let n = es.len() as f64;
    let mean = es.iter().sum::<f64>() / n;
    let var = es.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    Some(TiltRestitution {
        e: mean,
        std_error: (var / n).sqrt(),
        landings: es.len(),
    })
}

/// The landings of `events`: the events at one instant (a landing and a tilt at once) as
/// `(t, from, to)`, the first leaving a tilted mode for flat.
fn clusters(ev: &[tilting_record::EventRecord]) -> Vec<(f64, Mode, Mode)> {
    let mut clusters: Vec<(f64, Mode, Mode)> = Vec::new();
    let mut i = 0;
    while i < ev.len() {
        let mut j = i;
        while j + 1 < ev.len() && ev[j + 1].t - ev[i].t <= 1e-9 {
            j += 1;
        }
        if ev[i].from != Mode::Flat && ev[i].to == Mode::Flat {
            clusters.push((ev[i].t, ev[i].from, ev[j].to));
        }
        i = j + 1;
    }
    clusters
}

/// The landing `c` of `clusters` estimated from the samples on each side (`None` when a side
/// has too few samples).
fn one(
    trace: &Trace,
    tau: &[Option<f64>],
    p: &Params,
    clusters: &[(f64, Mode, Mode)],
    c: usize,
) -> Option<LandingEstimate> {
    let s = &trace.samples;
    let (te, from, to) = clusters[c];
    let (before, after) = side_samples(trace, clusters, c)?;
    let pre = |t: f64| side(trace, &before, t);
    // The landing instant: the root of alpha before, between the samples around the event.
    let (t_lo, t_hi) = (s[before[0]].t, s[after[0]].t);
    let mut tl = te;
    if let Some(poly) = pre(te) {
        let root = newton_root(&poly, te, t_lo, t_hi);
        if let Some(r) = root {
            tl = r;
        }
    }
    let (Some(mut b), Some(mut a)) = (pre(tl), side(trace, &after, tl)) else {
        return None;
    };
    if let Some(u) = tau.get(before[0]).copied().flatten() {
        tl = carry_to_landing(p, from, &s[before[0]], u, tl, t_hi, &mut b);
    }
    let k_int = s.partition_point(|x| x.t <= tl).saturating_sub(1);
    if let Some(u) = tau.get(k_int).copied().flatten() {
        back_to_landing(trace, &after, p, to, u, tl, &mut a);
    }
    let (ad, bd) = (b.d[0], b.d[1]);
    // The plate leaves the landing at rest unless it rebounds over the same edge, or passes
    // on over the striking edge into the other tilt at the same instant (the physical law's
    // pass-through; a plastic land-and-tilt starts that tilt from alpha_dot = 0, which the
    // side after then shows); a flat spell first: at rest (a polynomial through a flat spell
    // and a tilt's start would only blur that).
    let ad1 = if to == Mode::Flat { 0.0 } else { a.d[0] };
    let bd1 = a.d[1];
    let fast = ad.abs() >= MIN_SPEED;
    Some(LandingEstimate {
        t: tl,
        from,
        to,
        beta: 0.5 * (b.v[1] + a.v[1]),
        before: [ad, bd],
        after: [ad1, bd1],
        c: fast.then(|| (bd1 - bd) / ad),
        e: fast.then(|| -ad1 / ad),
    })
}

/// The indices of the samples on each side of landing `c` of `clusters`: strictly before the
/// event in its tilt, latest first, and strictly after it up to the next landing, at most
/// `SIDE` each (`SIDE_RATES` where the last sample before records its rates); `None` when a
/// side has fewer than `MIN_SIDE`.
fn side_samples(
    trace: &Trace,
    clusters: &[(f64, Mode, Mode)],
    c: usize,
) -> Option<(Vec<usize>, Vec<usize>)> {
    let s = &trace.samples;
    let (te, from, _) = clusters[c];
    let prev = if c > 0 {
        clusters[c - 1].0
    } else {
        f64::NEG_INFINITY
    };
    let next = clusters.get(c + 1).map_or(f64::INFINITY, |n| n.0);
    let k = s.partition_point(|x| x.t < te);
    let rates = s
        .get(k.saturating_sub(1))
        .is_some_and(|x| x.x[3].is_finite());
    let most = if rates { SIDE_RATES } else { SIDE };
    let before: Vec<usize> = (0..k)
        .rev()
        .take_while(|&i| s[i].mode == from && s[i].t > prev)
        .take(most)
        .collect();
    let start = s[k..].iter().position(|x| x.t > te).map(|d| k + d);
    let after: Vec<usize> = start.map_or(Vec::new(), |a| {
        (a..s.len())
            .take_while(|&i| s[i].t < next)
            .take(most)
            .collect()
    });
    if before.len() < MIN_SIDE || after.len() < MIN_SIDE {
        return None;
    }
    Some((before, after))
}

/// The side before `b` where the last sample before the landing, `last`, records its rates:
/// its state carried forward in the tilt `from` under its held torque `u` (N m) to
/// `alpha = 0` (two Newton steps on the landing instant from `tl`, s). Returns the landing
/// instant (s): the carried one where it falls between `last` and the first sample after
/// (`t_after`, s), with `b` set to the carried state, else `tl` with `b` kept.
fn carry_to_landing(
    p: &Params,
    from: Mode,
    last: &tilting_record::Sample,
    u: f64,
    tl: f64,
    t_after: f64,
    b: &mut Side,
) -> f64 {
    if !last.x.iter().all(|v| v.is_finite()) {
        return tl;
    }
    let mut t = tl;
    let mut x = integrate(p, from, last.x, u, t - last.t);
    for _ in 0..2 {
        if x[2] != 0.0 {
            t -= x[0] / x[2];
            x = integrate(p, from, last.x, u, t - last.t);
        }
    }
    if x.iter().all(|v| v.is_finite()) && t > last.t && t < t_after {
        b.v = [x[0], x[1]];
        b.d = [x[2], x[3]];
        return t;
    }
    tl
}

/// The side after `a` over the partial interval from the landing (at `tl`, s) to the first
/// sample after it (`after[0]`), where that sample is in the new mode `to`: the torque held
/// there, `u` (N m), is the one before the landing, in the new mode's dynamics, while the
/// polynomial carries the next intervals' (the controller answers the new mode at the next
/// sample: measured 1.2 % of the jump off on the paper's orbit). So the state at that sample is
/// integrated back to the landing instant under the held torque with the parameters `p`;
/// `a` is kept where that is not finite.
fn back_to_landing(
    trace: &Trace,
    after: &[usize],
    p: &Params,
    to: Mode,
    u: f64,
    tl: f64,
    a: &mut Side,
) {
    let first = &trace.samples[after[0]];
    if first.mode != to {
        return;
    }
    // The sample itself where its rates are recorded (a polynomial through the next
    // samples spans the torque's jump there: on the paper's orbit the plate rests
    // until the next sample, whose torque tips it).
    let recorded = first.x.iter().all(|v| v.is_finite()).then_some(first.x);
    let fitted = || side(trace, after, first.t).map(|a| [a.v[0], a.v[1], a.d[0], a.d[1]]);
    if let Some(x) = recorded.or_else(fitted) {
        let x = if to == Mode::Flat {
            [0.0, x[1], 0.0, x[3]]
        } else {
            x
        };
        let back = integrate(p, to, x, u, tl - first.t);
        if back.iter().all(|v| v.is_finite()) {
            a.v = [back[0], back[1]];
            a.d = [back[2], back[3]];
        }
    }
}

/// The law the landings follow: `c` by regression, the physical law's `e`, each law's
/// residual, the best.
fn regress(landings: Vec<LandingEstimate>, skipped: usize, p: &Params) -> Option<LandingFit> {
    if landings.is_empty() {
        return None;
    }
    let n = landings.len();
    let (mut saa, mut sad) = (0.0, 0.0);
    for l in &landings {
        let (a, d) = (l.before[0], l.after[1] - l.before[1]);
        saa += a * a;
        sad += a * d;
    }
    if saa <= 0.0 {
        return None;
    }
    let c = sad / saa;
    let rss_c: f64 = landings
        .iter()
        .map(|l| (l.after[1] - l.before[1] - c * l.before[0]).powi(2))
        .sum();
    let c_std_error = (rss_c / (n.max(2) - 1) as f64 / saa).sqrt();
    // The physical law's e: rows r = -e a and d - k a = e k a.
    let k = |l: &LandingEstimate| {
        let (_, m12, m22) = mass_matrix(p, l.from, l.beta);
        m12 / m22
    };
    let (mut sxx, mut sxy) = (0.0, 0.0);
    let rows: Vec<[(f64, f64); 2]> = landings
        .iter()
        .map(|l| {
            let (a, d, r, k) = (l.before[0], l.after[1] - l.before[1], l.after[0], k(l));
            [(-a, r), (k * a, d - k * a)]
        })
        .collect();
    for &(x, y) in rows.iter().flatten() {
        sxx += x * x;
        sxy += x * y;
    }
    let e = sxy / sxx;
    let rss_e: f64 = rows
        .iter()
        .flatten()
        .map(|(x, y)| (y - e * x).powi(2))
        .sum();
    let restitution_std_error = (rss_e / (2 * n - 1) as f64 / sxx).sqrt();
    let laws: Vec<LawFit> = [
        ImpactLaw::Paper,
        ImpactLaw::StrikingEdge,
        ImpactLaw::Physical,
    ]
    .into_iter()
    .map(|law| {
        let (mut rss, mut cw) = (0.0, 0.0);
        for l in &landings {
            let (a, bd, ad1, bd1) = (l.before[0], l.before[1], l.after[0], l.after[1]);
            let (cl, r) = match law {
                ImpactLaw::Physical => ((1.0 + e) * k(l), -e * a),
                _ => (law.coefficient(p, l.from, l.beta), 0.0),
            };
            rss += (ad1 - r).powi(2) + (bd1 - bd - cl * a).powi(2);
            cw += cl * a * a;
        }
        LawFit {
            law,
            c: cw / saa,
            residual_rms: (rss / (2 * n) as f64).sqrt(),
        }
    })
    .collect();
    let best = laws
        .iter()
        .filter(|l| l.residual_rms.is_finite())
        .min_by(|a, b| a.residual_rms.total_cmp(&b.residual_rms))
        .map_or(p.impact, |l| l.law);
    let rebounds = landings
        .iter()
        .filter(|l| l.to == l.from && l.after[0] * l.before[0] < 0.0)
        .count();
    Some(LandingFit {
        landings,
        skipped,
        c,
        c_std_error,
        restitution: e,
        restitution_std_error,
        rebounds,
        by_tilts: None,
        contact_dwell: None,
        laws,
        best,
    })
}

/// A law is told from the others when its residual RMS is at most this share of theirs: on
/// clean recordings the law a run was made with fits 1e-7 of the others' residuals or better.
pub const DECISIVE: f64 = 0.5;

/// The state `x` of mode `mode` carried over `dt` s (negative: backwards) under the torque
/// `u` with the parameters `p`: classical Runge-Kutta, eight steps (a partial sample interval:
/// the local error is far below the fits').
fn integrate(p: &Params, mode: Mode, x: [f64; 4], u: f64, dt: f64) -> [f64; 4] {
    let f = |x: &[f64; 4]| {
        let (add, bdd) = accelerations(p, mode, &State::new(x[0], x[1], x[2], x[3]), u);
        [x[2], x[3], add, bdd]
    };
    let n = 8;
    let h = dt / n as f64;
    let mut x = x;
    for _ in 0..n {
        let add = |x: &[f64; 4], k: &[f64; 4], c: f64| std::array::from_fn(|i| x[i] + c * k[i]);
        let k1 = f(&x);
        let k2 = f(&add(&x, &k1, 0.5 * h));
        let k3 = f(&add(&x, &k2, 0.5 * h));
        let k4 = f(&add(&x, &k3, h));
        x = std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
    }
    x
}

/// A side's local fit evaluated at an instant: the angles and their rates.
struct Side {
    /// `(alpha, beta)` (rad).
    v: [f64; 2],
    /// `(alpha_dot, beta_dot)` (rad/s).
    d: [f64; 2],
    /// `alpha`'s polynomial coefficients in `u = (t - t0) / scale` and the `(t0, scale)`.
    alpha: (Vec<f64>, f64, f64),
}

/// The local polynomials of the samples `idx` of `trace` evaluated at `t`: angles always, the
/// recorded rates where finite (weighted by the window's span, so both rows are in rad).
fn side(trace: &Trace, idx: &[usize], t: f64) -> Option<Side> {
    let s = &trace.samples;
    let deg = if idx.len() >= 10 { DEGREE } else { 2 };
    let deg = deg.min(idx.len().saturating_sub(2)).max(1);
    let ts: Vec<f64> = idx.iter().map(|&i| s[i].t).collect();
    let span = ts
        .iter()
        .map(|x| (x - t).abs())
        .fold(0.0, f64::max)
        .max(1e-6);
    let mut v = [0.0; 2];
    let mut d = [0.0; 2];
    let mut alpha = Vec::new();
    for q in 0..2 {
        let mut rows: Vec<Vec<f64>> = Vec::new();
        let mut rhs = Vec::new();
        for &i in idx {
            let u = (s[i].t - t) / span;
            rows.push((0..=deg).map(|j| u.powi(j as i32)).collect());
            rhs.push(s[i].x[q]);
            let rate = s[i].x[q + 2];
            if rate.is_finite() {
                rows.push(
                    (0..=deg)
                        .map(|j| {
                            if j == 0 {
                                0.0
                            } else {
                                j as f64 * u.powi(j as i32 - 1)
                            }
                        })
                        .collect(),
                );
                rhs.push(rate * span);
            }
        }
        let a = DMatrix::from_fn(rows.len(), deg + 1, |r, c| rows[r][c]);
        let b = DVector::from_column_slice(&rhs);
        let x = a.svd(true, true).solve(&b, 1e-14).ok()?;
        if !x.iter().all(|c| c.is_finite()) {
            return None;
        }
        v[q] = x[0];
        d[q] = x[1] / span;
        if q == 0 {
            alpha = x.iter().copied().collect();
        }
    }
    Some(Side {
        v,
        d,
        alpha: (alpha, t, span),
    })
}

/// The root of the side's `alpha` polynomial nearest `t0` by Newton's method, if it lies in
/// `[lo, hi]`.
fn newton_root(side: &Side, t0: f64, lo: f64, hi: f64) -> Option<f64> {
    let (c, tc, span) = (&side.alpha.0, side.alpha.1, side.alpha.2);
    let mut u = (t0 - tc) / span;
    for _ in 0..50 {
        let (mut f, mut df) = (0.0, 0.0);
        for (j, cj) in c.iter().enumerate() {
            f += cj * u.powi(j as i32);
            if j > 0 {
                df += j as f64 * cj * u.powi(j as i32 - 1);
            }
        }
        if df == 0.0 || !df.is_finite() {
            return None;
        }
        let du = f / df;
        u -= du;
        if du.abs() < 1e-14 {
            break;
        }
    }
    let t = tc + u * span;
    (t.is_finite() && t >= lo && t <= hi).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilting_record::{EventRecord, Sample};

    /// A landing between two samples, synthesised from closed forms: quadratic angles on each
    /// side meeting at `t_l = 0.0203` (not a sample time), the jump of a known law. The
    /// extrapolated rates are the closed forms' (1e-9: the polynomials are exact for
    /// quadratics) and the landing instant is found from `alpha`'s root (1e-12), not taken
    /// from the event's time (here a sample's, as a debounced robot may report it).
    #[test]
    fn a_landing_between_samples_is_extrapolated_to_its_instant() {
        let p = Params::default();
        let tl = 0.0203;
        let (a0, b0, bb) = (-0.2, 0.5, 1.5);
        let c = ImpactLaw::Physical.coefficient(&p, Mode::Left, bb);
        let b1 = b0 + c * a0;
        let mut samples = Vec::new();
        for k in 0..=40 {
            let t = k as f64 * 1e-3;
            let dt = t - tl;
            let (mode, x) = if t < tl {
                (
                    Mode::Left,
                    [
                        a0 * dt + 3.0 * dt * dt,
                        bb + b0 * dt + 2.0 * dt * dt,
                        f64::NAN,
                        f64::NAN,
                    ],
                )
            } else {
                (
                    Mode::Flat,
                    [0.0, bb + b1 * dt - 1.0 * dt * dt, f64::NAN, f64::NAN],
                )
            };
            samples.push(Sample { t, mode, x });
        }
        let trace = Trace {
            samples,
            events: vec![EventRecord {
                t: 0.021,
                from: Mode::Left,
                to: Mode::Flat,
                x_before: [0.0; 4],
                x_after: [0.0; 4],
            }],
            end: 0.04,
            stopped_early: false,
        };
        // The event is reported at the sample after the landing: the sides are the samples
        // strictly before and after it.
        let f = fit(&trace, &[None; 41], &p).expect("one landing");
        let l = &f.landings[0];
        assert!((l.t - tl).abs() < 1e-12, "{}", l.t);
        for (got, want) in [
            (l.before[0], a0),
            (l.before[1], b0),
            (l.after[1], b1),
            (l.after[0], 0.0),
        ] {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        assert!((f.c - c).abs() < 1e-8);
        assert_eq!(f.best, ImpactLaw::Physical);
        assert!(f.restitution.abs() < 1e-8, "{}", f.restitution);
    }

    /// The contact's flat spells between two tilts, from events written by hand: the spells
    /// are the gaps between the events into and out of flat, a direct pass-through is 0 s,
    /// and spells that are not between opposite tilts (a rebound over the same edge, the plate
    /// at rest longer than 50 ms, a flat start) are left out.
    #[test]
    fn contact_dwell_is_the_flat_spell_between_opposite_tilts() {
        let ev = |t: f64, from: Mode, to: Mode| EventRecord {
            t,
            from,
            to,
            x_before: [0.0; 4],
            x_after: [0.0; 4],
        };
        let (l, r, f) = (Mode::Left, Mode::Right, Mode::Flat);
        let events = [
            ev(0.10, f, l),   // a flat start: not a spell
            ev(0.5004, l, f), // 1.6 ms into the right tilt
            ev(0.5020, f, r),
            ev(1.0000, r, f), // 2.0 ms into the left tilt
            ev(1.0020, f, l),
            ev(1.5000, l, r), // a direct pass-through: 0 s
            ev(2.0000, r, f), // a rebound over the same edge: not one
            ev(2.0010, f, r),
            ev(2.5000, r, f), // flat for 0.1 s: at rest, not one
            ev(2.6000, f, l),
        ];
        let d = contact_dwell(&events).unwrap();
        assert_eq!((d.spells, d.outliers), (3, 0));
        assert!((d.longest - 0.002).abs() < 1e-12, "{d:?}");
        assert!((d.mean - (0.0016 + 0.002) / 3.0).abs() < 1e-12, "{d:?}");
        assert!(contact_dwell(&events[6..]).is_none());

        // Ten landings of 1.5-2.4 ms and one 40 ms rest between opposite tilts: the rest is an
        // outlier (over 3 x the 2.0 ms median), the longest landing spell is 2.4 ms.
        let mut events = Vec::new();
        let mut side = l;
        for (i, ms) in [1.5, 1.6, 1.8, 2.0, 2.0, 2.1, 2.2, 2.4, 40.0, 1.9, 2.0]
            .iter()
            .enumerate()
        {
            let t = 0.5 * (i + 1) as f64;
            events.push(ev(t, side, f));
            side = side.mirrored();
            events.push(ev(t + ms * 1e-3, f, side));
        }
        let d = contact_dwell(&events).unwrap();
        assert_eq!((d.spells, d.outliers), (11, 1), "{d:?}");
        assert!((d.longest - 0.0024).abs() < 1e-12, "{d:?}");
        // Mostly direct pass-throughs (median 0 s): a 1 ms spell is still a landing's, a 4 ms
        // one is not (the median is taken as at least 1 ms).
        let mut events = vec![ev(0.5, l, r), ev(1.0, r, l), ev(1.5, l, r), ev(2.0, r, f)];
        events.extend([ev(2.001, f, l), ev(2.5, l, f), ev(2.504, f, r)]);
        let d = contact_dwell(&events).unwrap();
        assert_eq!((d.spells, d.outliers), (5, 1), "{d:?}");
        assert!((d.longest - 0.001).abs() < 1e-12, "{d:?}");
    }
}
