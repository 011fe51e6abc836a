//! Side-by-side benchmark: the plant's own DOP853 with event location (`tilting_plant::Plant`)
//! against `diffsol` 0.18 (closures on nalgebra, its explicit RK `tsit45` and, for the passive
//! landing only, its implicit `bdf`, `esdirk34` and `tr_bdf2`), on the tilting system:
//! 1. a passive tilt to the first landing (plus a work-precision sweep);
//! 2. the controlled k = 500 orbit over 20 s, torque law inside the right-hand side, in one
//!    call and in 1 ms pieces;
//! 3. the same orbit under a 1 kHz zero-order hold (the networked plant's setting).
//!
//! Results and the decision: `bench/decisions-2026-11-28.md`, "Integrator: own DOP853 vs diffsol".
//!
//! Not part of the workspace (CI never builds diffsol): it has its own `[workspace]` table.
//! Run by hand: `cd bench/diffsol-compare && cargo run --release` (build about 1 to 2.5 min on
//! 2 cores, run under 10 s).
//!
//! Fairness rules: the same `rtol`/`atol` for both (the plant's default `Tolerance`);
//! right-hand-side evaluations counted by a counter inside the closure (for ours: inside the
//! torque law, which the plant calls exactly once per right-hand-side evaluation); the same
//! right-hand-side code (one `Terms` shared between the torque law and the accelerations, as
//! inside `Plant`); wall times are medians of repeated runs and include the set-up (building
//! the problem and the solver, initial step selection).

use std::cell::Cell;
use std::f64::consts::FRAC_PI_2;
use std::time::Instant;

use diffsol::{
    NalgebraLU, NalgebraMat, OdeBuilder, OdeEquations, OdeSolverMethod, OdeSolverStopReason,
};
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec};
use tilting_plant::dynamics::{accelerations_t, vertical_force, Terms};
use tilting_plant::ode::Dop853;
use tilting_plant::{
    ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, Tolerance, TorqueLaw, Transition,
};

type M = NalgebraMat<f64>;
type LS = NalgebraLU<f64>;

/// The tolerances of the comparison: the plant's defaults (`Tolerance::default()`).
fn tol() -> Tolerance {
    Tolerance::default()
}
/// The reference: our DOP853 at much tighter tolerances.
const REF_TOL: Tolerance = Tolerance {
    rtol: 1e-13,
    atol: 1e-15,
};

// ---------------------------------------------------------------------------------------------
// Shared pieces
// ---------------------------------------------------------------------------------------------

/// The right-hand side exactly as `Plant` evaluates it: one `Terms` (sines, cosines, mass
/// matrix, bias) shared by the torque law and the accelerations.
#[inline]
fn flow<L: TorqueLaw>(p: &Params, law: &L, mode: Mode, t: f64, x: &State) -> State {
    let tm = Terms::new(p, mode, x);
    let tau = law.torque_t(t, mode, x, p, &tm);
    let (add, bdd) = accelerations_t(p, mode, &tm, tau);
    State::new(x[2], x[3], add, bdd)
}

fn st(x: &[f64]) -> State {
    State::new(x[0], x[1], x[2], x[3])
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Median wall time (s) of `n` runs of `f`.
fn time_median<R>(n: usize, mut f: impl FnMut() -> R) -> f64 {
    let mut v = Vec::with_capacity(n);
    for _ in 0..n {
        let t0 = Instant::now();
        std::hint::black_box(f());
        v.push(t0.elapsed().as_secs_f64());
    }
    median(v)
}

/// Records every transition.
#[derive(Default)]
struct Log(Vec<Transition>);

impl Observer for Log {
    fn transition(&mut self, ev: &Transition) {
        self.0.push(*ev);
    }
}

/// Outcome of one integration to the first landing.
#[derive(Debug, Clone, Copy)]
struct Landing {
    t: f64,
    x: State,
    evals: u64,
    /// Extra right-hand-side evaluations spent in finite-difference Jacobian-vector products
    /// (implicit diffsol methods only).
    jac_evals: u64,
    steps: usize,
}

// ---------------------------------------------------------------------------------------------
// 1. Passive tilting to the first landing
// ---------------------------------------------------------------------------------------------

/// The brief's start. With tau = 0 from rest the pivot force dips below zero before the plate
/// lands (here at t = 0.104 s; from every start angle tried, 0.01 to 0.3 rad), so `Plant` stops with a
/// contact-loss fault: this problem is run as the pure left-tilt ODE with the event alpha = 0,
/// on both sides, with our stepper and root finder called directly.
const A0_ODE: f64 = 0.3;

fn x0_passive(a0: f64) -> State {
    State::new(a0, FRAC_PI_2, 0.0, 0.0)
}

/// Ours on the pure ODE: the DOP853 stepper, a dense output only for the step that contains a
/// sign change, and the same Illinois root finder as `Plant` (its `hybrid::locate` is private:
/// [`locate`] below is a copy).
fn ours_passive_ode(tol: Tolerance, event_tol: f64) -> Landing {
    let p = Params::default();
    let n = Cell::new(0u64);
    let zero = |_t: f64, _m: Mode, _x: &State| 0.0;
    let mut f = |t: f64, x: &State| {
        n.set(n.get() + 1);
        flow(&p, &zero, Mode::Left, t, x)
    };
    let mut stepper = Dop853::new(tol);
    let (mut t, mut x) = (0.0, x0_passive(A0_ODE));
    let mut f0 = f(t, &x);
    let mut g0 = x[0];
    loop {
        let s = stepper.step(&mut f, t, &x, &f0, 10.0).unwrap();
        let g1 = s.y1[0];
        if g0 > 0.0 && g1 <= 0.0 {
            let d = stepper.dense(&mut f, &s);
            let tr = locate(&|t| d.eval(t)[0], s.t0, g0, s.t1, g1, event_tol);
            return Landing {
                t: tr,
                x: d.eval(tr),
                evals: n.get(),
                jac_evals: 0,
                steps: stepper.stats.steps as usize,
            };
        }
        assert!(s.t1 < 10.0, "no landing");
        (t, x, f0, g0) = (s.t1, s.y1, *s.f1(), g1);
    }
}

use tilting_plant::hybrid::locate;

/// Steps a diffsol solver until its first root (alpha = 0) and reads the state there from its
/// interpolant.
fn first_root<'a, Eqn, S>(s: &mut S) -> (f64, State)
where
    Eqn: OdeEquations<T = f64, V = diffsol::NalgebraVec<f64>> + 'a,
    S: OdeSolverMethod<'a, Eqn>,
{
    loop {
        match s.step().expect("diffsol step") {
            OdeSolverStopReason::RootFound(t, _) => {
                let y = s.interpolate(t).unwrap();
                return (t, State::new(y[0], y[1], y[2], y[3]));
            }
            _ => assert!(s.state().t < 10.0, "no landing"),
        }
    }
}

/// diffsol's explicit `tsit45` (the only explicit RK tableau it ships).
fn diffsol_passive_tsit45(a0: f64, rtol: f64, atol: f64) -> Landing {
    let p = Params::default();
    let n = Cell::new(0u64);
    let zero = |_t: f64, _m: Mode, _x: &State| 0.0;
    let problem = OdeBuilder::<M>::new()
        .rtol(rtol)
        .atol([atol])
        .rhs(|x, _p, t, y| {
            n.set(n.get() + 1);
            y.copy_from_slice(flow(&p, &zero, Mode::Left, t, &st(x)).as_slice());
        })
        .init(|_p, _t, y| y.copy_from_slice(x0_passive(a0).as_slice()), 4)
        .root(|x, _p, _t, g| g[0] = x[0], 1)
        .build()
        .unwrap();
    let mut s = problem.tsit45().unwrap();
    let (t, x) = first_root(&mut s);
    let steps = s.get_statistics().number_of_steps;
    Landing {
        t,
        x,
        evals: n.get(),
        jac_evals: 0,
        steps,
    }
}

/// diffsol's implicit methods need a Jacobian-vector product: a forward difference, whose
/// right-hand-side evaluations are counted separately.
#[derive(Clone, Copy, Debug)]
enum Implicit {
    Bdf,
    Esdirk34,
    TrBdf2,
}

fn diffsol_passive_implicit(method: Implicit, a0: f64, rtol: f64, atol: f64) -> Landing {
    let p = Params::default();
    let n = Cell::new(0u64);
    let nj = Cell::new(0u64);
    let zero = |_t: f64, _m: Mode, _x: &State| 0.0;
    let f = |t: f64, x: &State| flow(&p, &zero, Mode::Left, t, x);
    let problem = OdeBuilder::<M>::new()
        .rtol(rtol)
        .atol([atol])
        .rhs_implicit(
            |x, _p, t, y| {
                n.set(n.get() + 1);
                y.copy_from_slice(f(t, &st(x)).as_slice());
            },
            |x, _p, t, v, y| {
                nj.set(nj.get() + 2);
                let (x, v) = (st(x), st(v));
                let vn = v.norm();
                if vn == 0.0 {
                    y.fill(0.0);
                    return;
                }
                let h = 1e-8 * (1.0 + x.norm()) / vn;
                let d = (f(t, &(x + v * h)) - f(t, &x)) / h;
                y.copy_from_slice(d.as_slice());
            },
        )
        .init(|_p, _t, y| y.copy_from_slice(x0_passive(a0).as_slice()), 4)
        .root(|x, _p, _t, g| g[0] = x[0], 1)
        .build()
        .unwrap();
    let (t, x, steps) = match method {
        Implicit::Bdf => {
            let mut s = problem.bdf::<LS>().unwrap();
            let (t, x) = first_root(&mut s);
            (t, x, s.get_statistics().number_of_steps)
        }
        Implicit::Esdirk34 => {
            let mut s = problem.esdirk34::<LS>().unwrap();
            let (t, x) = first_root(&mut s);
            (t, x, s.get_statistics().number_of_steps)
        }
        Implicit::TrBdf2 => {
            let mut s = problem.tr_bdf2::<LS>().unwrap();
            let (t, x) = first_root(&mut s);
            (t, x, s.get_statistics().number_of_steps)
        }
    };
    Landing {
        t,
        x,
        evals: n.get(),
        jac_evals: nj.get(),
        steps,
    }
}

// ---------------------------------------------------------------------------------------------
// 2. The controlled orbit over 20 s
// ---------------------------------------------------------------------------------------------

const T_END: f64 = 20.0;

fn controller() -> ComputedTorque {
    ComputedTorque::new(ControlConfig {
        law: LawSpec {
            kp: 100.0,
            kd: 14.14,
            k: 500.0,
            energy_avg: 19.958_818_058_0,
            ..LawSpec::without_adaptation()
        },
        ..ControlConfig::default()
    })
    .unwrap()
}

fn x0_orbit() -> State {
    State::new(0.0, FRAC_PI_2 - 0.000_214_877_415, 0.0, 0.498_257_789_686)
}

/// A torque law that counts its calls: the plant calls it once per right-hand-side evaluation
/// (and once per landing for the flat-mode support check, which evaluates the right-hand side
/// too).
struct Counted<'a, L> {
    law: L,
    n: &'a Cell<u64>,
}

impl<L: TorqueLaw> TorqueLaw for Counted<'_, L> {
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        self.n.set(self.n.get() + 1);
        self.law.torque(t, mode, x)
    }
    fn torque_t(&self, t: f64, mode: Mode, x: &State, p: &Params, terms: &Terms) -> f64 {
        self.n.set(self.n.get() + 1);
        self.law.torque_t(t, mode, x, p, terms)
    }
}

/// Outcome of one orbit run.
#[derive(Debug, Clone)]
struct OrbitRun {
    /// Landing times (s).
    landings: Vec<f64>,
    /// State at T_END.
    x_end: State,
    mode_end: Mode,
    evals: u64,
    steps: usize,
    /// Did every landing go straight into the other tilt at the same instant?
    alternates: bool,
}

/// Ours: `Plant::advance_continuous`, either in one call to T_END or in `chunk`-second pieces
/// (a lockstep loop with a sample period `chunk`).
fn ours_orbit(tol: Tolerance, chunk: Option<f64>, x0: State) -> OrbitRun {
    let n = Cell::new(0u64);
    let law = Counted {
        law: controller(),
        n: &n,
    };
    let cfg = SimConfig {
        tol,
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let mut log = Log::default();
    match chunk {
        None => plant.advance_continuous(&law, T_END, &mut log).unwrap(),
        Some(dt) => {
            let k_end = (T_END / dt).round() as u64;
            for k in 1..=k_end {
                plant
                    .advance_continuous(&law, k as f64 * dt, &mut log)
                    .unwrap();
            }
        }
    }
    // Landings, and the check that each one is followed at once by the mirrored tilt.
    let mut landings = Vec::new();
    let mut alternates = true;
    for w in log.0.chunks(2) {
        let land = w[0];
        landings.push(land.t);
        alternates &= land.to == Mode::Flat && land.from.is_tilted();
        if let Some(tilt) = w.get(1) {
            alternates &=
                tilt.from == Mode::Flat && tilt.to == land.from.mirrored() && tilt.t == land.t;
        }
    }
    OrbitRun {
        landings,
        x_end: plant.state(),
        mode_end: plant.mode(),
        evals: n.get(),
        steps: plant.stats().steps as usize,
        alternates,
    }
}

/// diffsol (`tsit45`): stop at each root of alpha, move the state back to the root, apply the
/// impact map, restart in the mirrored tilt. Simplification: the flat-mode ZMP check after a
/// landing is replaced by "next mode = the other tilt", which is what happens on this orbit
/// (`ours_orbit` checks it). `chunk` as in `ours_orbit`, with `set_stop_time` at each sample.
fn diffsol_orbit(rtol: f64, atol: f64, chunk: Option<f64>) -> OrbitRun {
    let p = Params::default();
    let ctrl = controller();
    let mode = Cell::new(Mode::Left);
    let n = Cell::new(0u64);
    let f = |t: f64, x: &State| {
        n.set(n.get() + 1);
        flow(&p, &ctrl, mode.get(), t, x)
    };
    let problem = OdeBuilder::<M>::new()
        .rtol(rtol)
        .atol([atol])
        .rhs(|x, _p, t, y| y.copy_from_slice(f(t, &st(x)).as_slice()))
        .init(|_p, _t, y| y.copy_from_slice(x0_orbit().as_slice()), 4)
        .root(|x, _p, _t, g| g[0] = x[0], 1)
        .build()
        .unwrap();
    let mut s = problem.tsit45().unwrap();
    let mut landings = Vec::new();
    let stops: Vec<f64> = match chunk {
        None => vec![T_END],
        Some(dt) => (1..=(T_END / dt).round() as u64)
            .map(|k| k as f64 * dt)
            .collect(),
    };
    for &t_stop in &stops {
        s.set_stop_time(t_stop).unwrap();
        loop {
            match s.step().expect("diffsol step") {
                OdeSolverStopReason::InternalTimestep => {}
                OdeSolverStopReason::TstopReached => break,
                OdeSolverStopReason::RootFound(tr, _) => {
                    s.state_mut_back(tr).unwrap();
                    let from = mode.get();
                    let y = s.state().y;
                    let mut xm = State::new(y[0], y[1], y[2], y[3]);
                    xm[0] = 0.0; // as in Plant::land: the impact happens on the ground
                    let xa = ImpactLaw::Paper.apply(&p, from, &xm);
                    let to = from.mirrored();
                    mode.set(to);
                    let dy = f(tr, &xa);
                    let sm = s.state_mut();
                    for i in 0..4 {
                        sm.y[i] = xa[i];
                        sm.dy[i] = dy[i];
                    }
                    landings.push(tr);
                    // the stop time survives the state change (re-armed in start_step)
                    if tr >= t_stop {
                        break;
                    }
                }
            }
        }
    }
    let y = s.state().y;
    OrbitRun {
        landings,
        x_end: State::new(y[0], y[1], y[2], y[3]),
        mode_end: mode.get(),
        evals: n.get(),
        steps: s.get_statistics().number_of_steps,
        alternates: true,
    }
}

// ---------------------------------------------------------------------------------------------
// 3. The same orbit under a 1 kHz zero-order hold (the networked plant's setting)
// ---------------------------------------------------------------------------------------------

const DT_ZOH: f64 = 1e-3;

/// A transition `(t, from, to)`.
type Tr = (f64, Mode, Mode);

#[derive(Debug, Clone)]
struct ZohRun {
    transitions: Vec<Tr>,
    x_end: State,
    mode_end: Mode,
    evals: u64,
    steps: usize,
}

/// Ours: each period the controller samples `(t_k, q_k, x_k)` and the plant advances with the
/// torque held (`Plant::advance_held`).
fn ours_zoh(tol: Tolerance, x0: State) -> ZohRun {
    let ctrl = controller();
    let cfg = SimConfig {
        tol,
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let mut log = Log::default();
    let k_end = (T_END / DT_ZOH).round() as u64;
    for k in 0..k_end {
        let tau = ctrl.torque(plant.time(), plant.mode(), &plant.state());
        plant
            .advance_held(tau, (k + 1) as f64 * DT_ZOH, &mut log)
            .unwrap();
    }
    ZohRun {
        transitions: log.0.iter().map(|e| (e.t, e.from, e.to)).collect(),
        x_end: plant.state(),
        mode_end: plant.mode(),
        // the plant's own counter: each evaluation is one call of the (held) torque law
        evals: plant.stats().evals,
        steps: plant.stats().steps as usize,
    }
}

/// diffsol (`tsit45`) with the full hybrid logic the held torque needs: flat mode with the two
/// support margins as root functions (they need the accelerations: one counted right-hand-side
/// evaluation per root-function call in the flat mode), landing -> impact -> flat -> support
/// check at once, support check at every torque change, tilt start with alpha = alpha_dot = 0.
/// No contact-loss, fall or Zeno checks (ours has them).
fn diffsol_zoh(rtol: f64, atol: f64) -> ZohRun {
    let p = Params::default();
    let ctrl = controller();
    let mode = Cell::new(Mode::Left);
    let tau = Cell::new(0.0);
    let n = Cell::new(0u64);
    let f = |x: &State| {
        n.set(n.get() + 1);
        let tm = Terms::new(&p, mode.get(), x);
        let (add, bdd) = accelerations_t(&p, mode.get(), &tm, tau.get());
        State::new(x[2], x[3], add, bdd)
    };
    // support margins (p.f F_y + tau, p.f F_y - tau) of the flat plate
    let margins = |x: &State| {
        let xd = f(x);
        let fy = vertical_force(&p, Mode::Flat, x, 0.0, xd[3]);
        (p.f * fy + tau.get(), p.f * fy - tau.get())
    };
    let problem = OdeBuilder::<M>::new()
        .rtol(rtol)
        .atol([atol])
        .rhs(|x, _p, _t, y| y.copy_from_slice(f(&st(x)).as_slice()))
        .init(|_p, _t, y| y.copy_from_slice(x0_orbit().as_slice()), 4)
        .root(
            |x, _p, _t, g| match mode.get() {
                Mode::Flat => {
                    let (l, r) = margins(&st(x));
                    g[0] = l;
                    g[1] = r;
                }
                _ => {
                    g[0] = x[0];
                    g[1] = 1.0;
                }
            },
            2,
        )
        .build()
        .unwrap();
    let mut s = problem.tsit45().unwrap();
    let mut transitions: Vec<Tr> = Vec::new();
    // Writes (q, x) into the solver and re-derives dy; in the flat mode tilts at once if the
    // support margin is negative for the held torque.
    let set = |s: &mut diffsol::ExplicitRk<'_, _, _, _>, t: f64, x: State, trs: &mut Vec<Tr>| {
        let mut x = x;
        if mode.get() == Mode::Flat {
            let (l, r) = margins(&x);
            let to = if l < 0.0 {
                Some(Mode::Left)
            } else if r < 0.0 {
                Some(Mode::Right)
            } else {
                None
            };
            if let Some(to) = to {
                trs.push((t, Mode::Flat, to));
                mode.set(to);
                x[0] = 0.0;
                x[2] = 0.0;
            }
        }
        let dy = f(&x);
        let sm: diffsol::StateRefMut<'_, diffsol::NalgebraVec<f64>> = s.state_mut();
        for i in 0..4 {
            sm.y[i] = x[i];
            sm.dy[i] = dy[i];
        }
    };
    let k_end = (T_END / DT_ZOH).round() as u64;
    for k in 0..k_end {
        let t_k = s.state().t;
        let x_k = read(&s);
        tau.set(ctrl.torque(t_k, mode.get(), &x_k));
        set(&mut s, t_k, x_k, &mut transitions);
        s.set_stop_time((k + 1) as f64 * DT_ZOH).unwrap();
        loop {
            match s.step().expect("diffsol step") {
                OdeSolverStopReason::InternalTimestep => {}
                OdeSolverStopReason::TstopReached => break,
                OdeSolverStopReason::RootFound(tr, idx) => {
                    s.state_mut_back(tr).unwrap();
                    let mut x = read(&s);
                    let from = mode.get();
                    if from == Mode::Flat {
                        // ZMP left the support: tilt over that edge
                        let to = if idx == 0 { Mode::Left } else { Mode::Right };
                        transitions.push((tr, Mode::Flat, to));
                        mode.set(to);
                        x[0] = 0.0;
                        x[2] = 0.0;
                    } else {
                        x[0] = 0.0;
                        x = ImpactLaw::Paper.apply(&p, from, &x);
                        transitions.push((tr, from, Mode::Flat));
                        mode.set(Mode::Flat);
                    }
                    set(&mut s, tr, x, &mut transitions);
                    if tr >= (k + 1) as f64 * DT_ZOH {
                        break;
                    }
                }
            }
        }
    }
    ZohRun {
        transitions,
        x_end: read(&s),
        mode_end: mode.get(),
        evals: n.get(),
        steps: s.get_statistics().number_of_steps,
    }
}

/// The current state of a diffsol solver.
fn read<'a, Eqn, S>(s: &S) -> State
where
    Eqn: OdeEquations<T = f64, V = diffsol::NalgebraVec<f64>> + 'a,
    S: OdeSolverMethod<'a, Eqn>,
{
    let y = s.state().y;
    State::new(y[0], y[1], y[2], y[3])
}

/// Largest |difference| between matching transition times; `None` if the sequences of modes
/// differ.
fn max_dt_tr(a: &[Tr], b: &[Tr]) -> Option<f64> {
    if a.len() != b.len() || a.iter().zip(b).any(|(x, y)| (x.1, x.2) != (y.1, y.2)) {
        return None;
    }
    Some(
        a.iter()
            .zip(b)
            .map(|(x, y)| (x.0 - y.0).abs())
            .fold(0.0, f64::max),
    )
}

/// Largest |difference| between matching landing times (panics if the counts differ).
fn max_dt(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "different numbers of landings");
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

// ---------------------------------------------------------------------------------------------

fn main() {
    let tol = tol();
    let (rtol, atol) = (tol.rtol, tol.atol);
    println!("# diffsol-compare: own DOP853 (tilting_plant::Plant) vs diffsol 0.18");
    println!("# rtol = {rtol:e}, atol = {atol:e} for every run; reference: own DOP853 at rtol = {:e}, atol = {:e}", REF_TOL.rtol, REF_TOL.atol);
    println!(
        "# machine: {} logical cores (shared), release build",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );

    // ---- 1. passive landing -----------------------------------------------------------------
    const REPS1: usize = 301;
    let table1 = |rows: &[(String, Landing, f64)], reference: &Landing| {
        println!();
        println!("| integrator | steps | RHS evals | (+ FD Jacobian evals) | wall (median) | landing-time error | state error at landing (max abs) |");
        println!("|---|---:|---:|---:|---:|---:|---:|");
        for (name, l, w) in rows {
            println!(
                "| {name} | {} | {} | {} | {:.1} us | {:+.2e} s | {:.2e} |",
                l.steps,
                l.evals,
                l.jac_evals,
                w * 1e6,
                l.t - reference.t,
                (l.x - reference.x).amax()
            );
        }
    };

    // 1a: the pure left-tilt ODE from alpha = 0.3
    let reference = ours_passive_ode(REF_TOL, 1e-15);
    let check = diffsol_passive_tsit45(A0_ODE, 1e-14, 1e-16);
    println!();
    println!("## 1a. Passive tilt (tau = 0), left-tilt ODE, x0 = ({A0_ODE}, pi/2, 0, 0), to the first alpha = 0 (pivot force ignored: it vanishes at t = 0.104 s)");
    println!(
        "reference landing: t = {:.15} s, x = ({:.3e}, {:.12}, {:.12}, {:.12}) [{} evals]",
        reference.t,
        reference.x[0],
        reference.x[1],
        reference.x[2],
        reference.x[3],
        reference.evals
    );
    println!(
        "cross-check of the reference: diffsol tsit45 at rtol 1e-14, atol 1e-16 lands {:+.2e} s from it ({} evals); own DOP853 at rtol 1e-12: {:+.2e} s",
        check.t - reference.t,
        check.evals,
        ours_passive_ode(Tolerance { rtol: 1e-12, atol: 1e-14 }, 1e-13).t - reference.t
    );
    let mut rows: Vec<(String, Landing, f64)> = Vec::new();
    rows.push((
        "own DOP853 (stepper + lazy dense + Illinois)".into(),
        ours_passive_ode(tol, 1e-13),
        time_median(REPS1, || ours_passive_ode(tol, 1e-13)),
    ));
    rows.push((
        "diffsol tsit45".into(),
        diffsol_passive_tsit45(A0_ODE, rtol, atol),
        time_median(REPS1, || diffsol_passive_tsit45(A0_ODE, rtol, atol)),
    ));
    for m in [Implicit::Bdf, Implicit::Esdirk34, Implicit::TrBdf2] {
        rows.push((
            format!("diffsol {m:?} (FD Jv)").to_lowercase(),
            diffsol_passive_implicit(m, A0_ODE, rtol, atol),
            time_median(21, || diffsol_passive_implicit(m, A0_ODE, rtol, atol)),
        ));
    }
    table1(&rows, &reference);

    // 1b: work-precision sweep, own DOP853 vs tsit45 on the same problem
    println!();
    println!("## 1b. Work-precision on 1a (atol = rtol / 100)");
    println!();
    println!("| rtol | own evals | own wall | own landing-time error | tsit45 evals | tsit45 wall | tsit45 landing-time error |");
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    for rtol in [1e-6, 1e-8, 1e-10, 1e-12] {
        let atol = rtol * 1e-2;
        let tl = Tolerance { rtol, atol };
        let o = ours_passive_ode(tl, 1e-13);
        let d = diffsol_passive_tsit45(A0_ODE, rtol, atol);
        let wo = time_median(REPS1, || ours_passive_ode(tl, 1e-13));
        let wd = time_median(REPS1, || diffsol_passive_tsit45(A0_ODE, rtol, atol));
        println!(
            "| {rtol:.0e} | {} | {:.1} us | {:+.2e} s | {} | {:.1} us | {:+.2e} s |",
            o.evals,
            wo * 1e6,
            o.t - reference.t,
            d.evals,
            wd * 1e6,
            d.t - reference.t
        );
    }

    // ---- 2. controlled orbit ----------------------------------------------------------------
    println!();
    println!("## 2. Controlled orbit, K_P = 100, K_D = 14.14, k = 500, E_av = 19.9588180580, 20 s from mode left, x0 = (0, pi/2 - 0.000214877415, 0, 0.498257789686)");
    let ref_orbit = ours_orbit(REF_TOL, None, x0_orbit());
    let ours = ours_orbit(tol, None, x0_orbit());
    let theirs = diffsol_orbit(rtol, atol, None);
    let ours_chunked = ours_orbit(tol, Some(1e-3), x0_orbit());
    let theirs_chunked = diffsol_orbit(rtol, atol, Some(1e-3));
    println!(
        "reference: {} landings, mode sequence left -> flat -> mirrored tilt at the same instant every time: {}; ends in mode {} at x = ({:.6e}, {:.12}, {:.12}, {:.12})",
        ref_orbit.landings.len(),
        ref_orbit.alternates && ours.alternates,
        ref_orbit.mode_end,
        ref_orbit.x_end[0],
        ref_orbit.x_end[1],
        ref_orbit.x_end[2],
        ref_orbit.x_end[3]
    );
    const REPS2: usize = 41;
    let w_ours = time_median(REPS2, || ours_orbit(tol, None, x0_orbit()));
    let w_theirs = time_median(REPS2, || diffsol_orbit(rtol, atol, None));
    let w_ours_c = time_median(REPS2, || ours_orbit(tol, Some(1e-3), x0_orbit()));
    let w_theirs_c = time_median(REPS2, || diffsol_orbit(rtol, atol, Some(1e-3)));
    println!();
    println!("| integrator | landings | steps | RHS evals per sim. s | sim. s per wall s | max landing-time error vs reference | state error at 20 s (max abs) |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (name, r, w) in [
        ("own DOP853, one call", &ours, w_ours),
        ("diffsol tsit45, one call", &theirs, w_theirs),
        ("own DOP853, 1 ms lockstep", &ours_chunked, w_ours_c),
        (
            "diffsol tsit45, 1 ms set_stop_time",
            &theirs_chunked,
            w_theirs_c,
        ),
    ] {
        assert_eq!(
            r.mode_end, ref_orbit.mode_end,
            "{name}: different final mode"
        );
        println!(
            "| {name} | {} | {} | {:.0} | {:.0} | {:.2e} s | {:.2e} |",
            r.landings.len(),
            r.steps,
            r.evals as f64 / T_END,
            T_END / w,
            max_dt(&r.landings, &ref_orbit.landings),
            (r.x_end - ref_orbit.x_end).amax()
        );
    }
    println!();
    println!(
        "landing-time agreement own vs diffsol over 20 s: max |dt| = {:.2e} s over {} landings",
        max_dt(&ours.landings, &theirs.landings),
        ours.landings.len()
    );
    println!(
        "lockstep vs one call: own max |dt| = {:.2e} s, bit-identical landings: {}; diffsol max |dt| = {:.2e} s, bit-identical: {}",
        max_dt(&ours.landings, &ours_chunked.landings),
        ours.landings == ours_chunked.landings,
        max_dt(&theirs.landings, &theirs_chunked.landings),
        theirs.landings == theirs_chunked.landings
    );
    let again = diffsol_orbit(rtol, atol, Some(1e-3));
    let again_ours = ours_orbit(tol, Some(1e-3), x0_orbit());
    println!(
        "repeatability (same run twice, bit-identical landings and final state): own {}, diffsol {}",
        again_ours.landings == ours_chunked.landings && again_ours.x_end == ours_chunked.x_end,
        again.landings == theirs_chunked.landings && again.x_end == theirs_chunked.x_end
    );

    // ---- 2b. work-precision on the orbit (one call) -----------------------------------------
    println!();
    println!("## 2b. Work-precision on the orbit (one call, 20 s, atol = rtol / 100): max landing-time error vs the reference");
    println!();
    println!("| rtol | own RHS evals / sim. s | own sim. s / wall s | own max landing-time error | tsit45 RHS evals / sim. s | tsit45 sim. s / wall s | tsit45 max landing-time error |");
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    for rtol in [1e-8, 1e-9, 1e-10, 3e-11, 1e-11, 1e-12] {
        let atol = rtol * 1e-2;
        let tl = Tolerance { rtol, atol };
        let o = ours_orbit(tl, None, x0_orbit());
        let d = diffsol_orbit(rtol, atol, None);
        let wo = time_median(REPS2, || ours_orbit(tl, None, x0_orbit()));
        let wd = time_median(REPS2, || diffsol_orbit(rtol, atol, None));
        let err = |r: &OrbitRun| {
            if r.landings.len() == ref_orbit.landings.len() {
                format!("{:.2e} s", max_dt(&r.landings, &ref_orbit.landings))
            } else {
                format!("{} landings", r.landings.len())
            }
        };
        println!(
            "| {rtol:.0e} | {:.0} | {:.0} | {} | {:.0} | {:.0} | {} |",
            o.evals as f64 / T_END,
            T_END / wo,
            err(&o),
            d.evals as f64 / T_END,
            T_END / wd,
            err(&d)
        );
    }

    // ---- 3. zero-order hold at 1 kHz --------------------------------------------------------
    println!();
    println!("## 3. The same orbit under a 1 kHz zero-order hold (torque sampled from (t_k, q_k, x_k), held for 1 ms), 20 s");
    // Every step is cut at a sample instant, so our DOP853 takes one 1 ms step per period at
    // any rtol down to 1e-13 (its local error there is at round-off): the reference is diffsol
    // tsit45 at rtol 1e-14 instead.
    let ref_zoh = diffsol_zoh(1e-14, 1e-16);
    let o = ours_zoh(tol, x0_orbit());
    let o_tight = ours_zoh(REF_TOL, x0_orbit());
    let d = diffsol_zoh(rtol, atol);
    let flat_stays = ref_zoh
        .transitions
        .windows(2)
        .filter(|w| w[0].2 == Mode::Flat)
        .map(|w| w[1].0 - w[0].0)
        .fold(0.0, f64::max);
    println!(
        "reference (diffsol tsit45, rtol 1e-14, atol 1e-16): {} transitions (landing -> flat until the next sample, at most {:.3e} s -> mirrored tilt), ends in mode {}",
        ref_zoh.transitions.len(),
        flat_stays,
        ref_zoh.mode_end
    );
    println!(
        "own DOP853 at rtol 1e-13 bit-identical to own at the default rtol: {}",
        o_tight.transitions == o.transitions && o_tight.x_end == o.x_end
    );
    // Sensitivity of the two orbits to a 1e-12 rad/s change of the initial beta_dot.
    let mut x0p = x0_orbit();
    x0p[3] += 1e-12;
    let zp = ours_zoh(tol, x0p);
    let cp = ours_orbit(tol, None, x0p);
    let c = ours_orbit(tol, None, x0_orbit());
    let within = |a: &[Tr], b: &[Tr], t_max: f64| {
        a.iter()
            .zip(b)
            .filter(|(x, _)| x.0 <= t_max)
            .map(|(x, y)| (x.0 - y.0).abs())
            .fold(0.0, f64::max)
    };
    let cland = |r: &OrbitRun| {
        r.landings
            .iter()
            .map(|&t| (t, Mode::Left, Mode::Flat))
            .collect::<Vec<Tr>>()
    };
    println!(
        "sensitivity to beta_dot0 + 1e-12 rad/s (own DOP853): landing-time shift by 5 s / 10 s / 20 s: continuous control {:.1e} / {:.1e} / {:.1e} s, 1 kHz hold {:.1e} / {:.1e} / {:.1e} s",
        within(&cland(&c), &cland(&cp), 5.0),
        within(&cland(&c), &cland(&cp), 10.0),
        within(&cland(&c), &cland(&cp), 20.0),
        within(&o.transitions, &zp.transitions, 5.0),
        within(&o.transitions, &zp.transitions, 10.0),
        within(&o.transitions, &zp.transitions, 20.0),
    );
    let w_o = time_median(REPS2, || ours_zoh(tol, x0_orbit()));
    let w_d = time_median(REPS2, || diffsol_zoh(rtol, atol));
    println!();
    println!("| integrator | transitions | steps | RHS evals per sim. s | sim. s per wall s | first landing: time error | transition-time error, max over the first 5 s | over 20 s |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for (name, r, w) in [
        ("own DOP853 (Plant::advance_held)", &o, w_o),
        ("diffsol tsit45 (hybrid driver)", &d, w_d),
    ] {
        assert!(
            max_dt_tr(&r.transitions, &ref_zoh.transitions).is_some(),
            "{name}: mode sequence differs from the reference"
        );
        println!(
            "| {name} | {} | {} | {:.0} | {:.0} | {:.2e} s | {:.2e} s | {:.2e} s |",
            r.transitions.len(),
            r.steps,
            r.evals as f64 / T_END,
            T_END / w,
            (r.transitions[0].0 - ref_zoh.transitions[0].0).abs(),
            within(&r.transitions, &ref_zoh.transitions, 5.0),
            within(&r.transitions, &ref_zoh.transitions, 20.0),
        );
    }
    println!();
    println!(
        "own vs diffsol under the hold: first landing {:.2e} s apart, max {:.2e} s over the first 5 s",
        (o.transitions[0].0 - d.transitions[0].0).abs(),
        within(&o.transitions, &d.transitions, 5.0)
    );
}
