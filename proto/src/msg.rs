//! Messages exchanged by plant, controller and planner.
//!
//! Units: angles rad, rates rad/s, torques N·m, times plant seconds (simulated time since the
//! plant started, not wall-clock), energies J. Frames: `alpha` is the plate tilt angle,
//! counter-clockwise positive (`> 0` only when tilted over the left edge, `< 0` only over the
//! right edge); `beta` is the arm angle relative to the plate, `pi/2` upright, counter-clockwise
//! positive; `tau` is the joint torque on `beta`, positive accelerates `beta` positively.
//! Continuous states are ordered `(alpha, beta, alpha_dot, beta_dot)`.
//!
//! Enumerations travel as `u8` so that a peer in any language can read them; each message's
//! `validate()` checks every float is finite and every enumeration is in range, and names the
//! offending field and the allowed range in its error. Field order is the wire order: do not
//! reorder fields (see `docs/protocol.md`).

use crate::mode::{Mode, ModeError};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A message field that is out of its allowed range.
///
/// The `Display` text reads `Message.field = value ...; allowed: ...`.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ValidationError {
    /// A float field is NaN or infinite.
    #[error("{message}.{field} = {value} is not finite; allowed: any finite f64")]
    NotFinite {
        /// Message type name, e.g. `"PlantState"`.
        message: &'static str,
        /// Field name, e.g. `"alpha"` or `"x_after[1]"`.
        field: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// A numeric field (float or enumeration byte) is outside its allowed range.
    #[error("{message}.{field} = {value} is out of range; allowed: {allowed}")]
    OutOfRange {
        /// Message type name.
        message: &'static str,
        /// Field name.
        field: &'static str,
        /// The rejected value (enumeration bytes are converted exactly).
        value: f64,
        /// Human-readable allowed range, e.g. `"0..=2 (0 flat, 1 left, 2 right)"`.
        allowed: &'static str,
    },
    /// A name field (a law's name) is empty or has a character outside its alphabet.
    #[error("{message}.{field} = {value:?} is not a valid name; allowed: {allowed}")]
    BadName {
        /// Message type name.
        message: &'static str,
        /// Field name.
        field: &'static str,
        /// The rejected name (bytes that are not UTF-8 replaced).
        value: String,
        /// Human-readable alphabet and length.
        allowed: &'static str,
    },
    /// A string field is longer than its cap.
    #[error("{message}.{field} is {len} bytes long; allowed: at most {max} bytes of UTF-8")]
    TooLong {
        /// Message type name.
        message: &'static str,
        /// Field name.
        field: &'static str,
        /// Length in bytes.
        len: usize,
        /// Cap in bytes.
        max: usize,
    },
}

pub(crate) fn finite(
    message: &'static str,
    field: &'static str,
    value: f64,
) -> Result<(), ValidationError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ValidationError::NotFinite {
            message,
            field,
            value,
        })
    }
}

pub(crate) fn at_most(
    message: &'static str,
    field: &'static str,
    value: u8,
    max: u8,
    allowed: &'static str,
) -> Result<(), ValidationError> {
    if value <= max {
        Ok(())
    } else {
        Err(ValidationError::OutOfRange {
            message,
            field,
            value: f64::from(value),
            allowed,
        })
    }
}

/// The angular frequency `omega` (rad/s) of a reference of `message`: `> 0` where its
/// trajectory `moves` (a sinusoid or an excitation), anything for a hold.
pub(crate) fn moving_omega(
    message: &'static str,
    omega: f64,
    moves: bool,
) -> Result<(), ValidationError> {
    if !moves {
        return Ok(());
    }
    range(
        message,
        "omega",
        omega,
        omega > 0.0,
        "> 0 rad/s for a sinusoid or an excitation",
    )
}

/// Checks `ok(value)` for an already finite float.
pub(crate) fn range(
    message: &'static str,
    field: &'static str,
    value: f64,
    ok: bool,
    allowed: &'static str,
) -> Result<(), ValidationError> {
    if ok {
        Ok(())
    } else {
        Err(ValidationError::OutOfRange {
            message,
            field,
            value,
            allowed,
        })
    }
}

const MODE_RANGE: &str = "0..=2 (0 flat, 1 left, 2 right)";

/// Plant state sample, published by the plant once per control period; 50 bytes on the wire
/// (protocol 2: the 49 bytes of protocol 1 and the `measured` byte).
///
/// The angles are always measured. A rate is `None` when the plant does not measure it
/// (`--measure angles`: encoders, no velocity sensor): it is **absent**, never zero. On the wire
/// an absent rate is the bit pattern of `+0.0` in its slot with its bit of the `measured` byte
/// clear ([`PlantState::MEASURED_ALPHA_DOT`], [`PlantState::MEASURED_BETA_DOT`]); a receiver
/// reads it only through the bit, so it cannot be taken for a measured zero. In JSON (MCAP
/// channels, `tilting echo`) an absent rate is `null`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(deny_unknown_fields))]
pub struct PlantState {
    /// Sample number, strictly increasing from 0 for one plant run.
    pub seq: u64,
    /// Plant time of the sample, s.
    pub time: f64,
    /// Plate tilt angle, rad, counter-clockwise positive.
    pub alpha: f64,
    /// Arm angle relative to the plate, rad, `pi/2` upright.
    pub beta: f64,
    /// Plate tilt rate, rad/s; `None` when not measured.
    pub alpha_dot: Option<f64>,
    /// Arm angular rate relative to the plate, rad/s; `None` when not measured.
    pub beta_dot: Option<f64>,
    /// Contact mode, a [`Mode`] byte (0 flat, 1 left, 2 right).
    pub mode: u8,
}

/// The wire layout of [`PlantState`] (bincode: fields in this order, no padding).
#[derive(Serialize, Deserialize)]
struct PlantStateWire {
    seq: u64,
    time: f64,
    alpha: f64,
    beta: f64,
    alpha_dot: f64,
    beta_dot: f64,
    mode: u8,
    measured: u8,
}

/// The JSON form of [`PlantState`]: the rates `null` when absent.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlantStateJson {
    seq: u64,
    time: f64,
    alpha: f64,
    beta: f64,
    alpha_dot: Option<f64>,
    beta_dot: Option<f64>,
    mode: u8,
}

/// Serializes a message with two serde forms: its JSON form `json()` for a human-readable format
/// (JSON, TOML: the recordings' and the tools' form), its wire form `wire()` otherwise (bincode:
/// the bytes on the wire), whose error (a field out of its range) becomes the format's.
pub(crate) fn serialize_dual<S, J, W, E>(
    s: S,
    json: impl FnOnce() -> J,
    wire: impl FnOnce() -> Result<W, E>,
) -> Result<S::Ok, S::Error>
where
    S: serde::Serializer,
    J: Serialize,
    W: Serialize,
    E: std::fmt::Display,
{
    if s.is_human_readable() {
        json().serialize(s)
    } else {
        wire().map_err(serde::ser::Error::custom)?.serialize(s)
    }
}

/// Deserializes a message with two serde forms ([`serialize_dual`]): from its JSON form `J`
/// through `json` for a human-readable format, else from its wire form `W` through `wire`, whose
/// refusal (a field named with its range) becomes the format's error.
pub(crate) fn deserialize_dual<'de, D, J, W, T, E>(
    d: D,
    json: impl FnOnce(J) -> T,
    wire: impl FnOnce(&W) -> Result<T, E>,
) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
    J: Deserialize<'de>,
    W: Deserialize<'de>,
    E: std::fmt::Display,
{
    if d.is_human_readable() {
        Ok(json(J::deserialize(d)?))
    } else {
        let w = W::deserialize(d)?;
        wire(&w).map_err(serde::de::Error::custom)
    }
}

impl Serialize for PlantState {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        serialize_dual(
            s,
            || PlantStateJson {
                seq: self.seq,
                time: self.time,
                alpha: self.alpha,
                beta: self.beta,
                alpha_dot: self.alpha_dot,
                beta_dot: self.beta_dot,
                mode: self.mode,
            },
            || {
                Ok::<_, std::convert::Infallible>(PlantStateWire {
                    seq: self.seq,
                    time: self.time,
                    alpha: self.alpha,
                    beta: self.beta,
                    alpha_dot: self.alpha_dot.unwrap_or(0.0),
                    beta_dot: self.beta_dot.unwrap_or(0.0),
                    mode: self.mode,
                    measured: self.measured(),
                })
            },
        )
    }
}

impl<'de> Deserialize<'de> for PlantState {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        deserialize_dual(
            d,
            |j: PlantStateJson| PlantState {
                seq: j.seq,
                time: j.time,
                alpha: j.alpha,
                beta: j.beta,
                alpha_dot: j.alpha_dot,
                beta_dot: j.beta_dot,
                mode: j.mode,
            },
            PlantState::from_wire,
        )
    }
}

const MEASURED_RANGE: &str = "bits 0 (alpha) and 1 (beta) set, 2 (alpha_dot) and 3 (beta_dot) \
                              as measured, bits 4..=7 clear: 3, 7, 11 or 15";

impl PlantState {
    /// Exact wire size in bytes (protocol 2).
    pub const SIZE: usize = 50;
    /// The size of the protocol-1 layout (no `measured` byte), refused with a clear error.
    pub const SIZE_V1: usize = 49;
    /// `measured` bit: `alpha` is measured (always set in protocol 2).
    pub const MEASURED_ALPHA: u8 = 1;
    /// `measured` bit: `beta` is measured (always set in protocol 2).
    pub const MEASURED_BETA: u8 = 2;
    /// `measured` bit: `alpha_dot` is measured.
    pub const MEASURED_ALPHA_DOT: u8 = 4;
    /// `measured` bit: `beta_dot` is measured.
    pub const MEASURED_BETA_DOT: u8 = 8;
    /// `measured` byte of a full state (every field measured).
    pub const MEASURED_ALL: u8 = 15;
    /// `measured` byte of a state with the angles only (`--measure angles`).
    pub const MEASURED_ANGLES: u8 = 3;

    /// A state with every field measured, from `x = [alpha, beta, alpha_dot, beta_dot]`.
    pub fn full(seq: u64, time: f64, x: [f64; 4], mode: u8) -> Self {
        Self {
            seq,
            time,
            alpha: x[0],
            beta: x[1],
            alpha_dot: Some(x[2]),
            beta_dot: Some(x[3]),
            mode,
        }
    }

    /// The `measured` byte of the wire: which fields carry a measurement.
    pub fn measured(&self) -> u8 {
        Self::MEASURED_ALPHA
            | Self::MEASURED_BETA
            | if self.alpha_dot.is_some() {
                Self::MEASURED_ALPHA_DOT
            } else {
                0
            }
            | if self.beta_dot.is_some() {
                Self::MEASURED_BETA_DOT
            } else {
                0
            }
    }

    /// The state of the wire layout: a rate whose `measured` bit is clear is `None` (its slot
    /// must hold `+0.0`); other bits as [`PlantState::measured`] allows.
    fn from_wire(w: &PlantStateWire) -> Result<Self, ValidationError> {
        const M: &str = "PlantState";
        let angles = Self::MEASURED_ALPHA | Self::MEASURED_BETA;
        if w.measured & 0xF0 != 0 || w.measured & angles != angles {
            return Err(ValidationError::OutOfRange {
                message: M,
                field: "measured",
                value: f64::from(w.measured),
                allowed: MEASURED_RANGE,
            });
        }
        let rate = |bit: u8, field: &'static str, v: f64| {
            if w.measured & bit != 0 {
                Ok(Some(v))
            } else if v.to_bits() == 0 {
                Ok(None)
            } else {
                Err(ValidationError::OutOfRange {
                    message: M,
                    field,
                    value: v,
                    allowed: "+0.0 while the `measured` byte marks it absent",
                })
            }
        };
        Ok(Self {
            seq: w.seq,
            time: w.time,
            alpha: w.alpha,
            beta: w.beta,
            alpha_dot: rate(Self::MEASURED_ALPHA_DOT, "alpha_dot", w.alpha_dot)?,
            beta_dot: rate(Self::MEASURED_BETA_DOT, "beta_dot", w.beta_dot)?,
            mode: w.mode,
        })
    }

    /// Checks every float is finite (the rates when present) and `mode` is in `0..=2`.
    pub fn validate(&self) -> Result<(), ValidationError> {
        const M: &str = "PlantState";
        finite(M, "time", self.time)?;
        finite(M, "alpha", self.alpha)?;
        finite(M, "beta", self.beta)?;
        if let Some(v) = self.alpha_dot {
            finite(M, "alpha_dot", v)?;
        }
        if let Some(v) = self.beta_dot {
            finite(M, "beta_dot", v)?;
        }
        at_most(M, "mode", self.mode, 2, MODE_RANGE)
    }

    /// The contact mode, decoded from the `mode` byte.
    pub fn mode(&self) -> Result<Mode, ModeError> {
        Mode::try_from(self.mode)
    }

    /// The measured angles `[alpha, beta]` (rad).
    pub fn angles(&self) -> [f64; 2] {
        [self.alpha, self.beta]
    }

    /// The rates `[alpha_dot, beta_dot]` (rad/s), if both are measured.
    pub fn rates(&self) -> Option<[f64; 2]> {
        Some([self.alpha_dot?, self.beta_dot?])
    }

    /// The continuous state `[alpha, beta, alpha_dot, beta_dot]` (rad, rad/s), if every field
    /// is measured; `None` when a rate is absent (estimate it: never read it as zero).
    pub fn x(&self) -> Option<[f64; 4]> {
        let [ad, bd] = self.rates()?;
        Some([self.alpha, self.beta, ad, bd])
    }
}

/// Torque answer of the controller to one [`PlantState`]; 16 bytes on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(deny_unknown_fields))]
pub struct TorqueCommand {
    /// The `seq` of the [`PlantState`] this command answers.
    pub seq: u64,
    /// Joint torque on `beta`, N·m.
    pub tau: f64,
}

impl TorqueCommand {
    /// Exact wire size in bytes.
    pub const SIZE: usize = 16;

    /// Checks `tau` is finite.
    pub fn validate(&self) -> Result<(), ValidationError> {
        finite("TorqueCommand", "tau", self.tau)
    }
}

const X_BEFORE: [&str; 4] = ["x_before[0]", "x_before[1]", "x_before[2]", "x_before[3]"];
const X_AFTER: [&str; 4] = ["x_after[0]", "x_after[1]", "x_after[2]", "x_after[3]"];

/// A discrete transition of the hybrid plant (tilt start, landing with impact); 82 bytes.
///
/// States are `[alpha, beta, alpha_dot, beta_dot]` in rad and rad/s, just before and just after
/// the transition (equal across a tilt start; related by the impact map across a landing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(deny_unknown_fields))]
pub struct ModeEvent {
    /// `seq` of the last [`PlantState`] published before the event.
    pub seq: u64,
    /// Plant time of the event, s.
    pub time: f64,
    /// Mode before the event, a [`Mode`] byte (0 flat, 1 left, 2 right).
    pub from: u8,
    /// Mode after the event, a [`Mode`] byte (0 flat, 1 left, 2 right).
    pub to: u8,
    /// State `[alpha, beta, alpha_dot, beta_dot]` just before the event.
    pub x_before: [f64; 4],
    /// State `[alpha, beta, alpha_dot, beta_dot]` just after the event.
    pub x_after: [f64; 4],
}

impl ModeEvent {
    /// Exact wire size in bytes.
    pub const SIZE: usize = 82;

    /// Checks every float is finite and `from`, `to` are in `0..=2`.
    pub fn validate(&self) -> Result<(), ValidationError> {
        const M: &str = "ModeEvent";
        finite(M, "time", self.time)?;
        at_most(M, "from", self.from, 2, MODE_RANGE)?;
        at_most(M, "to", self.to, 2, MODE_RANGE)?;
        for (field, &value) in X_BEFORE.iter().zip(&self.x_before) {
            finite(M, field, value)?;
        }
        for (field, &value) in X_AFTER.iter().zip(&self.x_after) {
            finite(M, field, value)?;
        }
        Ok(())
    }

    /// The modes before and after the event, decoded from the `from` and `to` bytes.
    pub fn modes(&self) -> Result<(Mode, Mode), ModeError> {
        Ok((Mode::try_from(self.from)?, Mode::try_from(self.to)?))
    }
}

/// Plant health and counters, published by the plant at a low rate; variable size.
///
/// [`Status::default`] is a plant that is starting: every counter and statistic zero, mode
/// flat, no fault (a valid message).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(deny_unknown_fields))]
pub struct Status {
    /// `seq` of the last published [`PlantState`].
    pub seq: u64,
    /// Plant time, s.
    pub time: f64,
    /// Run state: 0 starting, 1 running, 2 safe mode, 3 faulted, 4 stopped
    /// ([`Status::STARTING`], [`Status::RUNNING`], [`Status::SAFE_MODE`],
    /// [`Status::FAULTED`], [`Status::STOPPED`]).
    pub state: u8,
    /// Current contact mode, a [`Mode`] byte (0 flat, 1 left, 2 right).
    pub mode: u8,
    /// Number of tilts (flat to left or right) since start.
    pub tilts: u64,
    /// Number of control periods (state samples) since start.
    pub steps: u64,
    /// Torque commands received, valid or not.
    pub torques_received: u64,
    /// Torque commands dropped because they did not decode or validate.
    pub torques_dropped: u64,
    /// Valid torque commands ignored because their `seq` was not the latest state.
    pub torques_stale: u64,
    /// Control periods whose torque did not arrive before the deadline.
    pub deadline_misses: u64,
    /// Times the watchdog put the plant into safe mode (no torque for too long).
    pub watchdog_trips: u64,
    /// Median period jitter, µs.
    pub jitter_p50_us: f64,
    /// 99th percentile of period jitter, µs.
    pub jitter_p99_us: f64,
    /// Largest period overrun since start, µs.
    pub max_overrun_us: f64,
    /// Median loop latency (state published to its torque received), µs.
    pub latency_p50_us: f64,
    /// 99th percentile of the loop latency, µs.
    pub latency_p99_us: f64,
    /// Torques applied after their own period (age > 0; under `--max-age`). (This field and the
    /// five after it are new in this release: `#[serde(default)]` lets the JSON of older
    /// recordings, which lack them, still load; the wire format has no optional fields.)
    #[serde(default)]
    pub torques_late: u64,
    /// States whose answer was never applied (skipped between two applied torques).
    #[serde(default)]
    pub torques_lost: u64,
    /// Valid torques that arrived after a newer one (dropped).
    #[serde(default)]
    pub torques_reordered: u64,
    /// Median age of the applied torques, periods (state answered to state in force).
    #[serde(default)]
    pub age_p50: f64,
    /// 99th percentile of the age, periods.
    #[serde(default)]
    pub age_p99: f64,
    /// Largest age since start, periods.
    #[serde(default)]
    pub age_max: f64,
    /// Fault description, empty if none; at most [`Status::MAX_FAULT_LEN`] bytes of UTF-8.
    pub fault: String,
}

impl Status {
    /// `state`: starting up, not yet stepping.
    pub const STARTING: u8 = 0;
    /// `state`: stepping normally.
    pub const RUNNING: u8 = 1;
    /// `state`: stepping with a safe fallback torque (controller missing or late).
    pub const SAFE_MODE: u8 = 2;
    /// `state`: stopped on a fault described in `fault`.
    pub const FAULTED: u8 = 3;
    /// `state`: stopped on request.
    pub const STOPPED: u8 = 4;
    /// Cap on `fault`, bytes.
    pub const MAX_FAULT_LEN: usize = 1024;
    /// Wire size with an empty `fault`, bytes.
    pub const MIN_SIZE: usize = 170;
    /// Largest valid wire size, bytes.
    pub const MAX_SIZE: usize = Self::MIN_SIZE + Self::MAX_FAULT_LEN;

    /// The contact mode, decoded from the `mode` byte.
    pub fn mode(&self) -> Result<Mode, ModeError> {
        Mode::try_from(self.mode)
    }

    /// The name of the run state: `starting`, `running`, `safe mode`, `faulted` or `stopped`
    /// (`?` for a byte out of range).
    pub fn state_name(&self) -> &'static str {
        match self.state {
            Status::STARTING => "starting",
            Status::RUNNING => "running",
            Status::SAFE_MODE => "safe mode",
            Status::FAULTED => "faulted",
            Status::STOPPED => "stopped",
            _ => "?",
        }
    }

    /// Sets `fault`, truncated to at most [`Status::MAX_FAULT_LEN`] bytes on a UTF-8 character
    /// boundary, so the message always validates.
    pub fn set_fault(&mut self, fault: &str) {
        let mut end = fault.len().min(Self::MAX_FAULT_LEN);
        while !fault.is_char_boundary(end) {
            end -= 1;
        }
        self.fault.clear();
        self.fault.push_str(&fault[..end]);
    }

    /// Checks every float is finite, `state` in `0..=4`, `mode` in `0..=2` and `fault` is at most
    /// [`Status::MAX_FAULT_LEN`] bytes.
    pub fn validate(&self) -> Result<(), ValidationError> {
        const M: &str = "Status";
        finite(M, "time", self.time)?;
        at_most(
            M,
            "state",
            self.state,
            Self::STOPPED,
            "0..=4 (0 starting, 1 running, 2 safe mode, 3 faulted, 4 stopped)",
        )?;
        at_most(M, "mode", self.mode, 2, MODE_RANGE)?;
        finite(M, "jitter_p50_us", self.jitter_p50_us)?;
        finite(M, "jitter_p99_us", self.jitter_p99_us)?;
        finite(M, "max_overrun_us", self.max_overrun_us)?;
        finite(M, "latency_p50_us", self.latency_p50_us)?;
        finite(M, "latency_p99_us", self.latency_p99_us)?;
        finite(M, "age_p50", self.age_p50)?;
        finite(M, "age_p99", self.age_p99)?;
        finite(M, "age_max", self.age_max)?;
        if self.fault.len() > Self::MAX_FAULT_LEN {
            return Err(ValidationError::TooLong {
                message: M,
                field: "fault",
                len: self.fault.len(),
                max: Self::MAX_FAULT_LEN,
            });
        }
        Ok(())
    }
}

/// Reference trajectory and controller gains, published by the planner; 57 bytes.
///
/// The controller tracks `beta_d(t) = pi/2 + amplitude sin(omega t)` (sinusoid) or
/// `beta_d = pi/2` (hold), or the identification's excitation (a finite Fourier series of
/// amplitude bound `amplitude` and base frequency `omega`, docs/protocol.md), with `v = beta_d_ddot + kd (beta_d_dot - beta_dot) + K_P (beta_d - beta)`,
/// `K_P = kp + k (energy_avg - E(t))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(deny_unknown_fields))]
pub struct Reference {
    /// 0 hold `beta_d = pi/2`, 1 sinusoid, 2 excitation ([`Reference::HOLD`],
    /// [`Reference::SINUSOID`], [`Reference::EXCITATION`]).
    pub kind: u8,
    /// Sinusoid amplitude `A` (the excitation's bound), rad (ignored for hold).
    pub amplitude: f64,
    /// Sinusoid angular frequency `w` (the excitation's base), rad/s; `> 0` for a sinusoid
    /// or an excitation.
    pub omega: f64,
    /// Nominal proportional gain `K_P0`, 1/s²; `>= 0`.
    pub kp: f64,
    /// Derivative gain `K_D`, 1/s; `>= 0`.
    pub kd: f64,
    /// Energy adaptation gain `k`, 1/(J s²); `>= 0` (0 disables adaptation).
    pub k: f64,
    /// Target average energy `E_av`, J.
    pub energy_avg: f64,
    /// Symmetric torque saturation, N·m; `>= 0`, 0 = no limit.
    pub torque_limit: f64,
}

impl Reference {
    /// `kind`: hold `beta_d = pi/2`.
    pub const HOLD: u8 = 0;
    /// `kind`: `beta_d = pi/2 + amplitude sin(omega t)`.
    pub const SINUSOID: u8 = 1;
    /// `kind`: the identification's excitation (`amplitude` bound, base frequency `omega`).
    pub const EXCITATION: u8 = 2;
    /// Exact wire size in bytes.
    pub const SIZE: usize = 57;

    /// Checks `kind` in `0..=2`, every float finite, `kp, kd, k, torque_limit >= 0`, and
    /// `omega > 0` for a sinusoid or an excitation.
    pub fn validate(&self) -> Result<(), ValidationError> {
        const M: &str = "Reference";
        at_most(
            M,
            "kind",
            self.kind,
            Self::EXCITATION,
            "0..=2 (0 hold, 1 sinusoid, 2 excitation)",
        )?;
        finite(M, "amplitude", self.amplitude)?;
        finite(M, "omega", self.omega)?;
        finite(M, "kp", self.kp)?;
        finite(M, "kd", self.kd)?;
        finite(M, "k", self.k)?;
        finite(M, "energy_avg", self.energy_avg)?;
        finite(M, "torque_limit", self.torque_limit)?;
        moving_omega(
            M,
            self.omega,
            self.kind == Self::SINUSOID || self.kind == Self::EXCITATION,
        )?;
        range(M, "kp", self.kp, self.kp >= 0.0, ">= 0 1/s^2")?;
        range(M, "kd", self.kd, self.kd >= 0.0, ">= 0 1/s")?;
        range(M, "k", self.k, self.k >= 0.0, ">= 0 1/(J s^2)")?;
        range(
            M,
            "torque_limit",
            self.torque_limit,
            self.torque_limit >= 0.0,
            ">= 0 N·m (0 = no limit)",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_status_is_a_valid_starting_plant() {
        let s = Status::default();
        assert!(s.validate().is_ok());
        assert_eq!(
            (s.state, s.mode, s.fault.as_str()),
            (Status::STARTING, 0, "")
        );
        assert_eq!(crate::codec::encode(&s).len(), Status::MIN_SIZE);
    }

    #[test]
    fn set_fault_truncates_on_char_boundary() {
        let mut s = Status {
            state: Status::FAULTED,
            ..Status::default()
        };
        s.set_fault("short");
        assert_eq!(s.fault, "short");
        // 'é' is 2 bytes: 1023 ASCII + 'é' would straddle the cap.
        let long = format!("{}é{}", "a".repeat(1023), "b".repeat(100));
        s.set_fault(&long);
        assert_eq!(s.fault.len(), 1023);
        assert!(s.validate().is_ok());
        s.set_fault(&"x".repeat(5000));
        assert_eq!(s.fault.len(), Status::MAX_FAULT_LEN);
        assert!(s.validate().is_ok());
        s.fault.push('x');
        let err = s.validate().unwrap_err();
        assert_eq!(
            err,
            ValidationError::TooLong {
                message: "Status",
                field: "fault",
                len: 1025,
                max: 1024
            }
        );
    }

    #[test]
    fn reference_ranges() {
        let ok = Reference {
            kind: Reference::SINUSOID,
            amplitude: 0.33,
            omega: 5.0,
            kp: 100.0,
            kd: 14.14,
            k: 0.0,
            energy_avg: 30.0,
            torque_limit: 0.0,
        };
        assert!(ok.validate().is_ok());
        // Hold ignores omega's sign but not its finiteness.
        let hold = Reference {
            kind: Reference::HOLD,
            omega: 0.0,
            ..ok
        };
        assert!(hold.validate().is_ok());
        let cases: [(Reference, &str); 7] = [
            (Reference { omega: 0.0, ..ok }, "omega"),
            (Reference { omega: -1.0, ..ok }, "omega"),
            (Reference { kp: -1e-9, ..ok }, "kp"),
            (Reference { kd: -1.0, ..ok }, "kd"),
            (Reference { k: -0.5, ..ok }, "k"),
            (
                Reference {
                    torque_limit: -2.0,
                    ..ok
                },
                "torque_limit",
            ),
            (Reference { kind: 3, ..ok }, "kind"),
        ];
        for (r, field) in cases {
            match r.validate() {
                Err(ValidationError::OutOfRange { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
