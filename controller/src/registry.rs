//! The laws a controller builds from the planner's message: [`LawRegistry`], a law's name to a
//! constructor from its parameters ([`tilting_proto::LawReference`], protocol 3, or the paper
//! law's [`tilting_proto::Reference`] in its generic form).
//!
//! The paper's law (`computed-torque`) is built as before ([`ControlConfig::from_wire`], with the
//! controller's own robust option and orbit start, then [`Controller::new`]); every other law is
//! a [`PlannableLaw`] registered by a prototype: the message's parameters go through its
//! [`PlannableLaw::with_parameters`] with the controller's model (`--params`) and its
//! trajectory through [`PlannableLaw::with_trajectory`], both checked by the law, naming the
//! parameter. The law runs as [`Controller::Registered`].
//!
//! **Adding a law** touches two non-test files: its module, `controller/src/registry/NAME.rs`,
//! a [`PlannableLaw`]; and this file, `mod NAME;` and its `.register(...)` line in
//! [`LawRegistry::builtin`]. The planner plans it through the trait, and it crosses the wire as
//! a `LawReference` with no change to the protocol (`planner/tests/planner/toy_law.rs` does
//! all three with a toy plain PD).
//!
//! ```
//! use tilting_controller::registry::LawRegistry;
//! use tilting_controller::LawSpec;
//! use tilting_plant::Params;
//! use tilting_proto::{LawReference, Reference};
//! let registry = LawRegistry::builtin();
//! assert_eq!(registry.names(), ["computed-torque"]);
//! let paper = LawReference {
//!     trajectory: Reference::HOLD,
//!     amplitude: 0.0,
//!     omega: 0.0,
//!     law: "computed-torque".into(),
//!     parameters: vec![100.0, 14.14, 500.0, 20.0, 0.0],
//! };
//! let law = registry.build(&Params::default(), &LawSpec::default(), &paper).unwrap();
//! assert_eq!(law.config().law.k, 500.0);
//! // An unknown law, or a bad parameter, is refused by name.
//! let e = registry
//!     .build(&Params::default(), &LawSpec::default(), &LawReference { law: "pid".into(), ..paper.clone() })
//!     .unwrap_err();
//! assert!(e.to_string().contains("`law` = pid"), "{e}");
//! let e = registry
//!     .build(&Params::default(), &LawSpec::default(), &LawReference { parameters: vec![100.0, -1.0, 0.0, 0.0, 0.0], ..paper })
//!     .unwrap_err();
//! assert!(e.to_string().contains("kd"), "{e}");
//! ```

use crate::plannable::{check_count, COMPUTED_TORQUE_PARAMETERS};
use crate::{ControlConfig, Controller, LawSpec, PlannableLaw, Trajectory};
use std::sync::Arc;
use tilting_plant::dynamics::Terms;
use tilting_plant::{ConfigError, Mode, Params, State, TorqueLaw};
use tilting_proto::LawReference;

/// Builds a law from the controller's model, its own settings that are not on the wire (the
/// robust option, the orbit start) and a message.
type Build =
    dyn Fn(&Params, &LawSpec, &LawReference) -> Result<Controller, ConfigError> + Send + Sync;

/// A law's name and how to build it.
#[derive(Clone)]
struct Entry {
    name: &'static str,
    build: Arc<Build>,
}

/// The laws a controller can build from a message, by name.
#[derive(Clone)]
pub struct LawRegistry {
    entries: Vec<Entry>,
}

impl std::fmt::Debug for LawRegistry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LawRegistry")
            .field("names", &self.names())
            .finish()
    }
}

impl Default for LawRegistry {
    /// [`LawRegistry::builtin`].
    fn default() -> Self {
        Self::builtin()
    }
}

impl LawRegistry {
    /// The laws of this build: the paper's, then one `.register(...)` line per law.
    pub fn builtin() -> Self {
        Self::paper()
    }

    /// The paper's law only (`computed-torque`).
    pub fn paper() -> Self {
        Self {
            entries: vec![Entry {
                name: LawReference::PAPER_LAW,
                build: Arc::new(build_paper),
            }],
        }
    }

    /// This registry with the law of `prototype` under its [`PlannableLaw::name`] (replacing
    /// a law of that name): a message's parameters become `prototype.with_parameters(model,
    /// parameters)` and its trajectory [`PlannableLaw::with_trajectory`].
    pub fn register<L: PlannableLaw + 'static>(mut self, prototype: L) -> Self {
        let name = prototype.name();
        self.entries.retain(|e| e.name != name);
        self.entries.push(Entry {
            name,
            build: Arc::new(move |model, _local, r| {
                let law = prototype
                    .with_parameters(model, &r.parameters)?
                    .with_trajectory(trajectory(r))?;
                Ok(Controller::Registered(RegisteredLaw::new(
                    law,
                    trajectory(r),
                )))
            }),
        });
        self
    }

    /// The names of the laws, in registration order.
    pub fn names(&self) -> Vec<&'static str> {
        self.entries.iter().map(|e| e.name).collect()
    }

    /// The law a message names, with the controller's model `model` and its own settings
    /// `local` (only the paper's law reads them: `orbit_peak`, `orbit_start`,
    /// `orbit_steepness`); checked, naming the bad field: `law` for a name not registered,
    /// `parameters` for a list of the wrong length, else the law's parameter.
    pub fn build(
        &self,
        model: &Params,
        local: &LawSpec,
        r: &LawReference,
    ) -> Result<Controller, ConfigError> {
        let entry = self
            .entries
            .iter()
            .find(|e| e.name == r.law)
            .ok_or_else(|| ConfigError::OutOfRange {
                field: "law",
                value: format!(
                    "{} (this controller has {})",
                    r.law,
                    self.names().join(", ")
                ),
                allowed: "the name of a law in the controller's registry",
            })?;
        (entry.build)(model, local, r)
    }
}

/// The trajectory of a message.
fn trajectory(r: &LawReference) -> Trajectory {
    crate::wire::trajectory_of(r.trajectory, r.amplitude, r.omega)
}

/// The paper's law: the protocol-2 message of its five parameters, as the controller has
/// always read it ([`ControlConfig::from_wire`]: ranges and bounds), with the controller's own
/// robust option and orbit.
fn build_paper(
    model: &Params,
    local: &LawSpec,
    r: &LawReference,
) -> Result<Controller, ConfigError> {
    check_count(&COMPUTED_TORQUE_PARAMETERS, &r.parameters)?;
    let paper = r.to_paper().ok_or(ConfigError::OutOfRange {
        field: "law",
        value: r.law.clone(),
        allowed: "computed-torque",
    })?;
    let mut cfg = ControlConfig::from_wire(*model, &paper)?;
    cfg.law.orbit_peak = local.orbit_peak;
    cfg.law.orbit_start = local.orbit_start;
    cfg.law.orbit_steepness = local.orbit_steepness;
    Controller::new(cfg)
}

/// A law of the registry other than the paper's, ready to run: its name, its parameters and
/// its torque (a [`PlannableLaw`], type-erased). Two are equal when their names, parameters,
/// model and trajectory are ([`PlannableLaw`]'s contract: those fix the torque).
#[derive(Clone)]
pub struct RegisteredLaw {
    name: &'static str,
    parameters: Vec<(&'static str, f64)>,
    config: ControlConfig,
    law: Arc<dyn TorqueLaw + Send + Sync>,
}

impl RegisteredLaw {
    /// `law` tracking `trajectory`, type-erased.
    pub fn new<L: PlannableLaw + 'static>(law: L, trajectory: Trajectory) -> Self {
        // The model and the trajectory; the paper's gains are not this law's: all zero.
        let config = ControlConfig::new(
            *law.model(),
            LawSpec {
                kp: 0.0,
                kd: 0.0,
                reference: trajectory,
                ..LawSpec::without_adaptation()
            },
        );
        Self {
            name: law.name(),
            parameters: law.parameters(),
            config,
            law: Arc::new(law),
        }
    }

    /// The law's name ([`PlannableLaw::name`]).
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// The law's parameters ([`PlannableLaw::parameters`]).
    pub fn parameters(&self) -> &[(&'static str, f64)] {
        &self.parameters
    }

    /// The model and the trajectory (the paper law's gains in it are zero: they are not this
    /// law's).
    pub fn config(&self) -> &ControlConfig {
        &self.config
    }

    /// The name and the parameters, for a node's summary.
    pub fn summary(&self) -> RegisteredSummary {
        RegisteredSummary {
            name: self.name.to_owned(),
            parameters: self
                .parameters
                .iter()
                .map(|&(n, v)| (n.to_owned(), v))
                .collect(),
        }
    }
}

/// A registered law in a node's summary (JSON): its name and its parameters by name, in the
/// law's order.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegisteredSummary {
    /// The law's name ([`PlannableLaw::name`]).
    pub name: String,
    /// `(name, value)` in the order of [`PlannableLaw::parameters`], each in the law's unit.
    pub parameters: Vec<(String, f64)>,
}

impl PartialEq for RegisteredLaw {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
            && self.parameters == other.parameters
            && self.config == other.config
    }
}

impl std::fmt::Debug for RegisteredLaw {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RegisteredLaw")
            .field("name", &self.name)
            .field("parameters", &self.parameters)
            .field("reference", &self.config.law.reference)
            .finish()
    }
}

impl TorqueLaw for RegisteredLaw {
    #[inline]
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        self.law.torque(t, mode, x)
    }

    #[inline]
    fn torque_t(&self, t: f64, mode: Mode, x: &State, params: &Params, terms: &Terms) -> f64 {
        self.law.torque_t(t, mode, x, params, terms)
    }
}
