//! The example plant in Python (`examples/python/plant.py`, written from docs/model.md and
//! docs/protocol.md only) speaks the plant's topics: our Rust `tilting-controller` drives it in
//! lockstep, and the run reproduces the offline sampled loop computed here with the Rust
//! libraries (DOP853, event location on its dense output), sample by sample, with the same
//! mode transitions. Each side is told the other's zenoh id (`--controller-id`, `--plant-id`)
//! and believes only messages whose TSRC attachment names it: the Python plant's states carry
//! a source the Rust controller accepts (`states_foreign: 0`, every state answered), and the
//! Rust controller's torques one the Python plant accepts.
//!
//! Needs `python3` with the `zenoh` module (`.ci/run` installs `eclipse-zenoh`); without it the
//! tests print a SKIP line and pass.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_proto::{ModeEvent, PlantState, Status};
use tilting_tests::recording::{largest_differences, offline, offline_with_events, parse_csv, Row};
use tilting_tests::*;

const PERIOD: f64 = 0.001;
/// Two seconds of the `k = 500` orbit under a 1 kHz hold: four tilts (left, right, left,
/// right), three landings each followed by a re-tilt at the next sample, the last tilt
/// unfinished.
const DURATION: f64 = 2.0;

/// Agreement required between the Python plant's run and the offline Rust loop, on every state
/// component (rad, rad/s) and torque (N m), and on the transition times (s).
///
/// Not bit-identical: the two plants integrate the same equations with different methods. The
/// Rust one is DOP853 at `rtol = 3e-11`, `atol = 3e-13` with event location on its dense
/// output; the Python one fixed-step RK4 at 0.1 ms with switching times bisected to 1e-13 s.
/// Both are far more accurate than 1e-9 over 2 s, and the sampled loop amplifies a difference
/// by only about five per second of plant time (examples/python/README.md). Measured on this
/// run: 4.8e-13 on a state component, 1.6e-11 N m on a torque (the energy adaptation `k = 500`
/// multiplies state differences), 1.6e-13 s on a transition time. 1e-9, the bound of the
/// Python controller's test, leaves a factor of 60 above that, and is still tight enough to
/// catch a real mistake: an impact gain off by one part in a million moves the state by 3e-6
/// within these 2 s, and a Coriolis term off by a factor of two by 8e-3.
const TOLERANCE: f64 = 1e-9;

fn script() -> PathBuf {
    workspace_root().join("examples/python/plant.py")
}

/// The part of plant.py's summary this test reads (its fields are named as the Rust plant's).
#[derive(Debug, serde::Deserialize)]
struct PyPlantSummary {
    result: RunResult,
    steps: u64,
    deadline_misses: u64,
    torques_dropped: u64,
    torques_stale: u64,
    watchdog_trips: u64,
    torques_foreign: u64,
}

/// The zenoh ids of the Python plant and the Rust controller, chosen before either starts.
const PLANT_ID: &str = "5a17c0de0000000000000000000000a1";
const CONTROLLER_ID: &str = "c0417201000000000000000000000b2";

#[test]
fn python_plant_self_test() {
    // Encodings against the worked examples, the model against the checks of docs/model.md
    // (energy, mirror symmetry, angular momentum at the impact, ZMP at rest); needs no zenoh.
    python_self_test("python_plant_self_test", &script());
}

/// Starts plant.py for [`DURATION`] s recording to `csv`, with `extra` flags.
fn spawn_plant(dir: &Scratch, robot: &str, port: u16, csv: &Path, extra: &[&str]) -> Proc {
    let mut args = vec![script().to_str().unwrap().to_owned()];
    let duration = DURATION.to_string();
    let mut flags = vec!["--duration", &duration, "--record", csv.to_str().unwrap()];
    flags.extend(["--zenoh-id", PLANT_ID, "--controller-id", CONTROLLER_ID]);
    flags.extend(extra);
    args.extend(plant_args(robot, port, &flags));
    Proc::spawn("plant.py", Path::new(&python()), &args, dir.path())
}

/// Waits for the plant's liveliness token (as the protocol requires), then starts our
/// controller. `client`'s subscriptions, declared before, have reached the plant by then.
async fn start_controller(
    client: &Client,
    plant: &Proc,
    dir: &Scratch,
    robot: &str,
    port: u16,
) -> Proc {
    let alive = client.keys.alive_plant().to_owned();
    let (presence, _watch) = tilting_net::watch_presence(&client.session, &alive, |_| {})
        .await
        .unwrap();
    let seen = poll_until(Duration::from_secs(20), || presence.alive().then_some(())).await;
    assert!(
        seen.is_some(),
        "no liveliness token {alive} within 20 s\n{}",
        plant.logs()
    );
    // A little slack for the routing tables.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let ctl_bin = bin("tilting-controller");
    Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(
            robot,
            port,
            &["--zenoh-id", CONTROLLER_ID, "--plant-id", PLANT_ID],
        ),
        dir.path(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rust_controller_drives_the_python_plant_like_the_rust_one() {
    let _turn = realtime_turn();
    if !python_runs("import zenoh") {
        let why = format!(
            "`{} -c \"import zenoh\"` failed; install it with `python3 -m pip install \
             'eclipse-zenoh==1.10.2'`",
            python()
        );
        skip(
            "rust_controller_drives_the_python_plant_like_the_rust_one",
            Missing::Package,
            &why,
        );
        return;
    }
    let dir = Scratch::new("python-plant");
    let port = free_port();
    let robot = robot("python_plant");
    let csv = dir.path().join("rec.csv");
    let started = Instant::now();
    let mut plant = spawn_plant(&dir, &robot, port, &csv, &[]);

    // A watcher of the plant's other topics: events and status, decoded by the Rust codec.
    let client = Client::open(&robot, None, Some(port)).await;
    let events: Arc<Mutex<Vec<Result<ModeEvent, String>>>> = Arc::default();
    let statuses: Arc<Mutex<Vec<Result<Status, String>>>> = Arc::default();
    let (e, s) = (events.clone(), statuses.clone());
    let _event_sub = client
        .session
        .declare_subscriber(client.keys.plant_event().to_owned())
        .callback(move |m| {
            let r = tilting_proto::decode::<ModeEvent>(&m.payload().to_bytes());
            e.lock().unwrap().push(r.map_err(|e| e.to_string()));
        })
        .await
        .unwrap();
    let _status_sub = client
        .session
        .declare_subscriber(client.keys.plant_status().to_owned())
        .callback(move |m| {
            let r = tilting_proto::decode::<Status>(&m.payload().to_bytes());
            s.lock().unwrap().push(r.map_err(|e| e.to_string()));
        })
        .await
        .unwrap();
    let mut ctl = start_controller(&client, &plant, &dir, &robot, port).await;
    let status = plant.expect_exit(Duration::from_secs(120));
    let elapsed = started.elapsed();
    assert!(
        status.success(),
        "plant.py: {status}\n{}\n{}",
        plant.logs(),
        ctl.logs()
    );
    let summary: PyPlantSummary =
        serde_json::from_value(plant.summary_json()).expect("plant.py's summary");
    eprintln!("plant.py summary: {summary:?}");
    let n = (DURATION / PERIOD).round() as u64;
    assert_eq!(summary.result, RunResult::Completed, "{summary:?}");
    assert_eq!(summary.steps, n, "{summary:?}");
    let counters = [
        summary.deadline_misses,
        summary.torques_dropped,
        summary.torques_stale,
        summary.watchdog_trips,
        summary.torques_foreign,
    ];
    assert_eq!(counters, [0; 5], "{summary:?}");
    let c_status = ctl.interrupt(Duration::from_secs(10));
    assert!(c_status.success(), "{}", ctl.logs());
    let c_summary = ctl.controller_summary();
    assert_eq!(c_summary.states_dropped, 0, "{c_summary:?}");
    // Every state named the Python plant's session, as the controller was told to expect.
    assert_eq!(c_summary.states_foreign, 0, "{c_summary:?}");
    assert!(c_summary.torques_published >= n, "{c_summary:?}");

    // Sample by sample against the offline Rust loop.
    let got = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let (want, transitions) = offline_with_events(DURATION, PERIOD);
    // The documented default start is the Rust one, bit for bit.
    assert_eq!(got[0].x, want[0].x, "initial state");
    // Sample times are k h, a product in both: exact.
    let (mut worst_x, worst_tau) = largest_differences(&got, &want);

    // The mode transitions, as published on the event topic.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let events = events.lock().unwrap().clone();
    let events: Vec<ModeEvent> = events
        .into_iter()
        .map(|r| r.expect("every event payload decodes"))
        .collect();
    assert_eq!(
        events.len(),
        transitions.len(),
        "events {events:?}\noffline {transitions:?}"
    );
    let mut worst_t = 0.0f64;
    for (e, w) in events.iter().zip(&transitions) {
        assert_eq!(
            (e.from, e.to),
            (w.from.as_u8(), w.to.as_u8()),
            "{e:?} {w:?}"
        );
        // Published after the period it happened in, with that period's seq.
        assert_eq!(e.seq, (w.t / PERIOD).floor() as u64, "{e:?} {w:?}");
        worst_t = worst_t.max((e.time - w.t).abs());
        for i in 0..4 {
            worst_x = worst_x.max((e.x_before[i] - w.x_before[i]).abs());
            worst_x = worst_x.max((e.x_after[i] - w.x_after[i]).abs());
        }
    }
    let landings = transitions.iter().filter(|t| t.to.as_u8() == 0).count();
    let tilts = transitions.len() - landings;
    assert!(
        landings >= 2 && tilts >= 3,
        "the reference run should tilt and land several times: {transitions:?}"
    );
    assert!(
        want.iter().any(|r| r.mode == 1) && want.iter().any(|r| r.mode == 2),
        "the reference run should tilt both ways"
    );

    // The status: valid payloads, the last one `stopped` with the final counters.
    let statuses = statuses.lock().unwrap().clone();
    let statuses: Vec<Status> = statuses
        .into_iter()
        .map(|r| r.expect("every status payload decodes"))
        .collect();
    let last = statuses.last().expect("some status");
    assert_eq!(last.state, Status::STOPPED, "{last:?}");
    assert_eq!((last.seq, last.steps), (n, n), "{last:?}");
    assert_eq!(last.time, DURATION, "{last:?}");
    assert_eq!(last.tilts, tilts as u64, "{last:?}");
    assert!(
        statuses.iter().any(|s| s.state == Status::RUNNING),
        "no `running` status"
    );

    eprintln!(
        "python plant vs offline Rust loop: {} samples, {} transitions; largest difference: \
         state {worst_x:e}, torque {worst_tau:e} N m, transition time {worst_t:e} s; \
         run took {:.1} s",
        got.len(),
        events.len(),
        elapsed.as_secs_f64()
    );
    assert!(worst_x <= TOLERANCE, "largest state difference {worst_x:e}");
    assert!(
        worst_tau <= TOLERANCE,
        "largest torque difference {worst_tau:e}"
    );
    assert!(
        worst_t <= TOLERANCE,
        "largest transition time difference {worst_t:e}"
    );
}

/// The offline loop of the controller node with `--measure angles`: the Rust plant (settings of
/// `recording::offline`), its exact angles to the hybrid observer (`Estimation`, `--estimator auto`), the
/// node's default law on the estimate, each torque recorded as sent at its sample.
fn offline_measuring_angles(duration: f64, period: f64) -> Vec<Row> {
    use tilting_controller::estimate::{Estimation, EstimatorChoice};
    use tilting_controller::{ControlConfig, Controller, LawSpec};
    use tilting_plant::imperfect::Measurement;
    use tilting_plant::{paper, Plant, SimConfig, Tolerance};
    let model = SimConfig::default();
    let rtol = Tolerance::default().rtol;
    let tol = Tolerance {
        rtol,
        atol: rtol * 1e-2,
    };
    let cfg = SimConfig { tol, ..model };
    let mut plant = Plant::new(cfg, 0.0, paper::ORBIT_MODE, paper::orbit_state()).unwrap();
    let law = Controller::new(ControlConfig::new(model.params, LawSpec::default())).unwrap();
    let mut est = Estimation::new(EstimatorChoice::Auto, model);
    let n = (duration / period).round() as u64;
    let mut rows = Vec::new();
    for k in 0..=n {
        let (t, mode, x) = (plant.time(), plant.mode(), plant.state());
        let mut row = Row {
            t,
            mode: mode.as_u8(),
            x: [x[0], x[1], x[2], x[3]],
            tau: None,
            seq: k,
        };
        if k < n {
            let y = Measurement {
                angles: [x[0], x[1]],
                rates: None,
            };
            let tau = law.torque(t, mode, &est.state(t, mode, &y));
            est.sent(t, tau);
            row.tau = Some(tau);
            plant
                .advance_held(tau, (k + 1) as f64 * period, &mut ())
                .unwrap();
        }
        rows.push(row);
    }
    rows
}

/// `--measure angles`: the Python plant publishes the angles only (`measured = 3`, the rates
/// absent to the Rust decoder), and our controller estimates the rates with its hybrid observer
/// on every state. Checked against an independent re-simulation: the same loop offline with
/// the Rust plant (DOP853) and the same observer and law.
///
/// [`TOLERANCE`] on the true states and torques, as above: measured 6.8e-12 (the observer's
/// gain turns the plants' 1e-13 of angle difference into rate differences, which the torques
/// carry). The check discriminates: the same loop reading exact rates differs from it by more
/// than 1e-3 (the observer starts from zero rates, the orbit's arm rate is 0.5 rad/s).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_plant_measuring_angles_drives_the_rust_observer() {
    let _turn = realtime_turn();
    if !python_runs("import zenoh") {
        skip(
            "python_plant_measuring_angles_drives_the_rust_observer",
            Missing::Package,
            "no zenoh module",
        );
        return;
    }
    let dir = Scratch::new("python-plant-angles");
    let port = free_port();
    let robot = robot("python_plant_angles");
    let csv = dir.path().join("rec.csv");
    let mut plant = spawn_plant(&dir, &robot, port, &csv, &["--measure", "angles"]);
    let client = Client::open(&robot, None, Some(port)).await;
    let rates: Arc<Mutex<Vec<Option<[f64; 2]>>>> = Arc::default();
    let r = rates.clone();
    let _state_sub = client
        .session
        .declare_subscriber(client.keys.plant_state().to_owned())
        .callback(move |m| {
            let s = tilting_proto::decode::<PlantState>(&m.payload().to_bytes());
            r.lock()
                .unwrap()
                .push(s.expect("every state decodes").rates());
        })
        .await
        .unwrap();
    let mut ctl = start_controller(&client, &plant, &dir, &robot, port).await;
    let status = plant.expect_exit(Duration::from_secs(120));
    assert!(status.success(), "{}\n{}", plant.logs(), ctl.logs());
    let summary: PyPlantSummary = serde_json::from_value(plant.summary_json()).unwrap();
    let n = (DURATION / PERIOD).round() as u64;
    assert_eq!((summary.result, summary.steps), (RunResult::Completed, n));
    let bad = summary.torques_dropped + summary.deadline_misses + summary.torques_foreign;
    assert_eq!(bad, 0, "{summary:?}");
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let est = ctl
        .controller_summary()
        .estimation
        .expect("the controller estimated");
    assert_eq!(est.method, tilting_controller::estimate::Method::Observer);
    assert!(est.estimates >= n && est.fallbacks == 0, "{est:?}");
    let rates = rates.lock().unwrap().clone();
    assert!(rates.len() as u64 >= n && rates.iter().all(Option::is_none));

    let got = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let want = offline_measuring_angles(DURATION, PERIOD);
    assert_eq!(got.len(), want.len(), "number of samples");
    let largest = |a: &[Row], b: &[Row]| {
        let mut worst = 0.0f64;
        for (g, w) in a.iter().zip(b) {
            assert_eq!((g.seq, g.t), (w.seq, w.t), "{w:?}");
            let d = g.x.iter().zip(&w.x).map(|(a, b)| (a - b).abs());
            let dt = (g.tau.unwrap_or(0.0) - w.tau.unwrap_or(0.0)).abs();
            worst = d.fold(worst.max(dt), f64::max);
        }
        worst
    };
    let worst = largest(&got, &want);
    assert!(got.iter().zip(&want).all(|(g, w)| g.mode == w.mode));
    assert!(largest(&offline(DURATION, PERIOD), &want) > 1e-3);
    let tilts = want.windows(2).filter(|p| p[0].mode == 0 && p[1].mode != 0);
    assert!(tilts.count() >= 3, "the reference run tilts");
    eprintln!("python plant (angles only) vs offline Rust loop: largest difference {worst:e}");
    assert!(
        worst <= TOLERANCE,
        "largest state/torque difference {worst:e}"
    );
}
