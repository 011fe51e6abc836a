//! The flags of `tilting simulate` that say what to run (feature `clap`): the scenario, the
//! network, the robot's imperfections, the loop options and the safe mode, and the checked
//! [`Scenario`] and [`SimOptions`] they make. The front door adds its output flags (`--json`,
//! `--plot`, `--record`); the Python package parses the keyword arguments of
//! `tilting.simulate` with the same struct, so both take the same options and give the same
//! messages.

use crate::{Impairment, LoopArgs, NetworkArgs, Scenario, ScenarioArgs, SimOptions};
use tilting_plant::imperfect::ImperfectArgs;

/// What `simulate` runs.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SimulateArgs {
    /// The scenario.
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// An impaired network between plant and controller (sampled loop only).
    #[command(flatten)]
    pub network: NetworkArgs,
    /// The robot's imperfections (sensor noise, encoder, actuator saturation and lag, arm-mass
    /// error); the noise draws from --seed (its own stream).
    #[command(flatten)]
    pub imperfect: ImperfectArgs,
    /// With an impaired network: the oldest torque the plant applies (periods between the state
    /// it answers and the current one), as the plant's --max-age
    #[arg(long, default_value_t = 10, value_name = "PERIODS")]
    pub max_age: u64,
    /// Prediction and sampling on events (sampled loop only).
    #[command(flatten)]
    pub loop_args: LoopArgs,
    /// The plant's watchdog and safe mode, modelled over an impaired network or with
    /// prediction (a run in which no valid torque arrives ends in safe mode, as the plant's).
    #[command(flatten)]
    pub safe: tilting_plant::safe::SafeArgs,
}

/// An invalid flag: its message names the flag and the allowed range.
pub type FlagError = Box<dyn std::error::Error + Send + Sync>;

impl SimulateArgs {
    /// The scenario and the options of the run, checked; `record_samples` keeps the
    /// (decimated) trajectory.
    pub fn prepare(&self, record_samples: bool) -> Result<(Scenario, SimOptions), FlagError> {
        let sc = self.scenario.load()?;
        let mut network = self.network.impairment(self.max_age)?;
        let mut loop_options = self.loop_args.options();
        if !loop_options.is_plain() && network.is_none() {
            // Prediction or sampling on events over a perfect network: the plant's age rule is
            // still --max-age.
            network = Some(Impairment {
                max_age: self.max_age,
                ..Default::default()
            });
        }
        loop_options.safe = Some(self.safe.settings()?);
        let imperfect = self.imperfect.imperfections(self.network.seed)?;
        let opts = SimOptions {
            record_samples,
            network,
            loop_options,
            imperfect,
            log_measurements: false,
        };
        Ok((sc, opts))
    }
}
