//! Identification from a recording: the physical parameters of a robot estimated by least
//! squares on the regressor form of its dynamics (docs/model.md, "Linear in the parameters"),
//! per contact mode: flat, the arm's equation; tilted, both (the plate's row has no torque).
//!
//! The geometry (`f`, `g`, and `l`, which only draws the arm) is measured, not identified: it
//! comes with the prior [`Options::base`], as does the arm's mass `m_l` (weighed), which the
//! motion cannot tell from `l_c` and `i_l`. What the motion fixes are the seven base
//! parameters and the plate's inertia `i_f` ([`BASE`]); [`Identification::params`] turns them into a `--params` file with the
//! prior's `m_l`, `l`, `f` and `g`, which moves exactly as the base parameters say.
//!
//! How rows are made (accelerations without straddling a torque step, an impact or a mode
//! transition): [`rows`]. The landings (which law, the restitution): [`landing`].

pub mod fit;
pub mod landing;
pub mod load;
mod lsq;
pub mod refine;
mod report;
pub mod rows;
pub mod smooth;

use serde::Serialize;
use tilting_plant::Params;
use tilting_record::Trace;

pub use load::{load, Recorded};
use lsq::{plate_inertia_column, plate_inertia_unseen, rotor_unseen, solve, Fit};
pub use lsq::{PLATE_T_MIN, ROTOR_LUMPED, ROTOR_T_MIN};
use rows::N_BASE;

/// The base parameters: name, combination of physical parameters, unit.
pub const BASE: [(&str, &str, &str); N_BASE] = [
    ("pi1", "m_f + m_l", "kg"),
    ("pi2", "m_l l_c", "kg m"),
    ("pi3", "m_l l_c^2 + i_l + j_m", "kg m^2"),
    ("pi4", "(n_g - 1) j_m", "kg m^2"),
    ("pi5", "(n_g^2 - 1) j_m", "kg m^2"),
    ("pi6", "b_v", "N m s/rad"),
    ("pi7", "tau_c", "N m"),
    ("pi8", "i_f", "kg m^2"),
];

/// A regressor whose scaled condition number exceeds this is refused as singular.
pub const MAX_CONDITION: f64 = 1e9;

/// Where the velocities and accelerations come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Velocities {
    /// Differentiated from the recorded angles ([`smooth`]): works with or without recorded
    /// velocities (`--measure angles`), and smooths the angles' noise.
    #[default]
    Angles,
    /// The recorded velocities, taken as exact: one row per held-torque interval with its
    /// exact mean acceleration ([`rows::build`]). For recordings whose velocities are measured
    /// well.
    Recorded,
}

/// What the identification needs besides the recording.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// The prior: `f`, `g` and `l` (measured), `m_l` (weighed); its other fields are replaced
    /// by the estimates where the data fixes them, kept otherwise.
    pub base: Params,
    /// Shortest recording accepted (s of usable intervals).
    pub min_duration: f64,
    /// Where the velocities come from.
    pub velocities: Velocities,
    /// Half width (s) of the differentiator's window ([`Velocities::Angles`]): the
    /// velocities inside the weak form's terms.
    pub half_window: f64,
    /// Length (s) of the weak form's windows ([`Velocities::Angles`], [`rows::build_from_angles`]).
    pub window: f64,
    /// Slowest joint speed (rad/s) at which a torque row is used ([`Velocities::Angles`]):
    /// below it the joint may stick, and the estimated speed's sign may be noise.
    pub v_min: f64,
    /// The output-error refinement of the flat arm's parameters ([`refine`],
    /// [`Velocities::Angles`] only): its window length (s), `None` for the least squares
    /// alone.
    pub refine: Option<f64>,
    /// Time (s) left out of each segment at a landing or a lift-off ([`Velocities::Angles`]):
    /// a compliant contact settles over a few of its time constants there, and neither mode's
    /// equations hold while it does. `None`: measured from the recording ([`settle`]).
    pub settle: Option<f64>,
}

/// The differentiator's default half width (s): 4th-degree polynomials over 21 ms.
pub const HALF_WINDOW: f64 = 0.01;
/// The weak form's default window (s).
pub const WINDOW: f64 = 0.1;

impl Default for Options {
    fn default() -> Self {
        Self {
            base: Params::default(),
            min_duration: 1.0,
            velocities: Velocities::Angles,
            half_window: HALF_WINDOW,
            window: WINDOW,
            v_min: 0.01,
            refine: Some(refine::WINDOW),
            settle: None,
        }
    }
}

/// `value` if it is finite and in `range`, else [`IdentifyError::OutOfRange`] naming `flag` and
/// `allowed`.
fn in_range(
    flag: &'static str,
    value: f64,
    range: std::ops::RangeInclusive<f64>,
    allowed: &'static str,
) -> Result<(), IdentifyError> {
    if value.is_finite() && range.contains(&value) {
        return Ok(());
    }
    Err(IdentifyError::OutOfRange {
        flag,
        value,
        allowed,
    })
}

impl Options {
    /// The options' ranges, each refusal naming its flag: `half_window` in [0.002, 0.5] s,
    /// `window` in [0.01, 2] s, `v_min` in [0, 10] rad/s, `settle` in [0, 1] s.
    pub fn check(&self) -> Result<(), IdentifyError> {
        in_range(
            "half-window",
            self.half_window,
            0.002..=0.5,
            "a time in s in [0.002, 0.5]",
        )?;
        in_range(
            "window",
            self.window,
            0.01..=2.0,
            "a time in s in [0.01, 2]",
        )?;
        in_range(
            "min-speed",
            self.v_min,
            0.0..=10.0,
            "a speed in rad/s in [0, 10]",
        )?;
        if let Some(s) = self.settle {
            in_range("settle", s, 0.0..=1.0, "a time in s in [0, 1]")?;
        }
        Ok(())
    }
}

/// The fit check's restart interval `window` (s, [`Identification::check_fit`]) if it is in
/// [0.01, 10], else the refusal naming `--fit-window`.
pub fn check_fit_window(window: f64) -> Result<(), IdentifyError> {
    in_range(
        "fit-window",
        window,
        0.01..=10.0,
        "a time in s in [0.01, 10]",
    )
}

/// One base parameter's estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Estimate {
    /// `pi1` ... `pi8`, or `pi3+pi5` when only their sum is seen.
    pub name: String,
    /// The physical parameters it combines.
    pub combination: String,
    /// Unit.
    pub unit: String,
    /// The estimate, `None` when the data does not fix it.
    pub value: Option<f64>,
    /// Its standard error (same unit), from the residual variance.
    pub std_error: Option<f64>,
    /// Why the data does not fix it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_identifiable: Option<String>,
}

/// How many equations came from where.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RowCounts {
    /// Equations in the fit.
    pub equations: usize,
    /// Flat intervals used (the arm's equation).
    pub flat: usize,
    /// Tilted intervals used (the plate's equation, and the arm's while the joint slides).
    pub tilted: usize,
    /// Intervals skipped: an event or mode change inside, or no torque known.
    pub skipped: usize,
}

/// The result of [`identify`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Identification {
    /// The base parameters, in [`BASE`] order (and `pi3+pi5` when only the sum is seen).
    pub base: Vec<Estimate>,
    /// Condition number of the regressor with its columns scaled to unit norm.
    pub condition_number: f64,
    /// RMS of the residual (N m).
    pub residual_rms: f64,
    /// Where the equations came from.
    pub rows: RowCounts,
    /// The `--params` of the identified robot (the prior's where the data says nothing).
    pub params: Params,
    /// Physical parameters the data cannot fix, and why.
    pub not_identifiable: Vec<String>,
    /// Things to look at: estimates clamped to their range, a prior that does not fit.
    pub warnings: Vec<String>,
    /// Where the velocities came from.
    pub velocities: Velocities,
    /// The fit check ([`fit`]): the recording re-simulated with the identified parameters
    /// and, for comparison, with the prior's; filled by [`Identification::check_fit`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitChecks>,
    /// The output-error refinement of the flat arm's parameters ([`refine`]), when it ran:
    /// `b_v` and `tau_c` above are its estimates where their standard errors are smaller
    /// than the least squares'.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refinement: Option<refine::Refinement>,
    /// The landings ([`landing`]): each one's jump, the law that fits them, the restitution;
    /// `None` when the recording has no usable landing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub landing: Option<landing::LandingFit>,
    /// The state `(alpha, beta, alpha_dot, beta_dot)` at each sample as the fit saw it
    /// (smoothed, or recorded), `None` where unused; not serialised.
    #[serde(skip)]
    pub states: Vec<Option<[f64; 4]>>,
}

/// Why a recording cannot be identified.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// The recording cannot be loaded.
    #[error(transparent)]
    Load(#[from] tilting_record::LoadError),
    /// The recording cannot be read.
    #[error(transparent)]
    Read(#[from] tilting_record::ReadError),
    /// The recording holds another robot.
    #[error("{path}: robot {asked:?} is not in the file (it holds {found})")]
    Robot {
        /// The file.
        path: String,
        /// The name asked for.
        asked: String,
        /// The robot(s) found.
        found: String,
    },
    /// Too little usable motion.
    #[error(
        "the recording is too short: {usable:.3} s of usable intervals ({equations} equations), \
         at least {min} s needed"
    )]
    TooShort {
        /// Usable time (s).
        usable: f64,
        /// Equations.
        equations: usize,
        /// Minimum (s).
        min: f64,
    },
    /// The regressor is singular: the motion does not excite some combination.
    #[error(
        "the regressor is singular (condition number {condition:.3e} > {MAX_CONDITION:e}): the \
         motion does not separate {direction}; {advice}"
    )]
    Singular {
        /// Scaled condition number.
        condition: f64,
        /// The combination of base parameters the data cannot fix.
        direction: String,
        /// What to record.
        advice: String,
    },
    /// No equation carries a torque: nothing sets the scale of the parameters.
    #[error(
        "the recording has no excitation: none of its {equations} equations carries a torque \
         (the arm never slid one way through a window with a torque applied); record the arm \
         moving under torque, e.g. `tilting simulate --record` or `live` on the orbit"
    )]
    NoExcitation {
        /// Equations (all homogeneous).
        equations: usize,
    },
    /// The torques do not match the samples.
    #[error("{torques} torques for {samples} samples: one torque (or none) per sample needed")]
    Mismatch {
        /// Samples.
        samples: usize,
        /// Torques.
        torques: usize,
    },
    /// An option out of its range (named by its flag).
    #[error("invalid `--{flag}` = {value}: allowed {allowed}")]
    OutOfRange {
        /// The flag (`half-window`, `window`, `min-speed`, `settle`, `fit-window`).
        flag: &'static str,
        /// The value given.
        value: f64,
        /// The range, with its unit.
        allowed: &'static str,
    },
    /// A friction estimate is negative beyond its error.
    #[error(
        "the friction estimate {field} = {value:.4e} is negative (standard error {std_error:.1e}); \
         allowed: >= 0. The recording's torque may be offset or scaled, or not the joint's"
    )]
    NegativeFriction {
        /// `b_v` or `tau_c`.
        field: &'static str,
        /// Estimate.
        value: f64,
        /// Standard error.
        std_error: f64,
    },
}

/// Why a base parameter cannot be seen in what the recording holds (`None`: it may be): no
/// tilted interval (`merge35`: the flat rows see pi3 + pi5 only), no sliding joint.
fn unseen_in(r: &rows::Rows, merge35: bool) -> Vec<Option<String>> {
    let mut out = vec![None::<String>; N_BASE];
    if merge35 {
        out[0] = Some(
            "m_f + m_l enters only the plate's equation while tilted: the recording has \
                       no tilted interval (record tilts)"
                .into(),
        );
        out[3] = Some(
            "the rotor's share enters only while tilted: flat motion sees pi3 + pi5 \
                       (record tilts)"
                .into(),
        );
        out[2] = Some(
            "flat motion sees only pi3 + pi5, the arm's inertia about the joint \
                       (record tilts)"
                .into(),
        );
        out[4] = out[2].clone();
        out[7] = Some(
            "the plate's inertia enters only the plate's equation while tilted: the \
                       recording has no tilted interval (record tilts)"
                .into(),
        );
    }
    if r.sliding_fwd + r.sliding_bwd == 0 {
        for i in [5, 6] {
            out[i] = Some("no interval with the joint sliding: friction is not seen".into());
        }
    }
    out
}

/// The base parameters' estimates as reported: value, standard error or why not identifiable,
/// and the lumped `pi3 + pi5` when it was estimated (`sum35`: value, standard error).
fn estimates(
    value: &[Option<f64>; N_BASE],
    se: &[Option<f64>; N_BASE],
    out: &[Option<String>],
    sum35: Option<(f64, f64)>,
) -> Vec<Estimate> {
    let mut base: Vec<Estimate> = (0..N_BASE)
        .map(|i| Estimate {
            name: BASE[i].0.into(),
            combination: BASE[i].1.into(),
            unit: BASE[i].2.into(),
            value: value[i],
            std_error: se[i],
            not_identifiable: out[i].clone(),
        })
        .collect();
    if let Some((v, s)) = sum35 {
        base.push(Estimate {
            name: "pi3+pi5".into(),
            combination: "m_l l_c^2 + i_l + n_g^2 j_m".into(),
            unit: "kg m^2".into(),
            value: Some(v),
            std_error: Some(s),
            not_identifiable: None,
        });
    }
    base
}

/// Writes the landing law the recorded landings decide into `params` (and its restitution), or
/// keeps the prior's with a warning when they do not tell the laws apart.
fn write_landing(params: &mut Params, l: &landing::LandingFit, warnings: &mut Vec<String>) {
    match l.decisive() {
        Some(best) => {
            params.impact = best;
            (params.restitution, params.contact_dwell) = match best {
                tilting_plant::ImpactLaw::Physical => {
                    (l.restitution_written(), l.contact_dwell_written())
                }
                _ => (0.0, 0.0),
            };
        }
        None => {
            warnings.push(format!(
                "the landings do not tell the laws apart (residuals within a factor {} of \
                 each other: the rates around a landing are too noisy): the prior's law, {}, \
                 is kept",
                1.0 / landing::DECISIVE,
                params.impact.as_str()
            ));
            // The prior's physical law: its restitution is still the landings' to tell.
            if params.impact == tilting_plant::ImpactLaw::Physical {
                params.restitution = l.restitution_written();
                params.contact_dwell = l.contact_dwell_written();
            }
        }
    }
}

/// The equations of `trace` ([`build_rows`]), with the contact's settling at landings and
/// lift-offs left out: `opts.settle`, or measured from the plate's equations (their residual
/// against the distance from the mode change); and the warning that says what was left out.
fn rows_settled(
    trace: &Trace,
    tau: &[Option<f64>],
    opts: &Options,
) -> (rows::Rows, Vec<Option<[f64; 4]>>, f64, Option<String>) {
    let p = &opts.base;
    let h = sample_spacing(trace);
    let (mut r, mut states, corr) = build_rows(trace, tau, opts, 0);
    // Only the angles' rows are cut (the recorded velocities' are not): measure only there.
    let settle = match (opts.velocities, opts.settle) {
        (Velocities::Recorded, _) => 0,
        (Velocities::Angles, Some(s)) => (s / h).round() as usize,
        (Velocities::Angles, None) => measure_settle(&r, p.i_f),
    };
    let mut settle_note = None;
    if settle > 0 {
        let before = (r.plate.iter().filter(|p| **p).count(), r.y.len());
        (r, states, _) = build_rows(trace, tau, opts, settle);
        let after = r.plate.iter().filter(|p| **p).count();
        settle_note = Some(format!(
            "{:.0} ms left out after each landing and before each lift-off ({}): the \
             contact settles there (the plate sinks, rocks and bounces on its compliant \
             edge), which neither mode's equations describe; {} of {} equations kept ({} of \
             {} of the plate's)",
            settle as f64 * h * 1e3,
            if opts.settle.is_some() {
                "given"
            } else {
                "measured: the plate's equations' residual falls to twice its level far from \
                 the mode changes there"
            },
            r.y.len(),
            before.1,
            after,
            before.0
        ));
    }
    (r, states, corr, settle_note)
}

/// Refuses equations too few or too short for the fit, or without a torque in any of them.
fn check_rows(trace: &Trace, r: &rows::Rows, opts: &Options) -> Result<(), IdentifyError> {
    let used = r.flat + r.tilted;
    let intervals = used + r.skipped;
    let span =
        trace.samples.last().map_or(0.0, |l| l.t) - trace.samples.first().map_or(0.0, |f| f.t);
    let usable = if intervals == 0 {
        0.0
    } else {
        span * used as f64 / intervals as f64
    };
    if usable < opts.min_duration || r.y.len() < 2 * N_BASE {
        return Err(IdentifyError::TooShort {
            usable,
            equations: r.y.len(),
            min: opts.min_duration,
        });
    }
    if r.rhs.iter().all(|t| *t == 0.0) {
        return Err(IdentifyError::NoExcitation {
            equations: r.y.len(),
        });
    }
    Ok(())
}

/// [`fit_columns`]' answer: the fit, its columns, why each base parameter is left out, and
/// whether column 2 is a lumped `pi3 + pi5`.
type Fitted = (Fit, Vec<usize>, Vec<Option<String>>, bool);

/// The least squares over the columns the recording shows: `out[i]` says why base parameter
/// `i` is left out (`None`: estimated). Returns the fit, its columns, `out`, and whether
/// column 2 is a lumped `pi3 + pi5` (flat motion only, or the rotor's share lumped).
fn fit_columns(
    r: &rows::Rows,
    merge35: bool,
    corr: f64,
    i_f_prior: f64,
) -> Result<Fitted, IdentifyError> {
    let mut out = unseen_in(r, merge35);
    // Active columns: a merged pi3 + pi5 is column 2 (the flat rows have equal columns).
    let active = |out: &[Option<String>]| -> (Vec<usize>, Vec<String>) {
        let cols: Vec<usize> = (0..N_BASE)
            .filter(|&i| out[i].is_none() || (merge35 && i == 2))
            .collect();
        let names = cols
            .iter()
            .map(|&c| match (merge35, c) {
                (true, 2) => "pi3+pi5 (m_l l_c^2 + i_l + n_g^2 j_m)".into(),
                _ => format!("{} ({})", BASE[c].0, BASE[c].1),
            })
            .collect();
        (cols, names)
    };
    // The plate's inertia and the rotor's share are one combination: the constant parts of
    // M11, M12 and M22 are pi3 + pi8, pi3 + pi4 and pi3 + pi5, three numbers for four base
    // parameters (the direction pi3 + 1, pi4 - 1, pi5 - 1, pi8 - 1 moves no row). So the
    // first fit holds i_f at the prior's (its term moved to the right-hand side) and i_f gets
    // its column only where the rotor's share is lumped ([`plate_inertia_column`]).
    if out[7].is_none() {
        out[7] = Some(format!(
            "with the rotor's share (pi4, pi5) seen, i_f is not separable from it: the \
             constant parts of M11, M12, M22 are pi3 + i_f, pi3 + pi4, pi3 + pi5 (three \
             numbers for four parameters); the prior's i_f = {i_f_prior} kept"
        ));
    }
    let (mut cols, names) = active(&out);
    let mut fit = solve(r, &cols, &names, i_f_prior)?;
    // The rotor's share (pi4, pi5) is a fraction of a percent of the arm's inertia: under
    // sensor noise it may not be told from zero. Then it is left out (lumped into pi3, as for
    // a direct drive) rather than let its noise spill into pi1 and pi3; what column 2 then
    // estimates is pi3 + pi5 (the flat rows, where its column is beta_ddot, carry it).
    let mut lumped = false;
    if let Some(why) =
        rotor_unseen(&fit, &cols, corr).or_else(|| plate_inertia_column(&fit, &cols, corr))
    {
        out[3] = Some(why.clone());
        out[4] = Some(why);
        lumped = true;
    }
    if lumped {
        out[7] = None;
        let (c, n) = active(&out);
        fit = solve(r, &c, &n, i_f_prior)?;
        cols = c;
    }
    // The plate's inertia: left out (the prior's kept) when the tilts do not show it.
    if let Some(why) = plate_inertia_unseen(&fit, &cols, corr) {
        out[7] = Some(why);
        let (c, n) = active(&out);
        fit = solve(r, &c, &n, i_f_prior)?;
        cols = c;
    }
    let lump = merge35 || lumped;
    if lumped {
        out[2] = Some(ROTOR_LUMPED.into());
    }
    Ok((fit, cols, out, lump))
}

/// Identifies the robot of `trace`, with `tau[k]` the torque (N m) held over sample `k`'s
/// interval (`None` where unknown).
pub fn identify(
    trace: &Trace,
    tau: &[Option<f64>],
    opts: &Options,
) -> Result<Identification, IdentifyError> {
    opts.check()?;
    let p = &opts.base;
    if tau.len() != trace.samples.len() {
        return Err(IdentifyError::Mismatch {
            samples: trace.samples.len(),
            torques: tau.len(),
        });
    }
    let (r, states, corr, settle_note) = rows_settled(trace, tau, opts);
    check_rows(trace, &r, opts)?;
    let merge35 = r.tilted == 0;
    let (fit, cols, out, lump) = fit_columns(&r, merge35, corr, p.i_f)?;
    let mut value = [None; N_BASE];
    let mut se = [None; N_BASE];
    for (j, &c) in cols.iter().enumerate() {
        if !(lump && c == 2) {
            value[c] = Some(fit.x[j]);
            se[c] = Some(fit.se[j] * corr);
        }
    }
    let sum35 = lump.then(|| {
        let j = cols.iter().position(|&c| c == 2).unwrap_or(0);
        (fit.x[j], fit.se[j] * corr)
    });
    let refinement = refine_friction(trace, tau, &states, opts, sum35, &mut value, &mut se);
    let base = estimates(&value, &se, &out, sum35);
    let mut warnings = Vec::new();
    warnings.extend(settle_note);
    warnings.extend(refinement.as_ref().and_then(not_converged));
    let (noise, rms_rate) = friction_scales(&r, fit.residual_rms);
    let friction = check_friction(&value, &se, noise, rms_rate, &mut warnings)?;
    let (mut params, not_identifiable) =
        derive::params(p, &value, sum35.map(|s| s.0), friction, &mut warnings);
    let landing = landing::fit(trace, tau, &params);
    if let Some(l) = &landing {
        write_landing(&mut params, l, &mut warnings);
    }
    Ok(Identification {
        base,
        condition_number: fit.condition,
        residual_rms: fit.residual_rms,
        rows: RowCounts {
            equations: r.y.len(),
            flat: r.flat,
            tilted: r.tilted,
            skipped: r.skipped,
        },
        params,
        not_identifiable,
        warnings,
        velocities: opts.velocities,
        fit: None,
        refinement,
        landing,
        states,
    })
}

/// Runs the output-error refinement ([`refine`]) from the least squares' `value` when the
/// options ask for it and the flat arm's four parameters were estimated (`sum35`: the
/// lumped `pi3 + pi5`); replaces `b_v` (`pi6`) and `tau_c` (`pi7`) and their standard errors
/// where the refinement's standard error is the smaller.
fn refine_friction(
    trace: &Trace,
    tau: &[Option<f64>],
    states: &[Option<[f64; 4]>],
    opts: &Options,
    sum35: Option<(f64, f64)>,
    value: &mut [Option<f64>; N_BASE],
    se: &mut [Option<f64>; N_BASE],
) -> Option<refine::Refinement> {
    let window = opts.refine?;
    if opts.velocities != Velocities::Angles {
        return None;
    }
    let j = match (sum35, value[2], value[4]) {
        (Some((s, _)), _, _) => s,
        (None, Some(p3), Some(p5)) => p3 + p5,
        _ => return None,
    };
    // The refinement keeps tau_c >= 0 (a negative Coulomb friction pushes the arm): started
    // from a least squares' tau_c below 0 (zero within its noise) no step is admissible, and it
    // stayed there, its small standard error then refusing the recording (MuJoCo's flat
    // excitation: tau_c = -8.8e-5 N m). Negative friction starts from 0.
    let start = [
        j,
        opts.base.g * value[1]?,
        value[5]?.max(0.0),
        value[6]?.max(0.0),
    ];
    let r = refine::refine(trace, tau, states, start, window)?;
    for (k, i) in [(2, 5), (3, 6)] {
        let ls = se[i].unwrap_or(f64::INFINITY);
        if r.converged && r.value[k].is_finite() && r.std_error[k] < ls {
            value[i] = Some(r.value[k]);
            se[i] = Some(r.std_error[k]);
        }
    }
    Some(r)
}

/// The warning of a refinement that did not converge (its values were not used).
fn not_converged(r: &refine::Refinement) -> Option<String> {
    (!r.converged).then(|| {
        format!(
            "the output-error refinement did not converge in {} iterations: b_v and tau_c \
             are the least squares' (their standard errors say how far to trust them); a \
             longer excitation may help",
            r.iterations
        )
    })
}

/// The fit check with the identified parameters and with the prior.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitChecks {
    /// With the identified parameters.
    pub identified: fit::FitCheck,
    /// With the prior (`--params`, default the paper's).
    pub prior: fit::FitCheck,
}

impl Identification {
    /// Re-simulates the recording (`trace`, `tau`) with the identified parameters and with
    /// `prior`, restarting every `window` s ([`fit::resimulate`]); keeps the figures in
    /// [`Identification::fit`] and returns the identified re-simulation (for a figure).
    pub fn check_fit(
        &mut self,
        trace: &Trace,
        tau: &[Option<f64>],
        prior: &Params,
        window: f64,
    ) -> fit::Resimulation {
        let id = fit::resimulate(trace, tau, &self.states, &self.params, window);
        let pr = fit::resimulate(trace, tau, &self.states, prior, window);
        self.fit = Some(FitChecks {
            identified: id.check.clone(),
            prior: pr.check,
        });
        id
    }
}

/// The rows of `trace` by the velocities `opts` asks for, the state of each sample as the fit
/// saw it, and the standard errors' correction for overlapping windows.
fn build_rows(
    trace: &Trace,
    tau: &[Option<f64>],
    opts: &Options,
    settle: usize,
) -> (rows::Rows, Vec<Option<[f64; 4]>>, f64) {
    let p = &opts.base;
    match opts.velocities {
        Velocities::Recorded => {
            let r = rows::build(trace, tau, p.f, p.g);
            let states = trace.samples.iter().map(|s| Some(s.x)).collect();
            (r, states, 1.0)
        }
        Velocities::Angles => {
            let h = sample_spacing(trace);
            let m = (opts.half_window / h).round().max(1.0) as usize;
            let sg = smooth::Savgol::new(m);
            let w = (opts.window / h).round().max(1.0) as usize + 1;
            let (r, st) = rows::build_from_angles(
                trace,
                tau,
                p.f,
                p.g,
                &sg,
                rows::Windows {
                    len: w,
                    v_min: opts.v_min,
                    settle,
                },
            );
            // Overlapping windows share their noise: four windows cover each sample, so the
            // independent-row standard errors are scaled up by 2 (conservative).
            (r, st, 2.0)
        }
    }
}

/// Width (samples) of the bins of distance from a mode change in [`measure_settle`].
const SETTLE_BIN: usize = 5;

/// A bin of the plate's equations whose residual RMS exceeds this many times the level far
/// from the mode changes is still settling ([`measure_settle`]).
pub const SETTLE_RATIO: f64 = 2.0;

/// A rise of the plate's equations' residual near the mode changes counts only above this share
/// of the equations' size ([`measure_settle`]): the rigid plant's exact recording has its
/// one-sided differentiator's error there, 1e-7 of it, at up to 3 times the far level; MuJoCo's
/// `mid` contact 2e-3 of it.
pub const SETTLE_FLOOR: f64 = 1e-4;

/// The contact's settling (samples) at the mode changes, measured from the plate's equations
/// (`r`'s rows built without cutting): a first least squares (`m_f + m_l`, `m_l l_c`, the arm's
/// inertia, friction and `i_f`; the rotor's share left out), the RMS of the plate's rows'
/// residuals in bins of [`SETTLE_BIN`] samples of distance from the nearest mode change, and
/// the settling the distance beyond which every bin holding a row is within [`SETTLE_RATIO`]
/// of the level of the farthest quarter of the rows (or under [`SETTLE_FLOOR`] of the
/// equations' size). 0 when the plate's rows are too few
/// (under 8 bins' worth) or the fit fails. A rigid contact (our plant) shows no such rise,
/// within the bins' noise; a compliant one (MuJoCo's `mid` contact) a residual 500 times the
/// far level in the first 20 ms.
fn measure_settle(r: &rows::Rows, i_f: f64) -> usize {
    let cols = [0, 1, 2, 5, 6, 7];
    let names: Vec<String> = cols.iter().map(|c| BASE[*c].0.to_string()).collect();
    let Ok(fit) = solve(r, &cols, &names, i_f) else {
        return 0;
    };
    let mut pi = [0.0; N_BASE];
    for (j, &c) in cols.iter().enumerate() {
        pi[c] = fit.x[j];
    }
    let mut e: Vec<(usize, f64)> = (0..r.y.len())
        .filter(|&i| r.plate[i] && r.edge[i] != usize::MAX)
        .map(|i| {
            (
                r.edge[i],
                r.y[i].iter().zip(&pi).map(|(a, b)| a * b).sum::<f64>(),
            )
        })
        .collect();
    if e.len() < 8 * SETTLE_BIN {
        return 0;
    }
    e.sort_by_key(|x| x.0);
    let far = &e[3 * e.len() / 4..];
    let rms =
        |x: &[(usize, f64)]| (x.iter().map(|v| v.1 * v.1).sum::<f64>() / x.len() as f64).sqrt();
    let level = rms(far);
    // The plate's equations' own size: the RMS of their m_f + m_l term (gravity's moment
    // about the pivot, about m g f).
    let scale = (0..r.y.len())
        .filter(|&i| r.plate[i] && r.edge[i] != usize::MAX)
        .map(|i| (r.y[i][0] * pi[0]).powi(2))
        .sum::<f64>()
        / e.len() as f64;
    let floor = SETTLE_FLOOR * scale.sqrt();
    let top = far[0].0;
    let mut settle = 0;
    let mut lo = 0;
    while lo < top {
        let bin: Vec<(usize, f64)> = e
            .iter()
            .copied()
            .filter(|x| x.0 >= lo && x.0 < lo + SETTLE_BIN)
            .collect();
        if !bin.is_empty() && rms(&bin) > (SETTLE_RATIO * level).max(floor) {
            settle = lo + SETTLE_BIN;
        }
        lo += SETTLE_BIN;
    }
    settle
}

/// The median spacing of the samples (s); 1 ms for fewer than two.
fn sample_spacing(trace: &Trace) -> f64 {
    let mut d: Vec<f64> = trace
        .samples
        .windows(2)
        .map(|w| w[1].t - w[0].t)
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return 1e-3;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// A negative friction estimate within this many standard errors of 0 is zero within its
/// noise: clamped to 0 (with a warning), not refused.
pub const FRICTION_ZERO_IN_SE: f64 = 2.0;

/// A negative friction torque below this share of the recording's RMS torque is zero within
/// the noise of any torque measurement (1e-4: 0.1 mN m of a 10 N m drive), whatever its
/// standard error says: simulated data has errors that are not white (MuJoCo's flat
/// excitation without friction gave tau_c = -8.8e-5 N m, our plant's orbit -4.5e-7 N m at 4.5
/// standard errors).
pub const FRICTION_FLOOR: f64 = 1e-4;

/// The scales [`check_friction`] judges a friction by: the noise (N m, the residual RMS or
/// [`FRICTION_FLOOR`] of the torque rows' RMS: a friction below it is zero to any torque
/// sensor) and the RMS of the joint's rate over the rows (rad/s: b_v's regressor, which turns
/// b_v into the torque it makes in this recording).
fn friction_scales(r: &rows::Rows, residual_rms: f64) -> (f64, f64) {
    let rms = |v: Vec<f64>| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let rms_tau = rms(r.rhs.iter().copied().filter(|t| *t != 0.0).collect());
    let rms_rate = rms(r.y.iter().map(|y| y[5]).filter(|v| *v != 0.0).collect());
    (residual_rms.max(FRICTION_FLOOR * rms_tau), rms_rate)
}

/// The friction estimates `(b_v, tau_c)`, clamped to 0 when negative within their noise;
/// refused when clearly negative, naming the field and the value.
///
/// The noise is the larger of [`FRICTION_ZERO_IN_SE`] standard errors and `resid` (N m: the
/// equations' residual RMS or [`FRICTION_FLOOR`] of the RMS torque), against which a
/// friction is judged by the torque it makes in the recording: `tau_c` itself, `b_v` times
/// `rms_rate` (rad/s, the RMS of the joint's rate over the rows). The standard errors hold
/// for white noise, and an integrator's error is not white (MuJoCo's flat excitation, with no
/// friction, gave tau_c = -8.8e-5 N m at many standard errors, a torque far below what one
/// equation resolves; a MuJoCo robot's flat excitation and tilts, b_v = -4.4e-3 N m s at 86
/// standard errors: below the residual of 2.8e-3 N m at the arm's rates, refused when judged
/// at 1 rad/s).
fn check_friction(
    value: &[Option<f64>; N_BASE],
    se: &[Option<f64>; N_BASE],
    resid: f64,
    rms_rate: f64,
    warnings: &mut Vec<String>,
) -> Result<(f64, f64), IdentifyError> {
    let mut out = [0.0; 2];
    for (k, (i, field, scale)) in [(5, "b_v", rms_rate), (6, "tau_c", 1.0)]
        .into_iter()
        .enumerate()
    {
        let (Some(v), s) = (value[i], se[i].unwrap_or(0.0)) else {
            continue;
        };
        if v < 0.0 && -v > FRICTION_ZERO_IN_SE * s && -v * scale > resid {
            return Err(IdentifyError::NegativeFriction {
                field,
                value: v,
                std_error: s,
            });
        }
        if v < 0.0 {
            warnings.push(format!(
                "{field} = {v:.3e} is negative within its noise: set to 0"
            ));
        }
        out[k] = v.max(0.0);
    }
    Ok((out[0], out[1]))
}

mod derive;

#[cfg(test)]
mod tests;
