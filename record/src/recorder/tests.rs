use super::*;

fn state(seq: u64, mode: u8, alpha: f64) -> PlantState {
    PlantState {
        seq,
        time: seq as f64 * 1e-3,
        alpha,
        beta: 1.5,
        alpha_dot: Some(0.0),
        beta_dot: Some(0.0),
        mode,
    }
}

fn keys() -> Keys {
    Keys::new("t").unwrap()
}

/// The rules of a 1 kHz plant with the default bounds, started with the recorder.
fn rules() -> Rules {
    Rules {
        period: Some(1e-3),
        min_period: 1e-4,
        max_torque: 116.5,
        fall_angle: std::f64::consts::FRAC_PI_2,
        from_start: true,
    }
}

#[test]
fn a_peak_reached_in_the_unfinished_last_tilt_counts() {
    // The truth is the samples themselves: alpha rises to its largest sample, then falls
    // (a peak, though the tilt never lands) or only rises (no peak yet).
    for (turned_back, want) in [(true, 1), (false, 0)] {
        let tmp = tempfile::tempdir().unwrap();
        let rec = Recorder::create(tmp.path(), &keys(), false, None, Sources::default()).unwrap();
        let tx = rec.sender();
        let n = if turned_back { 60 } else { 20 };
        for k in 0..n {
            tx.send(Record::State(state(k, 1, 0.03 * (k as f64 * 0.06).sin())));
        }
        let v = rec.finish().unwrap();
        assert_eq!(v.peaks.len(), want, "turned back: {turned_back}");
        if turned_back {
            let best =
                (0..n).max_by(|&a, &b| (a as f64 * 0.06).sin().total_cmp(&(b as f64 * 0.06).sin()));
            let k = best.unwrap();
            assert_eq!(
                v.peaks[0],
                (k as f64 * 1e-3, 0.03 * (k as f64 * 0.06).sin())
            );
        }
    }
}

#[test]
fn writes_dedups_and_tracks_peaks() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let rec = Recorder::create(&dir, &keys(), true, None, Sources::default()).unwrap();
    let tx = rec.sender();
    tx.send(Record::State(state(0, 1, 0.0)));
    tx.send(Record::State(state(0, 1, 0.0))); // re-published
    tx.send(Record::Torque(TorqueCommand { seq: 0, tau: 1.0 }));
    tx.send(Record::Torque(TorqueCommand { seq: 0, tau: 1.0 }));
    for k in 1..100u64 {
        let (mode, alpha) = if k < 50 {
            (1, 0.01 * (k as f64 * 0.06).sin())
        } else {
            (2, -0.02 * ((k - 50) as f64 * 0.06).sin())
        };
        tx.send(Record::State(state(k, mode, alpha)));
        tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.5 }));
    }
    tx.send(Record::State(state(105, 0, 0.0))); // a gap of 5
    tx.send(Record::Event(ModeEvent {
        seq: 49,
        time: 0.0495,
        from: 1,
        to: 0,
        x_before: [0.0, 1.0, -0.1, 0.2],
        x_after: [0.0, 1.0, 0.0, -0.2],
    }));
    tx.send(Record::Event(ModeEvent {
        seq: 49,
        time: 0.0495,
        from: 0,
        to: 2,
        x_before: [0.0, 1.0, 0.0, -0.2],
        x_after: [0.0, 1.0, 0.0, -0.2],
    }));
    let v = rec.finish().unwrap();
    assert_eq!((v.states, v.torques, v.events, v.tilts), (101, 100, 2, 1));
    assert_eq!((v.repeated_states, v.repeated_torques), (1, 1));
    assert_eq!(v.missing_states, 5);
    assert_eq!(v.peaks.len(), 2);
    let want = (1..50)
        .map(|k| 0.01 * (k as f64 * 0.06).sin())
        .fold(0.0, f64::max);
    assert_eq!(v.peaks[0].1, want);
    assert!(v.peaks[1].1 < -0.019);
    let text = std::fs::read_to_string(dir.join(STATE_CSV)).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(STATE_HEADER));
    assert_eq!(lines.next(), Some("0,0,1,0,1.5,0,0"));
    assert_eq!(text.lines().count(), 102);
    let ev = std::fs::read_to_string(dir.join(EVENTS_CSV)).unwrap();
    assert_eq!(ev.lines().nth(2), Some("0.0495,0,2,0,1,0,-0.2,0,1,0,-0.2"));
    // The MCAP recording holds the same, deduplicated.
    let run = crate::read(&dir.join(RUN_MCAP)).unwrap();
    assert!(run.complete());
    assert_eq!(
        (
            run.count(Topic::State),
            run.count(Topic::Torque),
            run.count(Topic::Event)
        ),
        (101, 100, 2)
    );
    let tr = crate::load(&dir, Default::default(), None).unwrap().trace;
    assert_eq!((tr.samples.len(), tr.events.len()), (101, 2));
    assert_eq!(tr.end, 0.105);
    // And so do the CSV files.
    std::fs::remove_file(dir.join(RUN_MCAP)).unwrap();
    let csv = crate::load(&dir, Default::default(), None).unwrap().trace;
    assert_eq!(csv, tr);
}

/// Wire payloads as received: every copy kept without `skip_repeats`, one that does not
/// decode counted and not written.
#[test]
fn wire_payloads_are_decoded_and_kept_as_sent() {
    let tmp = tempfile::tempdir().unwrap();
    let opts = Options {
        mcap: tmp.path().join("r.mcap"),
        csv_dir: None,
        skip_repeats: false,
        rules: None,
        sources: None,
    };
    let rec = Recorder::with_options(&opts, &keys()).unwrap();
    let tx = rec.sender();
    for _ in 0..3 {
        tx.send(Record::Wire(Topic::State, encode(&state(0, 0, 0.0))));
    }
    tx.send(Record::Wire(Topic::Torque, vec![1, 2, 3]));
    let v = rec.finish().unwrap();
    assert_eq!((v.states, v.repeated_states, v.invalid), (3, 0, 1));
    assert_eq!((v.count(Topic::State), v.count(Topic::Torque)), (3, 0));
    let run = crate::read(&opts.mcap).unwrap();
    assert_eq!(run.count(Topic::State), 3);
}

/// The forged state of issue 22 (`seq = 2^63`, `time = 1e300`) and a forged torque amid a
/// plausible stream: both refused and counted, and the recording is the stream without them
/// (the truth: the same stream recorded without the forgeries).
#[test]
fn forged_messages_are_refused_and_change_nothing() {
    let rules = rules();
    let run = |forge: bool| {
        let tmp = tempfile::tempdir().unwrap();
        let rec =
            Recorder::create(tmp.path(), &keys(), false, Some(rules), Sources::default()).unwrap();
        let tx = rec.sender();
        for k in 0..200u64 {
            if forge && k == 50 {
                let mut lie = state(1 << 63, 1, 0.01);
                lie.time = 1e300;
                tx.send(Record::State(lie));
                tx.send(Record::Torque(TorqueCommand {
                    seq: 1 << 62,
                    tau: 1.0,
                }));
                tx.send(Record::Torque(TorqueCommand { seq: 49, tau: 1e6 }));
                // On its grid, but 2^40 periods ahead of the wall clock.
                tx.send(Record::State(state(1 << 40, 1, 0.01)));
            }
            tx.send(Record::State(state(k, 1, 0.03 * (k as f64 * 0.06).sin())));
            tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.5 }));
        }
        let v = rec.finish().unwrap();
        let file = crate::read(&tmp.path().join(RUN_MCAP)).unwrap();
        (v, file.count(Topic::State), file.span())
    };
    let (clean, n0, span0) = run(false);
    let (v, n, span) = run(true);
    assert_eq!(v.refused, [2, 2, 0, 0, 0]);
    assert!(
        v.first_refusal
            .as_deref()
            .unwrap()
            .contains("PlantState.seq"),
        "{v:?}"
    );
    assert_eq!((v.states, v.torques, v.missing_states), (200, 200, 0));
    assert_eq!((n, span), (n0, span0));
    assert_eq!(span, Some((0.0, 0.199)));
    assert_eq!(v.peaks, clean.peaks);
    assert_eq!(clean.refused, [0; 5]);
}

/// A second session publishing plausible states (one period ahead, on the grid) and
/// torques amid the plant's and the controller's streams, naming no source or its own:
/// every one refused as foreign, and the recording is the honest stream's (the truth: the
/// same stream recorded alone). A forger that copies the plant's id passes: the identity
/// is the publisher's claim ([`tilting_proto::source`]).
#[test]
fn messages_from_a_foreign_source_are_refused_and_change_nothing() {
    let rules = rules();
    let (plant, ctl, other) = (
        Some(SourceId([1; 16])),
        Some(SourceId([2; 16])),
        Some(SourceId([3; 16])),
    );
    let run = |forge: bool, copy_id: bool| {
        let tmp = tempfile::tempdir().unwrap();
        let rec =
            Recorder::create(tmp.path(), &keys(), false, Some(rules), Sources::default()).unwrap();
        let tx = rec.sender();
        for k in 0..200u64 {
            if forge && (50..60).contains(&k) {
                let from = match (copy_id, k % 2) {
                    (true, _) => plant,
                    (false, 0) => other,
                    (false, _) => None,
                };
                tx.send_from(Record::State(state(k, 1, 0.3)), from);
                let torque_from = if copy_id { ctl } else { from };
                let t = TorqueCommand {
                    seq: k - 1,
                    tau: 3.25,
                };
                tx.send_from(Record::Torque(t), torque_from);
            }
            let s = state(k, 1, 0.03 * (k as f64 * 0.06).sin());
            tx.send_from(Record::State(s), plant);
            tx.send_from(Record::Torque(TorqueCommand { seq: k, tau: 0.5 }), ctl);
        }
        let v = rec.finish().unwrap();
        let file = crate::read(&tmp.path().join(RUN_MCAP)).unwrap();
        let states: Vec<Vec<u8>> = file
            .messages()
            .filter(|m| m.topic == Topic::State)
            .map(|m| m.wire)
            .collect();
        (v, states)
    };
    let (clean, truth) = run(false, false);
    let (v, states) = run(true, false);
    assert_eq!(v.refused, [10, 10, 0, 0, 0], "{v:?}");
    assert_eq!(v.foreign, 20);
    let first = v.first_refusal.as_deref().unwrap();
    assert!(
        first.contains("PlantState from a foreign source"),
        "{first}"
    );
    assert_eq!(states, truth);
    assert_eq!((v.states, v.torques, v.missing_states), (200, 200, 0));
    assert_eq!(v.peaks, clean.peaks);
    assert_eq!((clean.refused, clean.foreign), ([0; 5], 0));
    // The limit: the plant's own id, copied, is believed (the forged state of seq k takes
    // the place of the plant's, which then counts as a repeat).
    let (v, states) = run(true, true);
    assert_eq!((v.refused, v.foreign), ([0; 5], 0));
    assert_ne!(states, truth);
}

/// A rogue session that publishes plausible states and torques *before* the plant and the
/// controller start (seq 0..10, alpha 0.3 rad). With the sources unknown, the rogue's first
/// state takes the pin and the plant's whole stream is refused (the failure this guards
/// against); with the plant's and the controller's ids known in advance ([`Sources`]), every
/// rogue message is refused as foreign and the recording is the honest stream's, the same
/// bytes as the honest stream recorded alone (the truth).
#[test]
fn a_rogue_that_talks_first_does_not_take_a_known_pin() {
    let (plant, ctl, rogue) = (SourceId([1; 16]), SourceId([2; 16]), SourceId([3; 16]));
    let known = Sources {
        plant: Some(plant),
        controller: Some(ctl),
    };
    let run = |sources: Sources, with_rogue: bool| {
        let tmp = tempfile::tempdir().unwrap();
        let rec = Recorder::create(tmp.path(), &keys(), false, Some(rules()), sources).unwrap();
        let tx = rec.sender();
        if with_rogue {
            for k in 0..10u64 {
                tx.send_from(Record::State(state(k, 1, 0.3)), Some(rogue));
                let t = TorqueCommand { seq: k, tau: 3.25 };
                tx.send_from(Record::Torque(t), Some(rogue));
            }
        }
        for k in 0..100u64 {
            let s = state(k, 1, 0.03 * (k as f64 * 0.06).sin());
            tx.send_from(Record::State(s), Some(plant));
            tx.send_from(
                Record::Torque(TorqueCommand { seq: k, tau: 0.5 }),
                Some(ctl),
            );
        }
        let v = rec.finish().unwrap();
        let file = crate::read(&tmp.path().join(RUN_MCAP)).unwrap();
        let wire: Vec<(Topic, Vec<u8>)> = file.messages().map(|m| (m.topic, m.wire)).collect();
        (v, wire)
    };
    let (_, truth) = run(known, false);
    let (v, wire) = run(known, true);
    // Every rogue message refused: its states as foreign, its torques as foreign or as
    // answering no believed state (that rule comes first).
    assert_eq!(v.refused, [10, 10, 0, 0, 0], "{v:?}");
    assert!(v.foreign >= 10, "{v:?}");
    assert_eq!((v.states, v.torques), (100, 100));
    assert_eq!(wire, truth);
    // Unknown sources: the rogue's states pinned the plant's stream and are in the
    // recording, and honest states were refused.
    let (v, wire) = run(Sources::default(), true);
    assert!(v.refused[0] > 0 && v.foreign > 0, "{v:?}");
    assert_ne!(wire, truth);
}

/// Sources without rules (`tilting record`): a second session's messages are refused as
/// foreign and kept out, whatever they say; the pinned sources' messages are all written,
/// implausible ones too (no rules). The truth: the honest streams recorded alone.
#[test]
fn sources_alone_keep_a_foreign_publisher_out() {
    let (plant, ctl, other) = (SourceId([1; 16]), SourceId([2; 16]), SourceId([3; 16]));
    let run = |sources: Option<Sources>, foreign: bool| {
        let tmp = tempfile::tempdir().unwrap();
        let opts = Options {
            mcap: tmp.path().join("r.mcap"),
            csv_dir: None,
            skip_repeats: false,
            rules: None,
            sources,
        };
        let rec = Recorder::with_options(&opts, &keys()).unwrap();
        let tx = rec.sender();
        for k in 0..50u64 {
            // An implausible state (alpha beyond the fall angle) from the plant: no rules.
            let alpha = if k == 7 { 9.0 } else { 0.01 };
            let s = encode(&state(k, 1, alpha));
            tx.send_from(Record::Wire(Topic::State, s), Some(plant));
            let t = encode(&TorqueCommand { seq: k, tau: 0.5 });
            tx.send_from(Record::Wire(Topic::Torque, t), Some(ctl));
            if foreign && k % 5 == 0 {
                let s = encode(&state(k + 1, 1, 0.2));
                tx.send_from(Record::Wire(Topic::State, s), Some(other));
                let t = encode(&TorqueCommand { seq: k, tau: 2.0 });
                tx.send_from(Record::Wire(Topic::Torque, t), None);
            }
        }
        let v = rec.finish().unwrap();
        let file = crate::read(&opts.mcap).unwrap();
        let wire: Vec<(Topic, Vec<u8>)> = file.messages().map(|m| (m.topic, m.wire)).collect();
        (v, wire)
    };
    let (_, truth) = run(None, false);
    let (v, wire) = run(Some(Sources::default()), true);
    assert_eq!((v.refused, v.foreign), ([10, 10, 0, 0, 0], 20), "{v:?}");
    // Each refusal is charged to its stream's pin: the states' to the plant's, the
    // torques' to the controller's.
    assert_eq!(v.foreign_per_topic, [10, 10, 0, 0, 0], "{v:?}");
    assert_eq!((v.states, v.torques), (50, 50));
    assert_eq!(wire, truth);
    // Without sources, everything is the recording (the foreign messages too).
    let (v, wire) = run(None, true);
    assert_eq!(
        (v.refused, v.foreign, v.states, v.torques),
        ([0; 5], 0, 60, 60)
    );
    assert_ne!(wire, truth);
}

#[test]
fn a_full_queue_drops_without_blocking() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = Recorder::create(tmp.path(), &keys(), false, None, Sources::default()).unwrap();
    let tx = rec.sender();
    for k in 0..(4 * QUEUE as u64) {
        tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.0 }));
    }
    let dropped = rec.dropped();
    let v = rec.finish().unwrap();
    assert_eq!(v.torques + dropped, 4 * QUEUE as u64);
}
