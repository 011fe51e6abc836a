//! The README's "Three hosts (and a recorder)" recipe, on loopback addresses of one machine:
//! `tilting certs --router-host 127.0.0.2 --host logger=127.0.0.3`, then the router, the plant,
//! the controller and `tilting record` started with nothing but their configuration files and
//! the zenoh ids (`--zenoh-id`, `--plant-id`, `--controller-id`), as the recipe starts them. The
//! endpoints come from the files: the plant listens on 127.0.0.2:7448, the recorder on
//! 127.0.0.3:7449, the controller dials both and the router, every dialler checking the name in
//! the certificate it is shown. The truth: the plant's own summary (torques applied, none
//! foreign) and the recording (read back), which holds the plant's states and the controller's
//! torques from their pinned sessions, and no reference (the recorder takes nothing from the
//! router).

use std::time::Duration;
use tilting_proto::Topic;
use tilting_tests::*;

#[test]
fn the_three_hosts_recipe_runs_on_direct_links_named_in_the_certificates() {
    let _turn = realtime_turn();
    let dir = Scratch::new("hosts");
    let robot = robot("hosts");
    let certs = dir.path().join("certs");
    let router_ep = format!("tls/127.0.0.2:{}", free_port());
    let s = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<String>>();
    let made = std::process::Command::new(bin("tilting"))
        .args(s(&["certs", "--robot", &robot, "--out"]))
        .arg(&certs)
        .args(s(&[
            "--router-host",
            "127.0.0.2",
            "--router-endpoint",
            &router_ep,
            "--host",
            "logger=127.0.0.3",
        ]))
        .output()
        .unwrap();
    assert!(made.status.success(), "{made:?}");
    let cfg = |node: &str| certs.join(format!("{node}.json5")).display().to_string();
    // Ids as the recipe draws them (`openssl rand -hex 16`): 32 hex digits.
    let (p, c) = (
        "6e1f3a5c7d9b0e2f4a6c8e0b1d3f5a7c",
        "c7a5f3d1b0e8c6a4f2e0b9d7c5a3f1e6",
    );
    let mut router = start_router(dir.path(), &certs, &router_ep);
    let out = dir.path().join("run.mcap");
    let mut record = Proc::spawn(
        "record",
        &bin("tilting"),
        &s(&[
            "record",
            "--robot",
            &robot,
            "--zenoh-config",
            &cfg("logger-direct"),
            "--plant-id",
            p,
            "--controller-id",
            c,
            "--seconds",
            "60",
            "--wait",
            "30",
            "--out",
            &out.display().to_string(),
        ]),
        dir.path(),
    );
    let duration = 3.0;
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &s(&[
            "--robot",
            &robot,
            "--zenoh-config",
            &cfg("plant-direct"),
            "--zenoh-id",
            p,
            "--controller-id",
            c,
            "--duration",
            &duration.to_string(),
        ]),
        dir.path(),
    );
    let mut controller = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &s(&[
            "--robot",
            &robot,
            "--zenoh-config",
            &cfg("controller-direct"),
            "--zenoh-id",
            c,
            "--plant-id",
            p,
        ]),
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "{status}\n{}", plant.logs());
    // The last messages reach the recorder, then everyone stops.
    std::thread::sleep(Duration::from_millis(500));
    controller.interrupt(Duration::from_secs(10));
    let status = record.interrupt(Duration::from_secs(10));
    assert!(status.success(), "{status}\n{}", record.logs());
    router.interrupt(Duration::from_secs(10));

    let summary: serde_json::Value = plant
        .stdout()
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("the plant's summary\n{}", plant.logs()));
    let n = |k: &str| {
        summary[k]
            .as_u64()
            .unwrap_or_else(|| panic!("{k}: {summary}"))
    };
    let (steps, applied) = (n("steps"), n("torques_applied"));
    eprintln!(
        "plant: {steps} periods, {applied} torques applied, {} foreign",
        n("torques_foreign")
    );
    // The controller reached the plant over the direct link (its name checked): it answered
    // (nearly) every period; nobody else's torque was taken.
    assert_eq!(steps, (duration * 1000.0) as u64, "{summary}");
    assert!(applied > steps / 2, "{summary}");
    assert_eq!(n("torques_foreign"), 0, "{summary}");
    // The recorder on 127.0.0.3 got both streams on its own links, the plant's (it dialled
    // 127.0.0.2:7448) and the controller's (which dialled it at 127.0.0.3:7449).
    let run = tilting_record::read(&out).unwrap_or_else(|e| panic!("{e}\n{}", record.logs()));
    let (states, torques) = (run.count(Topic::State), run.count(Topic::Torque));
    eprintln!(
        "recorded {states} states, {torques} torques, {} references",
        run.count(Topic::Reference)
    );
    assert!(states > steps / 2, "{states} states");
    assert!(torques > applied / 2, "{torques} torques");
    assert_eq!(run.count(Topic::Reference), 0);
    let said = record.stdout();
    assert!(said.contains("foreign 0"), "{said}");
}
