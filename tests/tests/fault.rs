//! A fault of the model ends the run cleanly: the status says `faulted` with the reason, the
//! summary too, and the exit code is 3.

use std::time::Duration;
use tilting_proto::{codec, PlantState, Status, TorqueCommand};
use tilting_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fault_is_published_and_ends_the_run_with_exit_code_3() {
    let plant_bin = bin("tilting-plant");
    let dir = Scratch::new("fault");
    let port = free_port();
    let robot = robot("fault");
    // Tilted far over with the arm low and no torque in safe mode: the plate loses contact.
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(
            &robot,
            port,
            &[
                "--safe-mode",
                "zero",
                "--mode",
                "left",
                "--x0",
                "0.3,1.2,0,0",
            ],
        ),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    // The test is a controller without a liveliness token: it answers state 0 once, which
    // starts the plant's clock, and then falls silent.
    let torque = client
        .session
        .declare_publisher(client.keys.controller_torque().to_owned())
        .await
        .unwrap();
    let states = client
        .session
        .declare_subscriber(client.keys.plant_state().to_owned())
        .await
        .unwrap();
    let s0 = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let s = states.recv_async().await.unwrap();
            if let Ok(s) = tilting_proto::decode::<PlantState>(&s.payload().to_bytes()) {
                break s;
            }
        }
    })
    .await
    .expect("no state 0");
    assert_eq!(s0.seq, 0);
    torque
        .put(codec::encode(&TorqueCommand { seq: 0, tau: 0.0 }))
        .await
        .unwrap();

    let (_, s) = status
        .wait_for(Duration::from_secs(10), |s| s.state == Status::FAULTED)
        .await
        .unwrap_or_else(|| panic!("no faulted status\n{}", plant.logs()));
    assert!(s.fault.contains("contact loss"), "{s:?}");
    assert_eq!(s.watchdog_trips, 1);
    let exit = plant.expect_exit(Duration::from_secs(10));
    assert_eq!(exit.code(), Some(3), "{}", plant.logs());
    let summary = plant.plant_summary();
    assert_eq!(summary.result, RunResult::Faulted);
    assert!(summary.fault.as_deref().unwrap().contains("contact loss"));
}
