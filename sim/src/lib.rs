//! The offline closed loop of the tilting system: the hybrid plant (`tilting-plant`) and the
//! computed-torque controller (`tilting-controller`) coupled in one process, as the `simulate`
//! command, the sweeps and the figures run them.
//!
//! - [`scenario`]: what to run (model, start, controller, coupling, run length), its TOML file
//!   and command-line flags, and validation that names the offending field and its range;
//! - [`robot`] (feature `clap`): the robot file, one TOML file for a robot and how it runs,
//!   checked key by key, whose keys are the defaults of the commands' flags;
//! - [`closed_loop`]: the two couplings ([`run_continuous`]: the law inside the right-hand
//!   side, the paper's setting; [`run_sampled`]: a zero-order hold at `t_k = k T`, the code a
//!   lockstep plant node reproduces bit for bit) and [`simulate`], which runs a scenario and
//!   reports its transitions, tilt peaks, final state and fault.
//!
//! The plant node and the controller node do not depend on this crate: the sampled loops here
//! are transports of the stepper the plant node runs too
//! ([`tilting_plant::sampled`]), with the same
//! [`ComputedTorque`](tilting_controller::ComputedTorque), which is why a lockstep run over
//! zenoh equals `simulate --control-period T` bit for bit (tested in `tests/`).
//!
//! ```
//! use tilting_sim::{simulate, Scenario, SimOptions};
//! // The paper's stabilised orbit (the default scenario), 2 s under continuous coupling.
//! let sc = Scenario { duration: 2.0, ..Scenario::default() };
//! let report = simulate(&sc, SimOptions::default()).unwrap();
//! assert!(report.fault.is_none());
//! assert!(report.stats.tilts >= 4); // a tilt every half period, 0.435 s
//! ```

#![warn(missing_docs)]

pub mod closed_loop;
#[cfg(feature = "clap")]
pub mod flags;
pub mod network;
pub mod recording;
#[cfg(feature = "clap")]
pub mod robot;
pub mod robustness;
pub mod scenario;

pub use closed_loop::{
    run_continuous, run_sampled, simulate, simulate_with, simulate_with_progress, SimOptions,
    SimulationReport,
};
pub use network::{run_sampled_over, Impairment, LoopOptions, NetStats, Predict};
#[cfg(feature = "clap")]
pub use network::{LoopArgs, NetworkArgs};
#[cfg(feature = "clap")]
pub use scenario::ScenarioArgs;
pub use scenario::{Scenario, ScenarioError, ScenarioFile};
