//! Hybrid dynamics of the tilting system and its event-exact simulator.
//!
//! A foot plate that lies flat or tilts passively over its left or right edge, with an actuated
//! arm on top (the model and its conventions: `docs/model.md` in the repository). The crate holds:
//! - [`Params`]: masses and lengths, with the paper's defaults;
//! - [`Mode`] and [`State`]: the hybrid state `(q, x)` with `x = (alpha, beta, alpha_dot,
//!   beta_dot)` in rad and rad/s;
//! - [`dynamics`]: equations of motion, ground force, ZMP, inverse dynamics;
//! - [`kinematics`]: positions, energy, angular momentum, the mirror map;
//! - [`impact`]: the landing map with the paper's and the striking-edge law;
//! - [`ode`]: the DOP853 integrator with dense output;
//! - [`hybrid`]: the simulator ([`Plant`]) with event location, impacts and faults;
//! - [`sampled`]: the sampled loop (zero-order hold on a period grid), written once for
//!   `simulate` and the plant node, with the transport of states and torques as a parameter;
//! - [`imperfect`]: what a real robot adds to the model (sensor noise, encoder quantisation,
//!   actuator saturation and lag, a mass error), seeded and off by default;
//! - [`flags`]: the `--params` flag and the `--x0` parser, shared by every command and node;
//! - [`robot_file`]: the robot file's parameter tables, and its keys as the defaults of flags;
//! - [`paper`]: the paper's numbers (the stabilised orbit and its gains), used as defaults everywhere.
//!
//! The model knows nothing of networks; the `node` feature adds the plant node (paced in real
//! time or lockstep over zenoh) behind the `tilting-plant` binary.
//!
//! ```
//! use tilting_plant::{Plant, SimConfig, Mode, State};
//! // Passive tilting: tilted 0.3 rad over the left edge, the arm leaning left and swinging.
//! let x0 = State::new(0.3, 2.0, 0.0, 2.0);
//! let mut plant = Plant::new(SimConfig::default(), 0.0, Mode::Left, x0).unwrap();
//! plant.advance_held(0.0, 0.05, &mut ()).unwrap(); // tau = 0 N m for 50 ms
//! assert!(plant.state()[0] < 0.3); // gravity pulls the plate back down
//! ```

#![warn(missing_docs)]

pub mod dynamics;
pub mod flags;
pub mod hybrid;
pub mod impact;
pub mod imperfect;
pub mod kinematics;
pub mod mode;
#[cfg(feature = "node")]
pub mod node;
pub mod ode;
pub mod paper;
pub mod params;
pub mod robot_file;
pub mod safe;
pub mod sampled;

pub use dynamics::Joint;
pub use flags::{parse_x0, ParamsArgs};
pub use hybrid::{Fault, JointEvent, Observer, Plant, SimConfig, TiltPeak, TorqueLaw, Transition};
pub use impact::{ImpactLaw, Landing, REBOUND_MIN_SPEED};
pub use kinematics::{energy, mirror};
pub use mode::Mode;
pub use ode::Tolerance;
pub use params::{ConfigError, Params};

/// Continuous state `x = (alpha, beta, alpha_dot, beta_dot)`: plate tilt angle (rad, counter-
/// clockwise positive), arm angle relative to the plate (rad, `pi/2` upright) and their rates
/// (rad/s).
pub type State = nalgebra::Vector4<f64>;
