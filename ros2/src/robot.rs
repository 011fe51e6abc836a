//! The tilting robot as ROS 2 messages: its topics, joint names, the contact mode, log lines for
//! events, faults and the safe mode, and the checks on an effort command arriving over ROS 2.
//!
//! Topics (namespace `/<robot>`):
//!
//! | topic | type | QoS | from |
//! |---|---|---|---|
//! | `/<robot>/joint_states` | `sensor_msgs/msg/JointState` | reliable, keep last 10 | every `PlantState` |
//! | `/<robot>/contact_mode` | `std_msgs/msg/UInt8` (0 flat, 1 left, 2 right) | reliable, keep last 10 | every `PlantState` |
//! | `/rosout` | `rcl_interfaces/msg/Log` | reliable, keep last 1000 | events, status changes |
//! | `/<robot>/effort_command` (subscribed) | `std_msgs/msg/Float64MultiArray`, one value: the arm torque (N m) | best effort, keep last 1 | a ROS 2 controller |

use crate::attachment::{Attachment, AttachmentError};
use crate::msgs::{self, CdrError, Float64MultiArray, Header, JointState, Log, Time};
use crate::names::Qos;
use tilting_proto::{Mode, ModeEvent, PlantState, Status};

/// The joints of [`JointState::name`], in order: the plate's tilt about its left edge (rad,
/// counter-clockwise, `>= 0`; zero unless tilted left), about its right edge (rad, `<= 0`; zero
/// unless tilted right), and the arm relative to the plate (`beta`, rad, `pi/2` upright). The
/// URDF ([`crate::urdf`]) has the same three revolute joints in a chain.
pub const JOINT_NAMES: [&str; 3] = ["left_edge", "right_edge", "arm"];

/// Index of the arm in [`JOINT_NAMES`] (the only actuated joint).
pub const ARM: usize = 2;

/// QoS of `joint_states`: reliable keep-last 10, what joint_state_publisher offers and
/// robot_state_publisher asks for (an offer every subscription accepts).
pub const JOINT_STATES_QOS: Qos = Qos::reliable(10);
/// QoS of `contact_mode`.
pub const CONTACT_MODE_QOS: Qos = Qos::reliable(10);
/// QoS of `/rosout` (rcl's depth; volatile: no late-joiner cache).
pub const ROSOUT_QOS: Qos = Qos::reliable(1000);
/// QoS of the `effort_command` subscription.
pub const EFFORT_QOS: Qos = Qos::best_effort(1);

/// The topic names of one robot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topics {
    /// `/<robot>`: the nodes' namespace.
    pub namespace: String,
    /// `/<robot>/joint_states`.
    pub joint_states: String,
    /// `/<robot>/contact_mode`.
    pub contact_mode: String,
    /// `/<robot>/effort_command`.
    pub effort_command: String,
    /// `/rosout`.
    pub rosout: String,
}

impl Topics {
    /// The topics of `robot`, which must also be a valid ROS 2 name
    /// ([`crate::names::validate_ros_name`]: no `-`, no leading digit).
    pub fn new(robot: &str) -> Result<Topics, String> {
        crate::names::validate_ros_name(robot)
            .map_err(|e| format!("--robot with --ros2 is a ROS 2 namespace: {e}"))?;
        Ok(Topics {
            namespace: format!("/{robot}"),
            joint_states: format!("/{robot}/joint_states"),
            contact_mode: format!("/{robot}/contact_mode"),
            effort_command: format!("/{robot}/effort_command"),
            rosout: "/rosout".into(),
        })
    }
}

/// Splits the plate's tilt `alpha` over the two edge joints by the contact mode.
fn edges(mode: Option<Mode>, alpha: f64) -> [f64; 2] {
    match mode {
        Some(Mode::Left) => [alpha, 0.0],
        Some(Mode::Right) => [0.0, alpha],
        _ => [0.0, 0.0],
    }
}

/// The `JointState` of a plant state: stamp = the state's plant time; positions and (when both
/// are measured) velocities of [`JOINT_NAMES`]; efforts `[0, 0, tau]` when the torque in force is
/// known, else empty.
pub fn joint_state(s: &PlantState, tau: Option<f64>) -> JointState {
    let mode = s.mode().ok();
    let [l, r] = edges(mode, s.alpha);
    JointState {
        header: Header {
            stamp: Time::from_secs(s.time),
            frame_id: String::new(),
        },
        name: JOINT_NAMES.iter().map(|n| (*n).to_owned()).collect(),
        position: vec![l, r, s.beta],
        velocity: match s.rates() {
            Some([ad, bd]) => {
                let [lv, rv] = edges(mode, ad);
                vec![lv, rv, bd]
            }
            None => Vec::new(),
        },
        effort: tau.map(|t| vec![0.0, 0.0, t]).unwrap_or_default(),
    }
}

fn mode_name(m: u8) -> &'static str {
    match Mode::try_from(m) {
        Ok(Mode::Flat) => "flat",
        Ok(Mode::Left) => "left",
        Ok(Mode::Right) => "right",
        Err(_) => "?",
    }
}

fn log(stamp_ns: i64, level: u8, logger: &str, msg: String) -> Log {
    Log {
        stamp: Time::from_ns(stamp_ns),
        level,
        name: logger.to_owned(),
        msg,
        file: String::new(),
        function: String::new(),
        line: 0,
    }
}

/// The `/rosout` line of a mode transition (INFO), stamped `stamp_ns` (wall clock, ns).
pub fn event_log(robot: &str, e: &ModeEvent, stamp_ns: i64) -> Log {
    log(
        stamp_ns,
        Log::INFO,
        &logger(robot),
        format!(
            "mode {} -> {} at t = {:.6} s (seq {})",
            mode_name(e.from),
            mode_name(e.to),
            e.time,
            e.seq
        ),
    )
}

/// The `/rosout` line of a status whose run state differs from `previous` (none when it is the
/// same): entering the safe mode WARN, a fault ERROR, running / stopped INFO.
pub fn status_log(robot: &str, previous: Option<u8>, s: &Status, stamp_ns: i64) -> Option<Log> {
    if previous == Some(s.state) {
        return None;
    }
    let (level, msg) = match s.state {
        Status::SAFE_MODE => (
            Log::WARN,
            format!(
                "safe mode at t = {:.3} s (seq {}): no valid torque in time",
                s.time, s.seq
            ),
        ),
        Status::FAULTED => (
            Log::ERROR,
            format!("fault at t = {:.3} s (seq {}): {}", s.time, s.seq, s.fault),
        ),
        Status::RUNNING if previous == Some(Status::SAFE_MODE) => (
            Log::INFO,
            format!("left safe mode at t = {:.3} s (seq {})", s.time, s.seq),
        ),
        _ => (
            Log::INFO,
            format!(
                "plant {} at t = {:.3} s (seq {})",
                s.state_name(),
                s.time,
                s.seq
            ),
        ),
    };
    Some(log(stamp_ns, level, &logger(robot), msg))
}

/// The logger name of the robot's lines: `<robot>.tilting_plant`.
pub fn logger(robot: &str) -> String {
    format!("{robot}.tilting_plant")
}

/// The bounds an effort command must meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffortLimits {
    /// Largest torque magnitude, N m (the plant's `--max-torque`).
    pub max_torque: f64,
    /// Largest age (receive time minus the attachment's source timestamp), ns: the plant's
    /// `--max-age` periods.
    pub max_age_ns: i64,
    /// Largest lead of the source timestamp over the receive time (clock skew), ns.
    pub max_lead_ns: i64,
}

/// Why an effort command was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Refusal {
    /// No or a malformed attachment.
    #[error("effort_command: {0}")]
    Attachment(#[from] AttachmentError),
    /// DDS: the sample carries no source timestamp (the writer sent no INFO_TS).
    #[error("effort_command has no source timestamp; allowed: a sample stamped by its writer (DDS INFO_TS)")]
    NoTimestamp,
    /// The payload is not a `Float64MultiArray`.
    #[error("effort_command: {0}")]
    Cdr(#[from] CdrError),
    /// Not exactly one value.
    #[error("effort_command.data has {0} values; allowed: exactly 1 (the arm torque, N m)")]
    Length(usize),
    /// NaN or infinite.
    #[error("effort_command.data[0] = {0} is not finite; allowed: a finite torque, N m")]
    NotFinite(f64),
    /// Beyond `--max-torque`.
    #[error("effort_command.data[0] = {value} N m; allowed: |tau| <= {max} N m (--max-torque)")]
    Beyond {
        /// The value.
        value: f64,
        /// The bound.
        max: f64,
    },
    /// Older than the age bound.
    #[error("effort_command is {age_ns} ns old (attachment source timestamp); allowed: at most {max_ns} ns (--max-age periods)")]
    Stale {
        /// Age, ns.
        age_ns: i64,
        /// Bound, ns.
        max_ns: i64,
    },
    /// From the future.
    #[error("effort_command source timestamp is {lead_ns} ns in the future; allowed: at most {max_ns} ns")]
    Future {
        /// Lead, ns.
        lead_ns: i64,
        /// Bound, ns.
        max_ns: i64,
    },
    /// More commands than the flood gate lets through.
    #[error("effort_command flood: more than {0} commands per second (burst {1}); allowed: fewer")]
    Flood(u32, u32),
}

/// A valid effort command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffortCommand {
    /// Arm torque, N m.
    pub tau: f64,
    /// Its attachment (source timestamp, publisher).
    pub attachment: Attachment,
}

/// Checks an effort command: the attachment, the CDR payload, one finite value within
/// `max_torque`, and the age of the source timestamp against `now_ns` (wall clock, ns).
pub fn check_effort(
    payload: &[u8],
    attachment: Option<&[u8]>,
    now_ns: i64,
    limits: &EffortLimits,
) -> Result<EffortCommand, Refusal> {
    let attachment = Attachment::decode(attachment)?;
    let m: Float64MultiArray = msgs::decode(payload, &msgs::FLOAT64_MULTI_ARRAY)?;
    check_command(&m, attachment, now_ns, limits)
}

/// The checks of [`check_effort`] on a command already decoded (DDS decodes it, and gives the
/// attachment's parts as sample info): one finite value within `max_torque`, and the age of the
/// source timestamp against `now_ns`.
pub fn check_command(
    m: &Float64MultiArray,
    attachment: Attachment,
    now_ns: i64,
    limits: &EffortLimits,
) -> Result<EffortCommand, Refusal> {
    let [tau] = m.data[..] else {
        return Err(Refusal::Length(m.data.len()));
    };
    if !tau.is_finite() {
        return Err(Refusal::NotFinite(tau));
    }
    if tau.abs() > limits.max_torque {
        return Err(Refusal::Beyond {
            value: tau,
            max: limits.max_torque,
        });
    }
    let age = now_ns.saturating_sub(attachment.source_timestamp_ns);
    if age > limits.max_age_ns {
        return Err(Refusal::Stale {
            age_ns: age,
            max_ns: limits.max_age_ns,
        });
    }
    if -age > limits.max_lead_ns {
        return Err(Refusal::Future {
            lead_ns: -age,
            max_ns: limits.max_lead_ns,
        });
    }
    Ok(EffortCommand { tau, attachment })
}

/// The state sample an effort command answers: the newest state published at or before its
/// source timestamp, given the newest state `seq` published at `published_ns` (wall clock) and
/// the period `period_ns` (states before `seq` were published one period apart).
pub fn answered_seq(source_ns: i64, seq: u64, published_ns: i64, period_ns: i64) -> u64 {
    let behind = published_ns.saturating_sub(source_ns);
    if behind <= 0 || period_ns <= 0 {
        return seq;
    }
    let periods = (behind + period_ns - 1) / period_ns;
    seq.saturating_sub(periods as u64)
}

/// A token bucket: at most `burst` commands at once and `rate` per second on average.
#[derive(Debug, Clone)]
pub struct FloodGate {
    rate: u32,
    burst: u32,
    tokens: f64,
    last_ns: Option<i64>,
}

impl FloodGate {
    /// A gate passing `rate` commands per second with bursts of `burst`.
    pub fn new(rate: u32, burst: u32) -> Self {
        Self {
            rate,
            burst,
            tokens: f64::from(burst),
            last_ns: None,
        }
    }

    /// Lets one command through at `now_ns` (monotonic or wall, ns), or refuses it.
    pub fn admit(&mut self, now_ns: i64) -> Result<(), Refusal> {
        if let Some(last) = self.last_ns {
            let dt = now_ns.saturating_sub(last).max(0) as f64 * 1e-9;
            self.tokens = (self.tokens + dt * f64::from(self.rate)).min(f64::from(self.burst));
        }
        self.last_ns = Some(now_ns);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            Ok(())
        } else {
            Err(Refusal::Flood(self.rate, self.burst))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{encode, MultiArrayLayout};

    const LIMITS: EffortLimits = EffortLimits {
        max_torque: 10.0,
        max_age_ns: 5_000_000,
        max_lead_ns: 5_000_000,
    };

    fn cmd(data: Vec<f64>) -> Vec<u8> {
        encode(&Float64MultiArray {
            layout: MultiArrayLayout::default(),
            data,
        })
    }

    fn att(ts: i64) -> [u8; 33] {
        Attachment {
            seq: 1,
            source_timestamp_ns: ts,
            gid: [7; 16],
        }
        .encode()
    }

    #[test]
    fn effort_checks_name_what_is_wrong() {
        let now = 1_000_000_000_000;
        let ok = check_effort(&cmd(vec![1.5]), Some(&att(now - 1000)), now, &LIMITS).unwrap();
        assert_eq!(ok.tau, 1.5);
        let refuse = |p: Vec<u8>, a: Option<&[u8]>| check_effort(&p, a, now, &LIMITS).unwrap_err();
        assert_eq!(
            refuse(cmd(vec![1.5]), None),
            Refusal::Attachment(AttachmentError::Missing)
        );
        assert_eq!(
            refuse(cmd(vec![1.0, 2.0]), Some(&att(now))),
            Refusal::Length(2)
        );
        assert_eq!(refuse(cmd(vec![]), Some(&att(now))), Refusal::Length(0));
        assert!(
            matches!(refuse(cmd(vec![f64::NAN]), Some(&att(now))), Refusal::NotFinite(v) if v.is_nan())
        );
        assert!(matches!(
            refuse(cmd(vec![11.0]), Some(&att(now))),
            Refusal::Beyond { .. }
        ));
        assert!(matches!(
            refuse(cmd(vec![1.0]), Some(&att(now - 5_000_001))),
            Refusal::Stale { .. }
        ));
        assert!(matches!(
            refuse(cmd(vec![1.0]), Some(&att(now + 5_000_001))),
            Refusal::Future { .. }
        ));
        assert!(check_effort(&cmd(vec![1.0]), Some(&att(now - 5_000_000)), now, &LIMITS).is_ok());
        assert!(matches!(
            refuse(vec![0, 1, 0, 0, 1], Some(&att(now))),
            Refusal::Cdr(_)
        ));
        assert!(refuse(cmd(vec![1.0]), None)
            .to_string()
            .contains("attachment"));
    }

    #[test]
    fn the_answered_state_is_the_newest_published_before_the_source_time() {
        let h = 1_000_000;
        assert_eq!(answered_seq(10 * h + 1, 10, 10 * h, h), 10);
        assert_eq!(answered_seq(10 * h, 10, 10 * h, h), 10);
        assert_eq!(answered_seq(10 * h - 1, 10, 10 * h, h), 9);
        assert_eq!(answered_seq(8 * h, 10, 10 * h, h), 8);
        assert_eq!(answered_seq(0, 3, 10 * h, h), 0);
    }

    #[test]
    fn the_flood_gate_passes_the_rate_and_the_burst() {
        let mut g = FloodGate::new(1000, 4);
        for _ in 0..4 {
            assert!(g.admit(0).is_ok());
        }
        assert!(g.admit(0).is_err());
        // One token back per ms.
        assert!(g.admit(1_000_000).is_ok());
        assert!(g.admit(1_000_000).is_err());
        // Sustained 1 kHz passes forever.
        let mut g = FloodGate::new(1000, 4);
        assert!((0..10_000).all(|k| g.admit(k * 1_000_000).is_ok()));
    }

    #[test]
    fn joint_states_split_the_tilt_by_mode() {
        let mut s = PlantState::full(0, 0.5, [0.1, 1.2, 0.3, -0.4], Mode::Left.as_u8());
        let j = joint_state(&s, Some(2.0));
        assert_eq!(j.position, vec![0.1, 0.0, 1.2]);
        assert_eq!(j.velocity, vec![0.3, 0.0, -0.4]);
        assert_eq!(j.effort, vec![0.0, 0.0, 2.0]);
        assert_eq!(
            j.header.stamp,
            Time {
                sec: 0,
                nanosec: 500_000_000
            }
        );
        s.mode = Mode::Right.as_u8();
        s.alpha = -0.1;
        assert_eq!(joint_state(&s, None).position, vec![0.0, -0.1, 1.2]);
        assert!(joint_state(&s, None).effort.is_empty());
        s.alpha_dot = None;
        assert!(joint_state(&s, None).velocity.is_empty());
    }
}
