//! `tilting live --foxglove` against an independent client: `tests/python/foxglove_client.py`
//! speaks the documented Foxglove WebSocket protocol with the Python `websockets` package and
//! decodes every message against the schema its channel advertised (`jsonschema` for our JSON
//! channels, `protobuf` classes built from the advertised descriptors for SceneUpdate,
//! FrameTransforms and Log). Without python3 or those packages (`.ci/run` installs them) the
//! tests print SKIP and pass.
//!
//! - a 3 s run with one client subscribed to the state, the scene, the frames and the log: the
//!   client gets >= 90 % of the recorded states and scene updates, all valid; the plate's edges
//!   and the arm's tip composed from the served frames equal the model's kinematics
//!   (`tilting_plant::kinematics::point_masses` on the recorded state) to 1e-9 m at three
//!   instants, one per mode; a second client subscribes to an unknown channel and is told so,
//!   and leaves mid-run; the run completes and `live` says the client left;
//! - `replay run.mcap --foxglove` plays that recording into the same scene (>= 90 % of the
//!   states, with their plant-time log times);
//! - `live --secure --foxglove`: the client gets the states (the recorder's direct links) and
//!   the reference (the planner's session, through the router);
//! - bad input: a port in use (live goes on without Foxglove, `view` refuses), an address that
//!   is not loopback without --foxglove-any (refused before anything starts).

use std::collections::HashMap;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;
use tilting_plant::kinematics::point_masses;
use tilting_plant::{Params, State};
use tilting_proto::{PlantState, Topic};
use tilting_tests::*;

const PY_PACKAGES: &str = "import websockets, jsonschema, google.protobuf";

fn client_ready(test: &str) -> bool {
    if python_runs(PY_PACKAGES) {
        return true;
    }
    skip(
        test,
        Missing::Package,
        &format!(
            "`{} -c \"{PY_PACKAGES}\"` failed; install them with `python3 -m pip install \
             websockets jsonschema protobuf`",
            python()
        ),
    );
    false
}

fn script() -> std::path::PathBuf {
    workspace_root().join("tests/python/foxglove_client.py")
}

/// Starts the client and waits until it says it is ready (its imports take a while: the run
/// must not start before it can connect).
fn client(url: &str, robot: &str, seconds: f64, out: &Path, extra: &[&str]) -> std::process::Child {
    let mut child = Command::new(python())
        .arg(script())
        .args(["--url", url, "--robot", robot, "--seconds"])
        .arg(seconds.to_string())
        .arg("--out")
        .arg(out)
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .expect("run foxglove_client.py");
    let mut line = String::new();
    let stdout = child.stdout.take().expect("piped");
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line).unwrap();
    assert_eq!(line.trim(), "ready", "foxglove_client.py did not start");
    child
}

fn text(o: &Output) -> String {
    format!(
        "status {}\n--- stdout ---\n{}\n--- stderr ---\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Rotates `v` by the unit quaternion `[x, y, z, w]` (written out: `v + 2w (u x v) + 2 u x (u x
/// v)`).
fn rotate(q: &[f64], v: [f64; 3]) -> [f64; 3] {
    let u = [q[0], q[1], q[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let t = cross(u, v).map(|c| 2.0 * c);
    let ut = cross(u, t);
    [0, 1, 2].map(|i| v[i] + q[3] * t[i] + ut[i])
}

/// A served transform `[translation, rotation]` applied to `v` (child frame to parent).
fn apply(tf: &serde_json::Value, v: [f64; 3]) -> [f64; 3] {
    let f = |x: &serde_json::Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect()
    };
    let (o, q) = (f(&tf[0]), f(&tf[1]));
    let r = rotate(&q, v);
    [r[0] + o[0], r[1] + o[1], r[2] + o[2]]
}

#[test]
fn a_foxglove_client_sees_the_live_robot() {
    if !client_ready("a_foxglove_client_sees_the_live_robot") {
        return;
    }
    // Built (if need be) before the clients start: their 60 s to connect must not include it.
    bin("tilting");
    let _turn = realtime_turn();
    let dir = Scratch::new("foxglove");
    let out = dir.path().join("out");
    let robot = robot("fox");
    let port = free_port();
    let url = format!("ws://127.0.0.1:{port}");
    let addr = format!("127.0.0.1:{port}");
    // The first client stays for the whole run (started first, it retries until the server is up; the run
    // takes 3 s after a start-up of a few seconds, so 60 s is ample on a slow machine).
    let main_json = dir.path().join("main.json");
    let mut main = client(&url, &robot, 60.0, &main_json, &[]);
    // The second subscribes to an unknown channel as well, and leaves after 1.5 s.
    let rude_json = dir.path().join("rude.json");
    let mut rude = client(
        &url,
        &robot,
        60.0,
        &rude_json,
        &["--unknown-channel", "--disconnect-after", "1.5"],
    );
    let live = Command::new(bin("tilting"))
        .args([
            "live",
            "--duration",
            "3",
            "--robot",
            &robot,
            "--foxglove",
            &addr,
            "--out",
        ])
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cannot run tilting live");
    let o = live.wait_with_output().expect("live");
    assert!(main.wait().unwrap().success(), "client 1\n{}", text(&o));
    assert!(rude.wait().unwrap().success(), "client 2\n{}", text(&o));
    assert!(o.status.success(), "live failed\n{}", text(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("Foxglove serves robot"), "{}", text(&o));
    assert!(stderr.contains("a client disconnected"), "{}", text(&o));

    let got: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&main_json).unwrap()).unwrap();
    assert_eq!(got["subprotocol"], "foxglove.sdk.v1");
    // The reference is put again once a second: a 3 s run shows it at least once.
    assert!(got["references"].as_u64().unwrap() >= 1, "{}", text(&o));
    assert_eq!(
        got["invalid"].as_array().unwrap().len(),
        0,
        "{}",
        got["invalid"]
    );
    let adv = got["advertised"].as_object().unwrap();
    for t in [
        "plant/state",
        "controller/torque",
        "plant/event",
        "plant/status",
        "planner/reference",
    ] {
        let ch = &adv[&format!("/tilting/{robot}/{t}")];
        assert_eq!(ch["encoding"], "json", "{t}: {ch}");
        assert_eq!(ch["schemaEncoding"], "jsonschema", "{t}: {ch}");
    }
    assert_eq!(
        adv[&format!("/tilting/{robot}/scene")]["schemaName"],
        "foxglove.SceneUpdate"
    );
    assert_eq!(
        adv[&format!("/tilting/{robot}/tf")]["schemaName"],
        "foxglove.FrameTransforms"
    );
    assert_eq!(
        adv[&format!("/tilting/{robot}/log")]["schemaName"],
        "foxglove.Log"
    );

    // >= 90 % of the recorded states, each equal to the recording's.
    let run = tilting_record::read(&out.join("run.mcap")).expect("run.mcap");
    let recorded: HashMap<u64, PlantState> = run
        .messages()
        .filter(|e| e.topic == Topic::State)
        .map(|e| {
            let s: PlantState = tilting_proto::decode(&e.wire).unwrap();
            (s.seq, s)
        })
        .collect();
    let states = got["states"].as_array().unwrap();
    assert!(
        states.len() as f64 >= 0.9 * recorded.len() as f64 && recorded.len() > 2500,
        "{} of {} states",
        states.len(),
        recorded.len()
    );
    for s in states {
        let r = &recorded[&s["seq"].as_u64().unwrap()];
        assert_eq!(
            (s["alpha"].as_f64(), s["time"].as_f64()),
            (Some(r.alpha), Some(r.time))
        );
    }
    // Scene updates: 20 a second at least, with the robot's entities.
    let scenes = got["scene_updates"].as_u64().unwrap();
    assert!(scenes >= 50, "{scenes} scene updates");
    let ids: Vec<&str> = got["scene_entity_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for id in ["plate", "arm", "pivot", "title"] {
        assert!(ids.contains(&id), "{ids:?}");
    }
    assert!(
        got["logs"]
            .as_array()
            .unwrap()
            .iter()
            .any(|l| { l["message"].as_str().unwrap().contains("(tilt)") }),
        "no tilt in the log: {}",
        got["logs"]
    );

    // Geometry at three instants, one per mode: the served frames against the kinematics.
    let by_time: HashMap<u64, &PlantState> = recorded
        .values()
        .map(|s| (tilting_foxglove::scene::nanos(s.time), s))
        .collect();
    let p = Params::default();
    let mut checked = HashMap::new();
    for tf in got["tf"].as_array().unwrap() {
        assert_eq!(
            (tf["plate_parent"].as_str(), tf["arm_parent"].as_str()),
            (Some("world"), Some("plate"))
        );
        let Some(s) = by_time.get(&tf["log_time"].as_u64().unwrap()) else {
            continue;
        };
        let mode = s.mode().unwrap();
        if checked.contains_key(&mode) || (mode.is_tilted() && s.alpha.abs() < 0.01) {
            continue;
        }
        let q = point_masses(&p, mode, &State::new(s.alpha, s.beta, 0.0, 0.0));
        let tip = apply(&tf["plate"], apply(&tf["arm"], [p.l, 0.0, 0.0]));
        let edge = |sign: f64| apply(&tf["plate"], [sign * p.f, 0.0, 0.0]);
        let (ca, sa) = (s.alpha.cos(), s.alpha.sin());
        // Model (x, y) is Foxglove (x, 0, y); the edges are the centre -/+ f (cos, sin) alpha.
        let want = [
            ([q.tip.x, q.tip.y], tip),
            ([q.foot.x - p.f * ca, q.foot.y - p.f * sa], edge(-1.0)),
            ([q.foot.x + p.f * ca, q.foot.y + p.f * sa], edge(1.0)),
        ];
        for (w, g) in want {
            let err = (w[0] - g[0]).abs().max(g[1].abs()).max((w[1] - g[2]).abs());
            assert!(
                err < 1e-9,
                "{mode} at t = {}: served {g:?}, model {w:?}",
                s.time
            );
        }
        checked.insert(mode, s.time);
    }
    assert_eq!(checked.len(), 3, "one instant per mode: {checked:?}");
    eprintln!("checked the geometry at {checked:?}");

    // The rude client was told the channel is unknown, and the others went on.
    let rude: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&rude_json).unwrap()).unwrap();
    let told = rude["statuses"]
        .as_array()
        .unwrap()
        .iter()
        .any(|s| s["level"] == 2 && s["message"].as_str().unwrap().contains("Unknown channel"));
    assert!(told, "{}", rude["statuses"]);

    // The recording played into the same scene (`replay --foxglove`, twice the pace).
    let port = free_port();
    let replay_json = dir.path().join("replay.json");
    let mut viewer = client(
        &format!("ws://127.0.0.1:{port}"),
        &robot,
        60.0,
        &replay_json,
        &[],
    );
    let o = Command::new(bin("tilting"))
        .arg("replay")
        .arg(out.join("run.mcap"))
        .args([
            "--robot",
            &robot,
            "--speed",
            "2",
            "--wait",
            "30",
            "--foxglove",
        ])
        .arg(format!("127.0.0.1:{port}"))
        .output()
        .unwrap();
    assert!(o.status.success(), "replay --foxglove\n{}", text(&o));
    assert!(viewer.wait().unwrap().success());
    let got: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&replay_json).unwrap()).unwrap();
    let states = got["states"].as_array().unwrap();
    assert!(
        states.len() as f64 >= 0.9 * recorded.len() as f64,
        "replayed {} of {} states\n{}",
        states.len(),
        recorded.len(),
        text(&o)
    );
    assert!(got["scene_updates"].as_u64().unwrap() >= 50, "{}", text(&o));
    for s in states {
        // Log times are the recording's (plant time).
        let r = &recorded[&s["seq"].as_u64().unwrap()];
        assert_eq!(
            s["log_time"].as_u64(),
            Some(tilting_foxglove::scene::nanos(r.time))
        );
    }
}

/// Under `--secure` the recording session links only to the plant and the controller; the
/// reference comes through the router on the planner's session, and Foxglove must show both.
#[test]
fn a_foxglove_client_of_a_secure_run_gets_the_loop_and_the_reference() {
    if !client_ready("a_foxglove_client_of_a_secure_run_gets_the_loop_and_the_reference") {
        return;
    }
    bin("tilting-router");
    let _turn = realtime_turn();
    let dir = Scratch::new("foxglove-secure");
    let out = dir.path().join("out");
    let robot = robot("foxsec");
    let port = free_port();
    let json = dir.path().join("client.json");
    let mut viewer = client(&format!("ws://127.0.0.1:{port}"), &robot, 60.0, &json, &[]);
    let o = Command::new(bin("tilting"))
        .args(["live", "--secure", "--duration", "3", "--robot", &robot])
        .args(["--foxglove", &format!("127.0.0.1:{port}"), "--out"])
        .arg(&out)
        .output()
        .expect("cannot run tilting live --secure");
    assert!(viewer.wait().unwrap().success(), "client\n{}", text(&o));
    assert!(o.status.success(), "live --secure failed\n{}", text(&o));
    let got: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(
        got["invalid"].as_array().unwrap().len(),
        0,
        "{}",
        got["invalid"]
    );
    // States come over the recorder's direct links, the reference through the router.
    assert!(
        got["states"].as_array().unwrap().len() > 1000,
        "{}",
        text(&o)
    );
    assert!(got["references"].as_u64().unwrap() >= 1, "{}", text(&o));
}

#[test]
fn foxglove_bad_addresses_are_refused_clearly() {
    let tilting = bin("tilting");
    // Not loopback, without --foxglove-any: a usage error before anything starts.
    let o = Command::new(&tilting)
        .args(["live", "--duration", "1", "--foxglove", "0.0.0.0:0"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--foxglove") && err.contains("--foxglove-any"),
        "{err}"
    );
    let o = Command::new(&tilting)
        .args(["live", "--foxglove", "nowhere"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("IP:PORT"),
        "{}",
        text(&o)
    );

    // A port in use: `view` (whose whole job it is) refuses, naming the address.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let o = Command::new(&tilting)
        .args([
            "view",
            "--robot",
            "nobody",
            "--seconds",
            "1",
            "--foxglove",
            &addr,
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("cannot serve Foxglove on {addr}")),
        "{err}"
    );
}

#[test]
fn live_goes_on_without_foxglove_when_its_port_is_taken() {
    let _turn = realtime_turn();
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let dir = Scratch::new("foxglove-taken");
    let o = Command::new(bin("tilting"))
        .args([
            "live",
            "--duration",
            "1",
            "--robot",
            &robot("fox_taken"),
            "--foxglove",
            &addr,
            "--out",
        ])
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("cannot serve Foxglove on {addr}"))
            && err.contains("the run goes on without Foxglove"),
        "{err}"
    );
    let _ = Duration::ZERO;
}

// ---- Foxglove's own JavaScript libraries (tests/node: @foxglove/ws-protocol, @mcap/core) ----

/// `tests/node` with its packages installed (`npm ci --prefix tests/node`, as `.ci/run` does),
/// and node; otherwise why not.
fn node_ready() -> Result<std::path::PathBuf, String> {
    let dir = workspace_root().join("tests/node");
    match Command::new("node").arg("--version").output() {
        Ok(o) if o.status.success() => {}
        _ => return Err("node is not installed".into()),
    }
    for pkg in [
        "@foxglove/ws-protocol",
        "@mcap/core",
        "@mcap/support",
        "protobufjs",
        "ws",
    ] {
        if !dir.join("node_modules").join(pkg).is_dir() {
            return Err(format!(
                "tests/node/node_modules/{pkg} is missing: run `npm ci --prefix tests/node`"
            ));
        }
    }
    Ok(dir)
}

/// Runs `node SCRIPT ARGS` in `tests/node` to the end; its stdout.
fn node(dir: &Path, script: &str, args: &[&str]) -> String {
    let o = Command::new("node")
        .arg(dir.join(script))
        .args(args)
        .output()
        .expect("run node");
    assert!(o.status.success(), "node {script}\n{}", text(&o));
    String::from_utf8(o.stdout).unwrap()
}

/// Starts `ws_client.mjs` offering `subprotocol` (it retries until the server listens).
fn node_client(dir: &Path, url: &str, subprotocol: &str, out: &Path) -> std::process::Child {
    Command::new("node")
        .arg(dir.join("ws_client.mjs"))
        .args([
            "--url",
            url,
            "--subprotocol",
            subprotocol,
            "--seconds",
            "60",
            "--out",
        ])
        .arg(out)
        .stdin(Stdio::null())
        .spawn()
        .expect("run ws_client.mjs")
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Foxglove's own libraries from npm under node read what we serve and record:
///
/// - `@mcap/core`'s `McapIndexedReader` (with `@mcap/support`'s decompressors) reads every
///   message of a `live` recording through its indexes: per topic as many as our reader, in
///   total the file's statistics; each decoded with its schema after the strict check of the
///   viewers' JSON Schema parser (`tests/node/schemas.mjs`);
/// - `@foxglove/ws-protocol`'s `FoxgloveClient` against `replay --foxglove` of that recording,
///   offering `foxglove.sdk.v1`, then `foxglove.sdk.v1.1`: every advertised channel
///   (five topics, the energy and the plot as JSON, tf, scene and log as protobuf) decodes with its
///   advertised schema, inline under v1, from the connection's schema table under v1.1 (which
///   the library alone does not pass on: the test says so, so a library that starts to
///   fails here and the docs get updated), and once offering the library's own
///   `foxglove.websocket.v1` (Studio 1.48's), which the SDK refuses and our handshake front
///   admits; the states are the recording's with their mode names; the log entries carry the
///   wall clock and name the plant time, mode changes at debug; a client offering an unknown
///   name is refused with HTTP 400; the plot channel ticks at the documented 50 Hz of plant
///   time and each tick bounds exactly the recording's samples in it.
#[test]
fn foxglove_libraries_from_npm_read_the_server_and_the_recording() {
    let dir = match node_ready() {
        Ok(d) => d,
        Err(why) => {
            let test = "foxglove_libraries_from_npm_read_the_server_and_the_recording";
            skip(test, Missing::Package, &why);
            return;
        }
    };
    let scratch = Scratch::new("foxglove-node");
    let out = scratch.path().join("out");
    let robot = robot("foxnode");
    {
        let _turn = realtime_turn();
        let o = Command::new(bin("tilting"))
            .args(["live", "--duration", "3", "--robot", &robot, "--out"])
            .arg(&out)
            .output()
            .expect("tilting live");
        assert!(o.status.success(), "live\n{}", text(&o));
    }
    let mcap = out.join("run.mcap");
    let run = tilting_record::read(&mcap).expect("run.mcap");
    let keys = tilting_proto::Keys::new(&robot).unwrap();

    // The recording through @mcap/core's indexed reader.
    let got: serde_json::Value =
        serde_json::from_str(&node(&dir, "mcap_read.mjs", &[mcap.to_str().unwrap()])).unwrap();
    let total: u64 = Topic::ALL.iter().map(|&t| run.count(t)).sum();
    assert_eq!(got["total"].as_u64(), Some(total), "{got}");
    assert_eq!(got["statisticsMessageCount"].as_u64(), Some(total), "{got}");
    for t in Topic::ALL {
        let topic = &got["topics"][tilting_record::json_topic(t.key(&keys))];
        assert_eq!(topic["count"].as_u64(), Some(run.count(t)), "{t}: {topic}");
        assert_eq!(topic["errors"], serde_json::json!([]), "{t}: {topic}");
        assert_eq!(topic["monotonic"], true, "{t}");
        assert_eq!(topic["schemaEncoding"], "jsonschema", "{t}");
    }
    assert!(run.count(Topic::Event) > 0, "no mode change in 3 s");

    let states: HashMap<u64, PlantState> = run
        .messages()
        .filter(|e| e.topic == Topic::State)
        .map(|e| {
            let s: PlantState = tilting_proto::decode(&e.wire).unwrap();
            (s.seq, s)
        })
        .collect();
    // The recording's states and torques by log time (ns): what the plot channel decimates.
    let samples: Vec<(u64, Topic, Vec<u8>)> = run
        .messages()
        .filter(|e| matches!(e.topic, Topic::State | Topic::Torque))
        .map(|e| (e.log_time, e.topic, e.wire.clone()))
        .collect();
    for (subprotocol, from, library) in [
        // The library's own name (FoxgloveClient.SUPPORTED_SUBPROTOCOL), Studio 1.48's: the SDK
        // refuses it, our front hands it `foxglove.sdk.v1`.
        ("foxglove.websocket.v1", "inline", true),
        ("foxglove.sdk.v1", "inline", true),
        ("foxglove.sdk.v1.1", "table", false),
    ] {
        let port = free_port();
        let url = format!("ws://127.0.0.1:{port}");
        let replay = Command::new(bin("tilting"))
            .arg("replay")
            .arg(&mcap)
            .args([
                "--robot",
                &robot,
                "--speed",
                "2",
                "--wait",
                "30",
                "--foxglove",
            ])
            .arg(format!("127.0.0.1:{port}"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("replay --foxglove");
        if subprotocol == "foxglove.sdk.v1" {
            // A name neither the SDK nor the front knows: refused (docs/foxglove.md says so).
            let refused = scratch.path().join("refused.json");
            let mut probe = node_client(&dir, &url, "foxglove.websocket.v2", &refused);
            assert!(probe.wait().unwrap().success());
            assert_eq!(read_json(&refused)["refused"], 400);
        }
        let json = scratch.path().join(format!("{subprotocol}.json"));
        let mut client = node_client(&dir, &url, subprotocol, &json);
        let o = replay.wait_with_output().unwrap();
        assert!(
            client.wait().unwrap().success(),
            "{subprotocol}\n{}",
            text(&o)
        );
        assert!(o.status.success(), "replay\n{}", text(&o));
        let got = read_json(&json);
        check_node_client(&got, subprotocol, from, library, &robot, &states);
        check_plot(&got, subprotocol, &samples);
    }
}

/// The plot channel's rate as docs/foxglove.md states it: 50 ticks per second of plant time.
const PLOT_RATE: f64 = 50.0;

/// The plot channel as the client saw it: 50 ticks a second of plant time (from the messages'
/// log times, within 10 %), and each tick's `alpha`, `beta` and `tau` ranges exactly the least
/// and greatest of the recording's samples whose log time falls in the tick (20 ms centred on
/// its `time`), so no peak is lost; the energy's range inside its bounds.
fn check_plot(got: &serde_json::Value, subprotocol: &str, samples: &[(u64, Topic, Vec<u8>)]) {
    let ticks = got["plots"].as_array().unwrap();
    assert!(
        ticks.len() >= 50,
        "{subprotocol}: {} plot ticks",
        ticks.len()
    );
    let times: Vec<u64> = ticks
        .iter()
        .map(|t| t["log_time"].as_u64().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{subprotocol}");
    let span = (times[times.len() - 1] - times[0]) as f64 * 1e-9;
    let rate = (times.len() - 1) as f64 / span;
    assert!(
        (rate / PLOT_RATE - 1.0).abs() <= 0.1,
        "{subprotocol}: plot at {rate:.2} Hz of plant time, docs say {PLOT_RATE}"
    );
    let half = (0.5e9 / PLOT_RATE) as u64;
    let mut peak = f64::NEG_INFINITY;
    for tick in ticks {
        let t = tick["log_time"].as_u64().unwrap();
        assert_eq!(tick["time"].as_f64(), Some(t as f64 * 1e-9), "{tick}");
        let inside = || {
            samples
                .iter()
                .filter(|(lt, _, _)| (t - half..t + half).contains(lt))
        };
        let mut want: HashMap<&str, (f64, f64)> = HashMap::new();
        let mut put = |name, v: f64| {
            let r = want.entry(name).or_insert((v, v));
            *r = (r.0.min(v), r.1.max(v));
        };
        for (_, topic, wire) in inside() {
            if *topic == Topic::State {
                let s: PlantState = tilting_proto::decode(wire).unwrap();
                put("alpha", s.alpha);
                put("beta", s.beta);
            } else {
                let c: tilting_proto::TorqueCommand = tilting_proto::decode(wire).unwrap();
                put("tau", c.tau);
            }
        }
        for (name, (lo, hi)) in &want {
            let got = (
                tick[format!("{name}_min")].as_f64(),
                tick[format!("{name}_max")].as_f64(),
            );
            assert_eq!(got, (Some(*lo), Some(*hi)), "{subprotocol} {name}: {tick}");
        }
        peak = peak.max(tick["alpha_max"].as_f64().unwrap_or(f64::NEG_INFINITY));
        let (lo, hi) = (tick["energy_min"].as_f64(), tick["energy_max"].as_f64());
        assert!(lo <= hi && lo.is_some(), "{subprotocol}: {tick}");
    }
    // The tilt's peak over the ticks is a recorded state's alpha, and a tilt (over 0.01 rad).
    assert!(peak > 0.01, "{subprotocol}: alpha peaks at {peak}");
}

/// What `ws_client.mjs` saw under `subprotocol`: every channel decoded with its schema (taken
/// `from` inline or the schema table; the library passing it on or not), the recording's states.
fn check_node_client(
    got: &serde_json::Value,
    subprotocol: &str,
    from: &str,
    library: bool,
    robot: &str,
    states: &HashMap<u64, PlantState>,
) {
    assert_eq!(got["subprotocol"], subprotocol, "{got}");
    let topics = got["topics"].as_object().unwrap();
    let want = [
        ("plant/state", "json", "tilting.PlantState"),
        ("controller/torque", "json", "tilting.TorqueCommand"),
        ("plant/event", "json", "tilting.ModeEvent"),
        ("plant/status", "json", "tilting.Status"),
        ("planner/reference", "json", "tilting.Reference"),
        ("energy", "json", "tilting.Energy"),
        ("plot", "json", "tilting.Plot"),
        ("tf", "protobuf", "foxglove.FrameTransforms"),
        ("scene", "protobuf", "foxglove.SceneUpdate"),
        ("log", "protobuf", "foxglove.Log"),
    ];
    assert_eq!(
        topics.len(),
        want.len(),
        "{subprotocol}: {:?}",
        topics.keys()
    );
    for (t, encoding, schema) in want {
        let ch = &topics[&format!("/tilting/{robot}/{t}")];
        assert_eq!(
            (ch["encoding"].as_str(), ch["schemaName"].as_str()),
            (Some(encoding), Some(schema)),
            "{subprotocol} {t}: {ch}"
        );
        assert_eq!(
            ch["errors"],
            serde_json::json!([]),
            "{subprotocol} {t}: {ch}"
        );
        assert!(ch["count"].as_u64().unwrap() > 0, "{subprotocol} {t}: {ch}");
        assert_eq!(ch["schemaFrom"], from, "{subprotocol} {t}");
        assert_eq!(ch["libraryHasSchema"], library, "{subprotocol} {t}");
    }
    let got_states = got["states"].as_array().unwrap();
    assert!(
        got_states.len() as f64 >= 0.9 * states.len() as f64,
        "{subprotocol}: {} of {} states",
        got_states.len(),
        states.len()
    );
    for s in got_states {
        let r = &states[&s["seq"].as_u64().unwrap()];
        assert_eq!(s["time"].as_f64(), Some(r.time));
        assert_eq!(s["mode_name"], r.mode().unwrap().as_str());
    }
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    let logs = got["logs"].as_array().unwrap();
    assert!(logs
        .iter()
        .any(|l| l["message"].as_str().unwrap().contains("(landing)")));
    for l in logs {
        let (message, level) = (l["message"].as_str().unwrap(), l["level"].as_i64().unwrap());
        // Wall clock (a viewer shows today's date), the plant time in the words.
        let stamp = l["sec"].as_f64().unwrap() + 1e-9 * l["nsec"].as_f64().unwrap();
        assert!(
            (now - stamp).abs() < 600.0,
            "{l}: stamped {stamp}, now {now}"
        );
        assert!(message.starts_with("plant t = "), "{l}");
        // Mode changes are routine: debug (1), below the info (2) a log panel shows.
        assert_eq!(message.contains(" -> "), level == 1, "{l}");
    }
    for e in got["events"].as_array().unwrap() {
        for (byte, name) in [("from", "from_name"), ("to", "to_name")] {
            let mode = tilting_proto::Mode::try_from(e[byte].as_u64().unwrap() as u8).unwrap();
            assert_eq!(e[name], mode.as_str(), "{e}");
        }
    }
    let ids = got["sceneEntityIds"].as_array().unwrap();
    for id in ["ground", "plate", "arm", "pivot", "title"] {
        assert!(ids.iter().any(|i| i == id), "{subprotocol}: {ids:?}");
    }
}
