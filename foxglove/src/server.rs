//! [`Server`]: the Foxglove WebSocket server (the SDK's) and the thread that publishes into it.

use crate::front::Front;
use crate::plot::{self, Decimator, Field};
use crate::queue::{self, Drain, Feed, Item};
use crate::scene;
use foxglove::messages::{log::Level, FrameTransforms, Log, SceneEntity, SceneUpdate};
use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Channel, ChannelBuilder, Context, PartialMetadata, RawChannel, Schema};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use tilting_plant::{Mode, Params, State};
use tilting_proto::{
    codec, AnyReference, Keys, ModeEvent, PlantState, Reference, Status, Topic, TorqueCommand,
};
use tilting_record::schema::{json_schema, schema_name, to_json};

/// The default address: loopback, Foxglove's default port.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// Messages queued for the publisher at most (about 1 s of a 1 kHz robot's five topics).
pub const QUEUE: usize = 4096;

/// Plant time between two scene updates (s): 20 per second, and at every mode change.
const SCENE_PERIOD: f64 = 0.05;

/// What the server serves, and where.
#[derive(Debug, Clone)]
pub struct Options {
    /// The address to listen on (port 0: a free port).
    pub addr: SocketAddr,
    /// Allow an address that is not loopback (it serves the robot to the network).
    pub any: bool,
    /// The robot's keys (channel names are `/` + key).
    pub keys: Keys,
    /// The robot's geometry and masses (for the scene and the energy).
    pub params: Params,
    /// The tilt's exaggeration in the scene (display only; 1 is to scale).
    pub exaggeration: f64,
}

/// Why the server did not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// A non-loopback address without consent.
    #[error(
        "invalid `--foxglove` = {0}: not a loopback address; serving the robot to the network \
         needs --foxglove-any"
    )]
    NotLoopback(SocketAddr),
    /// The address is taken or not ours.
    #[error("cannot serve Foxglove on {addr}: {cause}{hint}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The cause.
        cause: std::io::Error,
        /// A hint for a port in use.
        hint: &'static str,
    },
    /// A bad tilt exaggeration.
    #[error("{0}")]
    Exaggeration(String),
    /// Anything else the SDK reports.
    #[error("cannot start the Foxglove server: {0}")]
    Sdk(String),
}

/// Counters of a server's life.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Messages published on the five topics' channels.
    pub published: u64,
    /// Payloads that did not decode and validate (not published).
    pub invalid: u64,
    /// Messages dropped because the publisher fell behind (oldest first).
    pub dropped: u64,
    /// Scene updates published.
    pub scenes: u64,
    /// Log entries published.
    pub logs: u64,
    /// Clients that connected.
    pub clients: u64,
}

/// A running server: feed it the robot's messages with [`Server::feed`].
pub struct Server {
    /// The SDK's context of the channels (the server holds it weakly: it lives here).
    _ctx: Arc<Context>,
    handle: foxglove::WebSocketServerHandle,
    /// The viewers' address, in front of the SDK's server.
    front: Front,
    feed: Feed,
    drain: Arc<Drain>,
    thread: Option<JoinHandle<Counts>>,
    listener: Arc<Listener>,
    addr: SocketAddr,
}

/// Prints client connections on stderr and counts them.
struct Listener {
    connected: AtomicUsize,
    ever: AtomicUsize,
}

impl ServerListener for Listener {
    fn on_client_connect(&self) {
        let n = self.connected.fetch_add(1, Ordering::Relaxed) + 1;
        self.ever.fetch_add(1, Ordering::Relaxed);
        eprintln!("foxglove: a client connected ({n} connected)");
    }
    fn on_client_disconnect(&self) {
        let n = self
            .connected
            .fetch_sub(1, Ordering::Relaxed)
            .saturating_sub(1);
        eprintln!("foxglove: a client disconnected ({n} connected); the robot goes on");
    }
    fn on_subscribe(&self, _client: Client, channel: ChannelView) {
        tracing::info!("foxglove: a client subscribed to {}", channel.topic());
    }
}

/// Checks the address: loopback, or any address with `any`.
pub fn check_addr(addr: SocketAddr, any: bool) -> Result<(), StartError> {
    if addr.ip().is_loopback() || any {
        Ok(())
    } else {
        Err(StartError::NotLoopback(addr))
    }
}

impl Server {
    /// Checks the options, binds the address and starts the publisher thread. Call within a
    /// tokio runtime.
    pub async fn start(opts: &Options) -> Result<Self, StartError> {
        check_addr(opts.addr, opts.any)?;
        scene::check_exaggeration(opts.exaggeration).map_err(StartError::Exaggeration)?;
        let ctx = Context::new();
        let channels = Channels::new(&ctx, &opts.keys)?;
        let listener = Arc::new(Listener {
            connected: AtomicUsize::new(0),
            ever: AtomicUsize::new(0),
        });
        // The viewers' address is the front's (`front`: it also admits the protocol's old
        // name); the SDK's server listens on a loopback port of its own behind it.
        let front = tokio::net::TcpListener::bind(opts.addr)
            .await
            .map_err(|cause| StartError::Bind {
                addr: opts.addr,
                hint: if cause.kind() == std::io::ErrorKind::AddrInUse {
                    " (another server holds the port: pass --foxglove with another address, \
                     e.g. 127.0.0.1:8766)"
                } else {
                    ""
                },
                cause,
            })?;
        let handle = foxglove::WebSocketServer::new()
            .name(format!("tilting/{}", opts.keys.robot()))
            .context(&ctx)
            .bind("127.0.0.1", 0)
            .listener(listener.clone())
            .start()
            .await
            .map_err(|e| StartError::Sdk(e.to_string()))?;
        let backend = SocketAddr::from(([127, 0, 0, 1], handle.port()));
        let front =
            Front::serve(front, backend).map_err(|e| StartError::Sdk(format!("the front: {e}")))?;
        let addr = front.addr();
        let (feed, drain) = queue::bounded(QUEUE);
        let drain = Arc::new(drain);
        let publisher = Publisher::new(channels, opts);
        let d = drain.clone();
        let thread = std::thread::Builder::new()
            .name("foxglove".into())
            .spawn(move || publisher.run(&d))
            .map_err(|e| StartError::Sdk(format!("the publisher thread: {e}")))?;
        Ok(Self {
            _ctx: ctx,
            handle,
            front,
            feed,
            drain,
            thread: Some(thread),
            listener,
            addr,
        })
    }

    /// The handle for subscriber callbacks: never blocks.
    pub fn feed(&self) -> Feed {
        self.feed.clone()
    }

    /// The address served (with the port bound).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.listener.connected.load(Ordering::Relaxed)
    }

    /// Publishes what is queued, stops the server and returns the counts.
    pub async fn close(mut self) -> Counts {
        self.drain.close();
        let mut counts = match self.thread.take().map(|t| t.join()) {
            Some(Ok(c)) => c,
            _ => Counts::default(),
        };
        counts.dropped = self.feed.dropped();
        counts.clients = self.listener.ever.load(Ordering::Relaxed) as u64;
        drop(self.front);
        self.handle.stop().wait().await;
        counts
    }
}

/// The channels of a server.
struct Channels {
    /// The five topics, JSON, in [`Topic::ALL`] order.
    topics: Vec<Arc<RawChannel>>,
    /// `{time, energy}` (JSON).
    energy: Arc<RawChannel>,
    /// The decimated quantities for plot panels (JSON, [`plot`]).
    plot: Arc<RawChannel>,
    scene: Channel<SceneUpdate>,
    tf: Channel<FrameTransforms>,
    log: Channel<Log>,
}

/// The schema of the energy channel.
pub const ENERGY_SCHEMA: &str = "tilting.Energy";

/// The JSON channels for robot `keys`: topic, schema name and JSON Schema; the five topics in
/// [`Topic::ALL`] order, then the energy, then the plot channel ([`plot`]).
pub fn json_channels(keys: &Keys) -> Vec<(String, String, serde_json::Value)> {
    let mut v: Vec<_> = Topic::ALL
        .into_iter()
        .map(|t| {
            (
                tilting_record::json_topic(t.key(keys)),
                schema_name(t),
                json_schema(t),
            )
        })
        .collect();
    v.push((
        format!("/tilting/{}/energy", keys.robot()),
        ENERGY_SCHEMA.into(),
        serde_json::json!({
            "title": ENERGY_SCHEMA,
            "type": "object",
            "properties": {
                "time": {"type": "number", "description": "Plant time, s."},
                "energy": {"type": "number", "description":
                    "Total energy E = T + V of the model (J), ground at y = 0."},
            },
            "required": ["time", "energy"],
            "additionalProperties": false,
        }),
    ));
    v.push((
        format!("/tilting/{}/plot", keys.robot()),
        plot::PLOT_SCHEMA.into(),
        plot::schema(),
    ));
    v
}

impl Channels {
    fn new(ctx: &Arc<Context>, keys: &Keys) -> Result<Self, StartError> {
        let json = |topic: String, name: String, schema: serde_json::Value| {
            ChannelBuilder::new(topic)
                .message_encoding(tilting_record::JSON_ENCODING)
                .schema(Schema::new(
                    name,
                    "jsonschema",
                    serde_json::to_vec(&schema).unwrap_or_default(),
                ))
                .context(ctx)
                .build_raw()
                .map_err(|e| StartError::Sdk(e.to_string()))
        };
        let mut all = json_channels(keys).into_iter();
        let mut topics = Vec::new();
        for (topic, name, schema) in all.by_ref().take(Topic::ALL.len()) {
            topics.push(json(topic, name, schema)?);
        }
        let mut next = |what: &str| {
            let (topic, name, schema) = all
                .next()
                .ok_or_else(|| StartError::Sdk(format!("no {what} channel")))?;
            json(topic, name, schema)
        };
        let energy = next("energy")?;
        let plot = next("plot")?;
        let base = format!("/tilting/{}", keys.robot());
        let typed = |suffix: &str| ChannelBuilder::new(format!("{base}/{suffix}")).context(ctx);
        Ok(Self {
            topics,
            energy,
            plot,
            scene: typed("scene").build(),
            tf: typed("tf").build(),
            log: typed("log").build(),
        })
    }
}

/// The publisher thread's state.
struct Publisher {
    ch: Channels,
    params: Params,
    k: f64,
    title: String,
    robot: String,
    counts: Counts,
    /// The latest plant time seen (s).
    t: f64,
    mode: Mode,
    /// Plant time of the last scene update (s).
    last_scene: f64,
    /// The landing flash lasts until (plant time, s).
    flash_until: f64,
    /// The last status' run state and fault.
    status: Option<(u8, String)>,
    /// Invalid payloads already reported, per topic.
    reported: [bool; 5],
    /// The plot channel's ticks.
    decimator: Decimator,
    /// The plot ticks' stamps on the viewer's clock.
    wall: plot::WallStamp,
    /// The latest reference (for the plotted gain).
    reference: Option<Reference>,
}

impl Publisher {
    fn new(ch: Channels, opts: &Options) -> Self {
        Self {
            ch,
            params: opts.params,
            k: opts.exaggeration,
            title: scene::title(opts.keys.robot(), opts.exaggeration),
            robot: opts.keys.robot().to_owned(),
            counts: Counts::default(),
            t: 0.0,
            mode: Mode::Flat,
            last_scene: f64::NEG_INFINITY,
            flash_until: f64::NEG_INFINITY,
            status: None,
            reported: [false; 5],
            decimator: Decimator::default(),
            wall: plot::WallStamp::default(),
            reference: None,
        }
    }

    fn run(mut self, drain: &Drain) -> Counts {
        let mut batch = Vec::new();
        while drain.take(&mut batch, Duration::from_millis(100)) {
            for item in batch.drain(..) {
                self.publish(item);
            }
        }
        let last = self.decimator.flush();
        self.plot(last);
        self.counts
    }

    fn publish(&mut self, item: Item) {
        let Ok(json) = to_json(item.topic, &item.wire) else {
            self.counts.invalid += 1;
            if !std::mem::replace(&mut self.reported[item.topic.index()], true) {
                let msg = format!("a {} payload did not decode: not shown", item.topic);
                self.log(Level::Warning, msg);
            }
            return;
        };
        let own_time = match item.topic {
            Topic::State => codec::decode::<PlantState>(&item.wire).ok().map(|m| m.time),
            Topic::Event => codec::decode::<ModeEvent>(&item.wire).ok().map(|m| m.time),
            Topic::Status => codec::decode::<Status>(&item.wire).ok().map(|m| m.time),
            _ => None,
        };
        if let Some(t) = own_time {
            self.t = self.t.max(t);
        }
        let log_time = item
            .log_time
            .unwrap_or_else(|| scene::nanos(own_time.unwrap_or(self.t)));
        self.ch.topics[item.topic.index()]
            .log_with_meta(&json, PartialMetadata::with_log_time(log_time));
        self.counts.published += 1;
        match item.topic {
            Topic::State => {
                if let Ok(s) = codec::decode::<PlantState>(&item.wire) {
                    self.state(&s, log_time);
                }
            }
            Topic::Event => {
                if let Ok(e) = codec::decode::<ModeEvent>(&item.wire) {
                    self.event(&e, log_time);
                }
            }
            Topic::Status => {
                if let Ok(s) = codec::decode::<Status>(&item.wire) {
                    self.status(&s);
                }
            }
            Topic::Torque => {
                if let Ok(c) = codec::decode::<TorqueCommand>(&item.wire) {
                    let done = self.decimator.add(log_time, &[(Field::Tau, c.tau)]);
                    self.plot(done);
                }
            }
            // The gain plotted is the paper law's (its own or by name in the generic layout);
            // any other law's reference plots no gain.
            Topic::Reference => {
                self.reference = match codec::decode::<AnyReference>(&item.wire) {
                    Ok(AnyReference::Paper(r)) => Some(r),
                    Ok(AnyReference::Law(l)) => l.to_paper(),
                    Err(_) => None,
                }
            }
        }
    }

    /// Publishes closed ticks of the plot channel, each stamped on the viewer's clock.
    fn plot(&mut self, ticks: Vec<(u64, serde_json::Value)>) {
        let now = wall_ns();
        for (log_time, mut json) in ticks {
            plot::stamp(&mut json, self.wall.at(log_time, now));
            self.ch.plot.log_with_meta(
                json.to_string().as_bytes(),
                PartialMetadata::with_log_time(log_time),
            );
        }
    }

    /// The frames, the energy, the plot's samples and (20 times a second, at mode changes)
    /// the scene.
    fn state(&mut self, s: &PlantState, log_time: u64) {
        let Ok(mode) = s.mode() else { return };
        let meta = || PartialMetadata::with_log_time(log_time);
        let tfs = scene::transforms(&self.params, self.k, s.time, mode, s.alpha, s.beta);
        self.ch.tf.log_with_meta(&tfs, meta());
        let mut samples = vec![(Field::Alpha, s.alpha), (Field::Beta, s.beta)];
        if let (Some(ad), Some(bd)) = (s.alpha_dot, s.beta_dot) {
            let x = State::new(s.alpha, s.beta, ad, bd);
            let e = tilting_plant::kinematics::energy(&self.params, mode, &x);
            let json = serde_json::json!({"time": s.time, "energy": e});
            self.ch
                .energy
                .log_with_meta(json.to_string().as_bytes(), meta());
            samples.push((Field::Energy, e));
            if let Some(r) = &self.reference {
                samples.push((Field::Gain, plot::gain(r, e)));
            }
        }
        let done = self.decimator.add(log_time, &samples);
        self.plot(done);
        let flashing = s.time < self.flash_until;
        let flash_ended = !flashing && self.last_scene < self.flash_until;
        if mode != self.mode || flash_ended || s.time - self.last_scene >= SCENE_PERIOD {
            self.mode = mode;
            self.scene(s.time, flashing, None, log_time);
        }
    }

    fn scene(&mut self, t: f64, flashing: bool, extra: Option<SceneEntity>, log_time: u64) {
        let mut entities = scene::entities(&self.params, &self.title, t, self.mode, flashing);
        entities.extend(extra);
        let update = SceneUpdate {
            deletions: Vec::new(),
            entities,
        };
        self.ch
            .scene
            .log_with_meta(&update, PartialMetadata::with_log_time(log_time));
        self.last_scene = t;
        self.counts.scenes += 1;
    }

    /// A mode transition: a log entry, and at a landing the flash.
    fn event(&mut self, e: &ModeEvent, log_time: u64) {
        let Ok((from, to)) = e.modes() else { return };
        let what = match (from.is_tilted(), to.is_tilted()) {
            (false, true) => "tilt",
            (true, false) => "landing",
            _ => "switch",
        };
        // Routine (about 4.5 a second on the paper's orbit): debug, so that a safe mode's
        // warning stands out in a log panel showing info and above.
        self.log_at(
            Level::Debug,
            format!("plant t = {:.4} s: {from} -> {to} ({what})", e.time),
            log_time,
        );
        self.mode = to;
        if what == "landing" {
            self.flash_until = e.time + scene::FLASH;
            let flash = scene::landing_flash(&self.params, e.time, from);
            self.scene(e.time, true, Some(flash), log_time);
        }
    }

    /// A change of the run state or of the fault: a log entry.
    fn status(&mut self, s: &Status) {
        let prev = self.status.replace((s.state, s.fault.clone()));
        let (state, fault) = (s.state, s.fault.as_str());
        if prev
            .as_ref()
            .is_some_and(|(p, f)| *p == state && f == fault)
        {
            return;
        }
        let (level, what) = match state {
            Status::STARTING => (Level::Info, "starting".to_owned()),
            Status::RUNNING => (Level::Info, "running".to_owned()),
            Status::SAFE_MODE => (
                Level::Warning,
                "SAFE MODE: no timely torque, the plant applies its safe fallback".to_owned(),
            ),
            Status::FAULTED => (Level::Error, format!("FAULT: {fault}")),
            Status::STOPPED => (Level::Info, "stopped".to_owned()),
            other => (Level::Warning, format!("unknown run state {other}")),
        };
        let what = if !fault.is_empty() && fault != "none" && state != Status::FAULTED {
            format!("{what}; fault: {fault}")
        } else {
            what
        };
        self.log_at(
            level,
            format!("plant t = {:.4} s: {what}", s.time),
            scene::nanos(s.time),
        );
    }

    fn log(&mut self, level: Level, message: String) {
        self.log_at(level, message, scene::nanos(self.t));
    }

    /// A log entry stamped with the wall clock (when the server saw it: a log panel shows a
    /// date and time of day, not 1 January 1970); its message names the plant time, and the
    /// channel's log time is the plant time of the other channels (`log_time`, ns).
    fn log_at(&mut self, level: Level, message: String, log_time: u64) {
        let entry = Log {
            timestamp: Some(wall_clock()),
            level: level as i32,
            message,
            name: format!("tilting/{}", self.robot),
            file: String::new(),
            line: 0,
        };
        self.ch
            .log
            .log_with_meta(&entry, PartialMetadata::with_log_time(log_time));
        self.counts.logs += 1;
    }
}

/// The wall clock now as a Foxglove timestamp (the Unix epoch if the clock is before it).
pub fn wall_clock() -> foxglove::messages::Timestamp {
    let ns = wall_ns();
    foxglove::messages::Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

/// The wall clock now, ns since the Unix epoch (0 if the clock is before it).
fn wall_ns() -> u128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .as_nanos()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every message path of `docs/foxglove-layout.json` (robot `demo`) names a served JSON
    /// channel and a field of its schema, and every other topic it names is served: a layout
    /// edited alone, or a renamed field, fails here.
    #[test]
    fn the_layout_names_what_is_served() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/foxglove-layout.json");
        let layout: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let keys = Keys::new("demo").unwrap();
        let json = json_channels(&keys);
        let typed = ["scene", "tf", "log"].map(|s| format!("/tilting/demo/{s}"));
        let mut seen = 0;
        let mut check = |s: &str| {
            if !s.starts_with("/tilting/") {
                return;
            }
            seen += 1;
            if typed.iter().any(|t| t == s) {
                return;
            }
            let (topic, field) = s.rsplit_once('.').unwrap_or((s, ""));
            let (_, _, schema) = json
                .iter()
                .find(|(t, _, _)| t == topic)
                .unwrap_or_else(|| panic!("{s}: not a served channel"));
            assert!(
                field.is_empty() || schema["properties"].get(field).is_some(),
                "{s}: no field `{field}` in {}",
                schema["title"]
            );
        };
        fn walk(v: &serde_json::Value, f: &mut dyn FnMut(&str)) {
            match v {
                serde_json::Value::String(s) => f(s),
                serde_json::Value::Array(a) => a.iter().for_each(|x| walk(x, f)),
                serde_json::Value::Object(o) => o.iter().for_each(|(k, x)| {
                    f(k);
                    walk(x, f)
                }),
                _ => {}
            }
        }
        walk(&layout, &mut check);
        assert!(seen >= 8, "{seen} topic paths");
        // A 3D panel, two plots, the status, the log.
        let panels: Vec<&String> = layout["configById"].as_object().unwrap().keys().collect();
        for kind in ["3D!", "Plot!", "RawMessages!", "RosOut!"] {
            assert!(panels.iter().any(|p| p.starts_with(kind)), "{panels:?}");
        }
        // The torque and the energy on plots of their own (N m and J on one axis hid the
        // torque), each plot with one unit.
        let cfg = layout["configById"].as_object().unwrap();
        let plots: Vec<Vec<&str>> = cfg
            .iter()
            .filter(|(k, _)| k.starts_with("Plot!"))
            .map(|(_, v)| {
                let paths = v["paths"].as_array().unwrap();
                paths
                    .iter()
                    .filter(|p| p["enabled"] == true)
                    .map(|p| p["value"].as_str().unwrap())
                    .collect()
            })
            .collect();
        let with = |s: &str| {
            plots
                .iter()
                .filter(|p| p.iter().any(|v| v.ends_with(s)))
                .count()
        };
        // Each on exactly one plot, and the two never on the same one.
        let apart = |a: &str, b: &str| {
            assert_eq!((with(a), with(b)), (1, 1), "{plots:?}");
            assert!(
                !plots
                    .iter()
                    .any(|p| p.iter().any(|v| v.ends_with(a)) && p.iter().any(|v| v.ends_with(b))),
                "{plots:?}"
            );
        };
        apart("plot.tau_max", "plot.energy_max");
        // The tilt and the arm angle apart too: alpha's 0.04 rad was a flat line on the axis
        // of beta's 1.57 (seen in Foxglove Studio 1.48).
        apart("plot.alpha_max", "plot.beta_max");
        apart("plot.energy_max", "plot.gain_max");
        // Every plotted line reads the 50 Hz plot channel, never a 1 kHz one (Studio 1.48's
        // plots went blank for seconds fed the state), and each quantity's min with its max.
        for p in plots.iter().flatten() {
            assert!(
                p.starts_with("/tilting/demo/plot."),
                "{p}: not the plot channel"
            );
        }
        // ... drawn at each tick's own time (header.stamp), not when the browser read it
        // (receive time: a browser short of CPU reads ticks in bursts, drawn as straight lines).
        for (k, v) in cfg.iter().filter(|(k, _)| k.starts_with("Plot!")) {
            for p in v["paths"].as_array().unwrap() {
                if p["value"]
                    .as_str()
                    .unwrap()
                    .starts_with("/tilting/demo/plot.")
                {
                    assert_eq!(p["timestampMethod"], "headerStamp", "{k}: {p}");
                }
            }
        }
        for (_, name, _) in plot::FIELDS {
            let (lo, hi) = (format!("plot.{name}_min"), format!("plot.{name}_max"));
            assert!(
                plots
                    .iter()
                    .any(|p| p.iter().any(|v| v.ends_with(&lo))
                        && p.iter().any(|v| v.ends_with(&hi))),
                "{name}: min and max not on one plot: {plots:?}"
            );
        }
        // The camera looks at the robot: its target inside the paper's robot's extent (x from
        // the left edge to the right, z from the ground to the arm's length), from -y (theta 0:
        // the model's plane seen face on), a little above, close enough that the 2 m arm fills
        // over a third of the view's height.
        let p = Params::default();
        let cam = &layout["configById"]["3D!tilting"]["cameraState"];
        let t: Vec<f64> = cam["targetOffset"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert!(
            (0.0..=2.0 * p.f).contains(&t[0]) && t[1] == 0.0 && (0.0..=p.l).contains(&t[2]),
            "{t:?}"
        );
        assert_eq!(cam["thetaOffset"], 0);
        // The grid below the ground slab's top (z = 0): coplanar, the two flickered.
        let grid = &layout["configById"]["3D!tilting"]["layers"]["grid"]["position"];
        assert!(grid[2].as_f64().unwrap() < 0.0, "{grid}");
        // No frame labels: `plate` and `arm` share an origin and printed over each other (and
        // `world` beside them, large) in Studio 1.48's screenshot; the scene's own small
        // labels name the parts.
        assert_eq!(
            layout["configById"]["3D!tilting"]["scene"]["transforms"]["showLabel"],
            false
        );
        let (d, fov, phi) = (
            cam["distance"].as_f64().unwrap(),
            cam["fovy"].as_f64().unwrap(),
            cam["phi"].as_f64().unwrap(),
        );
        let height = 2.0 * d * (fov.to_radians() / 2.0).tan();
        assert!(
            p.l / height > 1.0 / 3.0 && (60.0..=90.0).contains(&phi),
            "view {height} m, phi {phi}"
        );
        // The log panel shows info and above: the routine mode changes (debug) do not bury a
        // safe mode's warning.
        let min = layout["configById"]["RosOut!log"]["minLogLevel"]
            .as_i64()
            .unwrap();
        assert!(
            min > Level::Debug as i64 && min <= Level::Warning as i64,
            "{min}"
        );
    }
}
