//! A Foxglove WebSocket server for a tilting robot (`tilting live --foxglove`, `tilting view`,
//! `tilting replay --foxglove`), on Foxglove's official SDK (the `foxglove` crate).
//!
//! It serves, for robot `NAME` ([`Server`], channel names `/` + key):
//!
//! - the five topics (`/tilting/NAME/plant/state`, ...) as JSON with the JSON Schemas named
//!   `tilting.<MessageType>`: byte for byte the JSON channels of our MCAP files
//!   (`tilting_record::schema`), so a layout made on a recording works live;
//! - `/tilting/NAME/energy`: `{time, energy}` (JSON, schema `tilting.Energy`), the model's total
//!   energy of each state that carries its rates;
//! - `/tilting/NAME/plot`: alpha, beta, the torque, the energy and the adapted gain decimated to
//!   50 ticks a second of plant time, each tick's least and greatest sample (JSON, schema
//!   `tilting.Plot`, [`plot`]): what the layout's plot panels read, since a plot panel cannot
//!   keep up with 1 kHz;
//! - `/tilting/NAME/tf`: `foxglove.FrameTransforms`, the frames `plate` and `arm` of each state
//!   ([`scene`]);
//! - `/tilting/NAME/scene`: `foxglove.SceneUpdate`, the plate, the arm, the pivot edge, a title
//!   stating the tilt exaggeration, and a landing flash ([`scene`]);
//! - `/tilting/NAME/log`: `foxglove.Log`, the mode transitions (info), safe mode (warning),
//!   faults (error) and payloads that did not decode (warning).
//!
//! The network's callbacks hand payloads to a [`Feed`], a bounded queue that drops its oldest
//! message when full and never waits ([`queue`]); one thread publishes from it into the SDK,
//! whose server keeps a bounded backlog per client and drops its oldest messages too. Nothing
//! on the robot's path ever waits for a WebSocket.
//!
//! Viewers connect to a handshake [`front`] that admits the protocol's old name
//! `foxglove.websocket.v1` (Foxglove Studio 1.48, Lichtblick up to 1.22.0), which the SDK's
//! server refuses, and relays to that server on a loopback port of its own.
//!
//! The address must be loopback unless the caller consents ([`Options::any`]); a port in use
//! is a clear [`StartError`]. Channel log times are plant time (ns, as in our MCAP files); a log
//! entry's own timestamp is the wall clock, and its text names the plant time.

#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod front;
pub mod plot;
pub mod queue;
pub mod scene;
pub mod server;

pub use queue::{Feed, Item};
pub use server::{check_addr, Counts, Options, Server, StartError, DEFAULT_ADDR};
