//! Byte-exact wire format tests. Expected bytes are built by hand from `to_le_bytes`, never with
//! bincode, so these tests pin the format independently of the codec's implementation.

use std::f64::consts::FRAC_PI_2;
use tilting_proto::codec::{self, DECODE_LIMIT};
use tilting_proto::{
    DecodeError, Message, ModeEvent, PlantState, Reference, Status, TorqueCommand, ValidationError,
};

/// The document whose worked examples must match the codec.
const PROTOCOL_MD: &str = include_str!("../../../docs/protocol.md");

/// Worked example of `docs/protocol.md`.
const PLANT_STATE_EXAMPLE_HEX: &str = "2a00000000000000000000000000f83f000000000000d03f182d4454fb21f93f000000000000e0bf0000000000000040010f";
/// Worked example of `docs/protocol.md`: the same state with the angles only.
const PLANT_STATE_ANGLES_EXAMPLE_HEX: &str = "2a00000000000000000000000000f83f000000000000d03f182d4454fb21f93f000000000000000000000000000000000103";

/// Worked example of `docs/protocol.md`.
const TORQUE_EXAMPLE_HEX: &str = "2a00000000000000000000000000c0bf";

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn example_state() -> PlantState {
    PlantState {
        seq: 42,
        time: 1.5,
        alpha: 0.25,
        beta: FRAC_PI_2,
        alpha_dot: Some(-0.5),
        beta_dot: Some(2.0),
        mode: 1,
    }
}

fn example_torque() -> TorqueCommand {
    TorqueCommand {
        seq: 42,
        tau: -0.125,
    }
}

fn example_event() -> ModeEvent {
    ModeEvent {
        seq: 1234,
        time: 3.25,
        from: 1,
        to: 0,
        x_before: [-1e-13, 1.2, -0.75, 0.5],
        x_after: [0.0, 1.2, 0.0, -3.0],
    }
}

fn example_status() -> Status {
    Status {
        seq: u64::MAX - 1,
        time: 12.5,
        state: Status::SAFE_MODE,
        mode: 2,
        tilts: 3,
        steps: 12_500,
        torques_received: 12_490,
        torques_dropped: 4,
        torques_stale: 5,
        deadline_misses: 6,
        watchdog_trips: 1,
        jitter_p50_us: 12.25,
        jitter_p99_us: 80.5,
        max_overrun_us: 950.0,
        latency_p50_us: 21.5,
        latency_p99_us: 64.75,
        torques_late: 7,
        torques_lost: 8,
        torques_reordered: 9,
        age_p50: 1.0,
        age_p99: 2.5,
        age_max: 3.0,
        fault: "watchdog: no torque for 20 ms (ü)".to_owned(),
    }
}

pub(crate) fn example_reference() -> Reference {
    Reference {
        kind: Reference::SINUSOID,
        amplitude: 0.33,
        omega: 4.5,
        kp: 100.0,
        kd: 14.14,
        k: 500.0,
        energy_avg: 31.7,
        torque_limit: 80.0,
    }
}

/// Decodes, expecting an error, and checks the error text contains every needle.
fn expect_err<T: Message + std::fmt::Debug>(bytes: &[u8], needles: &[&str]) -> DecodeError {
    let err = codec::decode::<T>(bytes).expect_err("decode must fail");
    let text = err.to_string();
    for n in needles {
        assert!(text.contains(n), "{text:?} lacks {n:?}");
    }
    err
}

// ---------------------------------------------------------------- layouts

#[test]
fn wire_sizes() {
    assert_eq!(PlantState::SIZE, 50);
    assert_eq!(PlantState::SIZE_V1, 49);
    assert_eq!(TorqueCommand::SIZE, 16);
    assert_eq!(ModeEvent::SIZE, 82);
    assert_eq!(Reference::SIZE, 57);
    assert_eq!(Status::MIN_SIZE, 170);
    assert_eq!(Status::MAX_SIZE, 170 + 1024);
    assert_eq!(<PlantState as Message>::WIRE_SIZE, Some(50));
    assert_eq!(<TorqueCommand as Message>::WIRE_SIZE, Some(16));
    assert_eq!(<ModeEvent as Message>::WIRE_SIZE, Some(82));
    assert_eq!(<Reference as Message>::WIRE_SIZE, Some(57));
    assert_eq!(<Status as Message>::WIRE_SIZE, None);
    for max in [
        <PlantState as Message>::MAX_WIRE_SIZE,
        <TorqueCommand as Message>::MAX_WIRE_SIZE,
        <ModeEvent as Message>::MAX_WIRE_SIZE,
        <Reference as Message>::MAX_WIRE_SIZE,
        <Status as Message>::MAX_WIRE_SIZE,
    ] {
        assert!(max <= DECODE_LIMIT);
    }
    assert_eq!(<PlantState as Message>::NAME, "PlantState");
    assert_eq!(<Status as Message>::NAME, "Status");
}

#[test]
fn plant_state_layout_is_hand_built() {
    let s = PlantState {
        seq: 0x0102_0304_0506_0708,
        time: 1.0 / 3.0,
        alpha: -0.1,
        beta: FRAC_PI_2 + 1e-3,
        alpha_dot: Some(7.25),
        beta_dot: Some(-1e300),
        mode: 2,
    };
    let mut want = Vec::new();
    want.extend_from_slice(&s.seq.to_le_bytes());
    for f in [s.time, s.alpha, s.beta, 7.25, -1e300] {
        want.extend_from_slice(&f.to_le_bytes());
    }
    want.push(s.mode);
    want.push(0x0f);
    assert_eq!(want.len(), 50);
    let got = codec::encode(&s);
    assert_eq!(got, want);
    // Offsets as documented.
    assert_eq!(got[0], 0x08);
    assert_eq!(got[7], 0x01);
    assert_eq!(&got[16..24], &(-0.1f64).to_le_bytes());
    assert_eq!(got[48], 2);
    assert_eq!(got[49], 0x0f);

    let mut buf = [0xAAu8; 64];
    assert_eq!(codec::encode_into(&s, &mut buf), 50);
    assert_eq!(&buf[..50], &want[..]);
    assert!(
        buf[50..].iter().all(|&b| b == 0xAA),
        "wrote past the message"
    );
}

/// Absent rates: `+0.0` in their slots, their bits of the `measured` byte clear; they decode as
/// absent (`None`), never as zero, and a full state's `x()` is refused for them.
#[test]
fn absent_rates_are_flagged_and_never_read_as_zeros() {
    let s = PlantState {
        alpha_dot: None,
        beta_dot: None,
        ..example_state()
    };
    let got = codec::encode(&s);
    assert_eq!(hex(&got), PLANT_STATE_ANGLES_EXAMPLE_HEX);
    assert_eq!(&got[32..48], &[0u8; 16]);
    assert_eq!(got[49], PlantState::MEASURED_ANGLES);
    let back = codec::decode::<PlantState>(&got).unwrap();
    assert_eq!((back.alpha_dot, back.beta_dot), (None, None));
    assert_eq!(back.x(), None);
    assert_eq!(back.rates(), None);
    assert_eq!(back.angles(), [0.25, FRAC_PI_2]);
    // A measured zero is another message: bit set, same slot bytes.
    let zero = PlantState {
        alpha_dot: Some(0.0),
        beta_dot: Some(0.0),
        ..s
    };
    let z = codec::encode(&zero);
    assert_eq!(&z[..49], &got[..49]);
    assert_eq!(z[49], PlantState::MEASURED_ALL);
    assert_eq!(
        codec::decode::<PlantState>(&z).unwrap().x(),
        Some([0.25, FRAC_PI_2, 0.0, 0.0])
    );
    // One rate only.
    let one = PlantState {
        beta_dot: Some(-3.0),
        ..s
    };
    let b = codec::encode(&one);
    assert_eq!(b[49], 0b1011);
    let back = codec::decode::<PlantState>(&b).unwrap();
    assert_eq!((back.alpha_dot, back.beta_dot), (None, Some(-3.0)));
    assert_eq!(back.x(), None);
    // A value in an absent slot, reserved bits, or an angle marked absent: refused, named.
    let mut bad = got.clone();
    bad[32..40].copy_from_slice(&1.5f64.to_le_bytes());
    expect_err::<PlantState>(&bad, &["PlantState.alpha_dot = 1.5", "marks it absent"]);
    let mut bad = got.clone();
    bad[40..48].copy_from_slice(&(-0.0f64).to_le_bytes());
    expect_err::<PlantState>(&bad, &["PlantState.beta_dot = -0", "marks it absent"]);
    for m in [0u8, 1, 2, 4, 12, 0x13, 0x1f, 0xff] {
        let mut bad = got.clone();
        bad[49] = m;
        expect_err::<PlantState>(
            &bad,
            &[&format!("PlantState.measured = {m}"), "3, 7, 11 or 15"],
        );
    }
}

/// A protocol-1 state (49 bytes, no `measured` byte) is refused with an error that says so.
#[test]
fn an_old_version_state_is_refused_with_a_clear_error() {
    let v2 = codec::encode(&example_state());
    let v1 = &v2[..49];
    let err = expect_err::<PlantState>(
        v1,
        &[
            "PlantState",
            "49-byte",
            "protocol-1",
            "`measured`",
            "protocol 3",
            "50 bytes",
            "update the sender",
        ],
    );
    assert!(matches!(
        err,
        DecodeError::OldVersion {
            got: 49,
            expected: 50,
            protocol: 3,
            ..
        }
    ));
    // Protocol 3 added `LawReference` (proto/tests/proto/law.rs); the state's layout is 2's.
    assert_eq!(tilting_proto::PROTOCOL_VERSION, 3);
}

#[test]
fn torque_command_layout_is_hand_built() {
    let c = TorqueCommand {
        seq: 0xDEAD_BEEF_0000_0001,
        tau: -12.375,
    };
    let mut want = Vec::new();
    want.extend_from_slice(&c.seq.to_le_bytes());
    want.extend_from_slice(&c.tau.to_le_bytes());
    assert_eq!(want.len(), 16);
    assert_eq!(codec::encode(&c), want);
    let mut buf = [0u8; 16];
    assert_eq!(codec::encode_into(&c, &mut buf), 16);
    assert_eq!(&buf[..], &want[..]);
}

#[test]
fn mode_event_layout_is_hand_built() {
    let e = example_event();
    let mut want = Vec::new();
    want.extend_from_slice(&e.seq.to_le_bytes());
    want.extend_from_slice(&e.time.to_le_bytes());
    want.push(e.from);
    want.push(e.to);
    for f in e.x_before.iter().chain(e.x_after.iter()) {
        want.extend_from_slice(&f.to_le_bytes());
    }
    assert_eq!(want.len(), 82);
    assert_eq!(codec::encode(&e), want);
    let mut buf = [0u8; 82];
    assert_eq!(codec::encode_into(&e, &mut buf), 82);
    assert_eq!(&buf[..], &want[..]);
}

#[test]
fn reference_layout_is_hand_built() {
    let r = example_reference();
    let mut want = vec![r.kind];
    for f in [
        r.amplitude,
        r.omega,
        r.kp,
        r.kd,
        r.k,
        r.energy_avg,
        r.torque_limit,
    ] {
        want.extend_from_slice(&f.to_le_bytes());
    }
    assert_eq!(want.len(), 57);
    assert_eq!(codec::encode(&r), want);
}

#[test]
fn status_layout_is_hand_built() {
    let s = example_status();
    let mut want = Vec::new();
    want.extend_from_slice(&s.seq.to_le_bytes());
    want.extend_from_slice(&s.time.to_le_bytes());
    want.push(s.state);
    want.push(s.mode);
    for n in [
        s.tilts,
        s.steps,
        s.torques_received,
        s.torques_dropped,
        s.torques_stale,
        s.deadline_misses,
        s.watchdog_trips,
    ] {
        want.extend_from_slice(&n.to_le_bytes());
    }
    for f in [
        s.jitter_p50_us,
        s.jitter_p99_us,
        s.max_overrun_us,
        s.latency_p50_us,
        s.latency_p99_us,
    ] {
        want.extend_from_slice(&f.to_le_bytes());
    }
    for n in [s.torques_late, s.torques_lost, s.torques_reordered] {
        want.extend_from_slice(&n.to_le_bytes());
    }
    for f in [s.age_p50, s.age_p99, s.age_max] {
        want.extend_from_slice(&f.to_le_bytes());
    }
    assert_eq!(want.len(), Status::MIN_SIZE - 8);
    want.extend_from_slice(&(s.fault.len() as u64).to_le_bytes());
    want.extend_from_slice(s.fault.as_bytes());
    assert_eq!(codec::encode(&s), want);

    let empty = Status {
        fault: String::new(),
        ..s
    };
    assert_eq!(codec::encode(&empty).len(), Status::MIN_SIZE);
}

// ---------------------------------------------------------------- worked examples

#[test]
fn worked_examples_match_docs() {
    assert_eq!(
        hex(&codec::encode(&example_state())),
        PLANT_STATE_EXAMPLE_HEX
    );
    assert_eq!(hex(&codec::encode(&example_torque())), TORQUE_EXAMPLE_HEX);
    assert!(
        PROTOCOL_MD.contains(PLANT_STATE_EXAMPLE_HEX),
        "docs/protocol.md lacks the PlantState example hex"
    );
    assert!(
        PROTOCOL_MD.contains(TORQUE_EXAMPLE_HEX),
        "docs/protocol.md lacks the TorqueCommand example hex"
    );
    // The per-field breakdown in the doc, 8 bytes per f64/u64.
    let h = PLANT_STATE_EXAMPLE_HEX;
    for i in 0..6 {
        let chunk = &h[16 * i..16 * (i + 1)];
        assert!(PROTOCOL_MD.contains(&format!("`{chunk}`")), "{chunk}");
    }
    assert!(PROTOCOL_MD.contains(PLANT_STATE_ANGLES_EXAMPLE_HEX));
    assert!(PROTOCOL_MD.contains("'<Q5d2B'") && PROTOCOL_MD.contains("'<Qd'"));
}

// ---------------------------------------------------------------- round trips

#[test]
fn round_trip_every_message() {
    let s = example_state();
    assert_eq!(codec::decode::<PlantState>(&codec::encode(&s)), Ok(s));
    let c = example_torque();
    assert_eq!(codec::decode::<TorqueCommand>(&codec::encode(&c)), Ok(c));
    let e = example_event();
    assert_eq!(codec::decode::<ModeEvent>(&codec::encode(&e)), Ok(e));
    let st = example_status();
    assert_eq!(codec::decode::<Status>(&codec::encode(&st)), Ok(st.clone()));
    let r = example_reference();
    assert_eq!(codec::decode::<Reference>(&codec::encode(&r)), Ok(r));

    // Extremes that are still valid.
    let s = PlantState {
        seq: u64::MAX,
        time: f64::MAX,
        alpha: -0.0,
        beta: f64::MIN_POSITIVE,
        alpha_dot: Some(5e-324),
        beta_dot: Some(f64::MIN),
        mode: 0,
    };
    let back = codec::decode::<PlantState>(&codec::encode(&s)).unwrap();
    assert_eq!(back.alpha.to_bits(), (-0.0f64).to_bits());
    assert_eq!(back, s);
    let hold = Reference {
        kind: Reference::HOLD,
        omega: 0.0,
        k: 0.0,
        torque_limit: 0.0,
        ..r
    };
    assert_eq!(codec::decode::<Reference>(&codec::encode(&hold)), Ok(hold));
    let mut big = example_status();
    big.fault = "é".repeat(512); // exactly 1024 bytes
    let bytes = codec::encode(&big);
    assert_eq!(bytes.len(), Status::MAX_SIZE);
    assert_eq!(codec::decode::<Status>(&bytes), Ok(big));
}

// ---------------------------------------------------------------- rejections

#[test]
fn wrong_sizes_are_rejected_with_expected_and_got() {
    let full = codec::encode(&example_state());
    for n in (0..50).filter(|&n| n != PlantState::SIZE_V1) {
        let err = expect_err::<PlantState>(
            &full[..n],
            &["PlantState", "expected 50", &format!("got {n}")],
        );
        assert_eq!(
            err,
            DecodeError::WrongSize {
                message: "PlantState",
                expected: 50,
                got: n
            }
        );
    }
    let mut ext = full.clone();
    ext.push(0);
    expect_err::<PlantState>(&ext, &["PlantState", "expected 50", "got 51"]);
    ext.extend_from_slice(&[0; 13]);
    expect_err::<PlantState>(&ext, &["expected 50", "got 64"]);

    let t = codec::encode(&example_torque());
    expect_err::<TorqueCommand>(&t[..15], &["TorqueCommand", "expected 16", "got 15"]);
    expect_err::<TorqueCommand>(&[t.as_slice(), &[1]].concat(), &["expected 16", "got 17"]);
    // A TorqueCommand is not a PlantState and vice versa.
    expect_err::<PlantState>(&t, &["expected 50", "got 16"]);
    expect_err::<TorqueCommand>(&full, &["expected 16", "got 50"]);

    let e = codec::encode(&example_event());
    expect_err::<ModeEvent>(&e[..81], &["ModeEvent", "expected 82", "got 81"]);
    let r = codec::encode(&example_reference());
    expect_err::<Reference>(
        &[r.as_slice(), &[0]].concat(),
        &["Reference", "expected 57", "got 58"],
    );
}

#[test]
fn status_truncated_or_extended_is_rejected() {
    let bytes = codec::encode(&example_status());
    for n in [
        0,
        1,
        8,
        50,
        Status::MIN_SIZE - 1,
        Status::MIN_SIZE,
        bytes.len() - 1,
    ] {
        let err = expect_err::<Status>(&bytes[..n], &["Status", "malformed", "ends early"]);
        assert!(matches!(err, DecodeError::Malformed { .. }), "{n}: {err:?}");
    }
    let mut ext = bytes.clone();
    ext.extend_from_slice(b"xyz");
    let err = expect_err::<Status>(&ext, &["Status", "3 trailing bytes"]);
    assert_eq!(
        err,
        DecodeError::TrailingBytes {
            message: "Status",
            used: bytes.len(),
            trailing: 3
        }
    );
    let too_big = vec![0u8; Status::MAX_SIZE + 1];
    let err = expect_err::<Status>(&too_big, &["Status", "at most 1194", "got 1195"]);
    assert!(matches!(err, DecodeError::TooLarge { .. }));
    // A 1025-byte fault encodes (encode does not validate) but cannot be received.
    let mut s = example_status();
    s.fault = "x".repeat(1025);
    expect_err::<Status>(&codec::encode(&s), &["Status", "too large"]);
}

#[test]
fn non_finite_plant_state_fields_are_named() {
    let base = example_state();
    type Set = fn(&mut PlantState, f64);
    let fields: [(&str, Set); 5] = [
        ("time", |s, v| s.time = v),
        ("alpha", |s, v| s.alpha = v),
        ("beta", |s, v| s.beta = v),
        ("alpha_dot", |s, v| s.alpha_dot = Some(v)),
        ("beta_dot", |s, v| s.beta_dot = Some(v)),
    ];
    for (name, set) in fields {
        for bad in [f64::NAN, -f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut s = base;
            set(&mut s, bad);
            let err = expect_err::<PlantState>(
                &codec::encode(&s),
                &[&format!("PlantState.{name} = "), "not finite", "finite f64"],
            );
            match err {
                DecodeError::Invalid(ValidationError::NotFinite {
                    message,
                    field,
                    value,
                }) => {
                    assert_eq!((message, field), ("PlantState", name));
                    assert_eq!(value.to_bits(), bad.to_bits());
                }
                other => panic!("{other:?}"),
            }
        }
    }
}

#[test]
fn non_finite_fields_of_other_messages_are_named() {
    let c = TorqueCommand {
        tau: f64::NAN,
        ..example_torque()
    };
    expect_err::<TorqueCommand>(
        &codec::encode(&c),
        &["TorqueCommand.tau = NaN", "not finite"],
    );

    for i in 0..4 {
        let mut e = example_event();
        e.x_before[i] = f64::INFINITY;
        expect_err::<ModeEvent>(
            &codec::encode(&e),
            &[&format!("ModeEvent.x_before[{i}] = inf")],
        );
        let mut e = example_event();
        e.x_after[i] = f64::NAN;
        expect_err::<ModeEvent>(
            &codec::encode(&e),
            &[&format!("ModeEvent.x_after[{i}] = NaN")],
        );
    }
    let e = ModeEvent {
        time: f64::NEG_INFINITY,
        ..example_event()
    };
    expect_err::<ModeEvent>(&codec::encode(&e), &["ModeEvent.time = -inf"]);

    for (name, s) in [
        (
            "time",
            Status {
                time: f64::NAN,
                ..example_status()
            },
        ),
        (
            "jitter_p50_us",
            Status {
                jitter_p50_us: f64::NAN,
                ..example_status()
            },
        ),
        (
            "jitter_p99_us",
            Status {
                jitter_p99_us: f64::INFINITY,
                ..example_status()
            },
        ),
        (
            "max_overrun_us",
            Status {
                max_overrun_us: f64::NAN,
                ..example_status()
            },
        ),
        (
            "latency_p50_us",
            Status {
                latency_p50_us: f64::NEG_INFINITY,
                ..example_status()
            },
        ),
        (
            "latency_p99_us",
            Status {
                latency_p99_us: f64::NAN,
                torques_late: 0,
                torques_lost: 0,
                torques_reordered: 0,
                age_p50: 0.0,
                age_p99: 0.0,
                age_max: 0.0,
                ..example_status()
            },
        ),
    ] {
        expect_err::<Status>(
            &codec::encode(&s),
            &[&format!("Status.{name} = "), "not finite"],
        );
    }

    let r = example_reference();
    for (name, r) in [
        (
            "amplitude",
            Reference {
                amplitude: f64::NAN,
                ..r
            },
        ),
        (
            "omega",
            Reference {
                omega: f64::INFINITY,
                ..r
            },
        ),
        ("kp", Reference { kp: f64::NAN, ..r }),
        (
            "kd",
            Reference {
                kd: f64::INFINITY,
                ..r
            },
        ),
        ("k", Reference { k: f64::NAN, ..r }),
        (
            "energy_avg",
            Reference {
                energy_avg: f64::NEG_INFINITY,
                ..r
            },
        ),
        (
            "torque_limit",
            Reference {
                torque_limit: f64::INFINITY,
                ..r
            },
        ),
    ] {
        expect_err::<Reference>(
            &codec::encode(&r),
            &[&format!("Reference.{name} = "), "not finite"],
        );
    }
}

#[test]
fn out_of_range_enums_are_named_with_allowed_range() {
    let s = PlantState {
        mode: 3,
        ..example_state()
    };
    let err = expect_err::<PlantState>(
        &codec::encode(&s),
        &["PlantState.mode = 3", "out of range", "0..=2"],
    );
    assert!(matches!(
        err,
        DecodeError::Invalid(ValidationError::OutOfRange { field: "mode", .. })
    ));
    let s = PlantState {
        mode: 255,
        ..example_state()
    };
    expect_err::<PlantState>(&codec::encode(&s), &["PlantState.mode = 255"]);

    let e = ModeEvent {
        from: 3,
        ..example_event()
    };
    expect_err::<ModeEvent>(&codec::encode(&e), &["ModeEvent.from = 3", "0..=2"]);
    let e = ModeEvent {
        to: 9,
        ..example_event()
    };
    expect_err::<ModeEvent>(&codec::encode(&e), &["ModeEvent.to = 9", "0..=2"]);

    let st = Status {
        state: 5,
        ..example_status()
    };
    expect_err::<Status>(&codec::encode(&st), &["Status.state = 5", "0..=4"]);
    let st = Status {
        mode: 3,
        ..example_status()
    };
    expect_err::<Status>(&codec::encode(&st), &["Status.mode = 3", "0..=2"]);

    let r = Reference {
        kind: 7,
        ..example_reference()
    };
    expect_err::<Reference>(
        &codec::encode(&r),
        &["Reference.kind = 7", "out of range", "0..=2"],
    );
    let r = Reference {
        omega: 0.0,
        ..example_reference()
    };
    expect_err::<Reference>(&codec::encode(&r), &["Reference.omega = 0", "> 0"]);
    let r = Reference {
        kd: -1.0,
        ..example_reference()
    };
    expect_err::<Reference>(&codec::encode(&r), &["Reference.kd = -1", ">= 0"]);
}

#[test]
fn status_forged_string_lengths_are_rejected() {
    let good = codec::encode(&Status {
        fault: String::new(),
        ..example_status()
    });
    assert_eq!(good.len(), Status::MIN_SIZE);
    let prefix = &good[..Status::MIN_SIZE - 8];
    let with_len = |len: u64, tail: &[u8]| {
        let mut b = prefix.to_vec();
        b.extend_from_slice(&len.to_le_bytes());
        b.extend_from_slice(tail);
        b
    };
    // Declared lengths far beyond the decode limit: rejected by the limit, before allocating.
    for len in [u64::MAX, 1 << 40, 1 << 32, DECODE_LIMIT as u64] {
        let err = expect_err::<Status>(
            &with_len(len, b"abc"),
            &["Status", "malformed", "decode limit"],
        );
        assert!(matches!(err, DecodeError::Malformed { .. }));
    }
    // Within the limit but longer than the payload.
    expect_err::<Status>(&with_len(1000, b"abc"), &["Status", "ends early"]);
    // Shorter than the payload.
    expect_err::<Status>(&with_len(2, b"abc"), &["Status", "1 trailing bytes"]);
    // Exact, but not UTF-8.
    expect_err::<Status>(&with_len(3, &[0x61, 0xff, 0x62]), &["Status", "UTF-8"]);
    // Exact and valid.
    let ok = codec::decode::<Status>(&with_len(3, b"abc")).unwrap();
    assert_eq!(ok.fault, "abc");
}

// ---------------------------------------------------------------- garbage

/// xorshift64*: deterministic, no dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn bytes(&mut self, out: &mut [u8]) {
        for b in out {
            *b = self.next() as u8;
        }
    }
    /// A random f64 bit pattern; one in four is NaN or infinite.
    fn f64_bytes(&mut self) -> [u8; 8] {
        let mut bits = self.next();
        if bits & 3 == 0 {
            bits |= 0x7ff0_0000_0000_0000;
        }
        bits.to_le_bytes()
    }
}

#[test]
fn garbage_50_bytes_with_nan_pattern_is_rejected() {
    // Quiet NaN in `alpha`, everything else random-looking but valid.
    let mut b = [0u8; 50];
    Rng(0x1234_5678).bytes(&mut b);
    b[8..16].copy_from_slice(&0.5f64.to_le_bytes());
    b[16..24].copy_from_slice(&[0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf8, 0x7f]);
    for off in [24, 32, 40] {
        b[off..off + 8].copy_from_slice(&1.0f64.to_le_bytes());
    }
    b[48] = 0;
    b[49] = PlantState::MEASURED_ALL;
    expect_err::<PlantState>(&b, &["PlantState.alpha = NaN"]);
    // Same bytes with alpha fixed decode fine: the NaN was the only problem.
    b[16..24].copy_from_slice(&0.0f64.to_le_bytes());
    assert!(codec::decode::<PlantState>(&b).is_ok());
    // All 0xff: seq is fine, time is NaN.
    let mut b = [0xff; 50];
    b[49] = PlantState::MEASURED_ALL;
    expect_err::<PlantState>(&b, &["PlantState.time = NaN"]);
}

#[test]
fn random_plant_states_decode_iff_valid() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let (mut ok, mut bad) = (0, 0);
    for _ in 0..20_000 {
        let mut b = [0u8; 50];
        rng.bytes(&mut b[..8]);
        for i in 0..5 {
            b[8 + 8 * i..16 + 8 * i].copy_from_slice(&rng.f64_bytes());
        }
        b[48] = (rng.next() % 4) as u8;
        b[49] = PlantState::MEASURED_ALL;
        let f = |i: usize| f64::from_le_bytes(b[8 + 8 * i..16 + 8 * i].try_into().unwrap());
        let valid = (0..5).all(|i| f(i).is_finite()) && b[48] <= 2;
        match codec::decode::<PlantState>(&b) {
            Ok(s) => {
                assert!(valid, "{b:?}");
                ok += 1;
                assert_eq!(s.seq, u64::from_le_bytes(b[..8].try_into().unwrap()));
                let [_, _, ad, bd] = s.x().unwrap();
                let got = [s.time, s.alpha, s.beta, ad, bd];
                for (i, g) in got.iter().enumerate() {
                    assert_eq!(g.to_bits(), f(i).to_bits());
                }
                assert_eq!(s.mode, b[48]);
                assert_eq!(codec::encode(&s), b.to_vec());
            }
            Err(e) => {
                assert!(!valid, "{b:?}: {e}");
                assert!(matches!(e, DecodeError::Invalid(_)), "{e:?}");
                bad += 1;
            }
        }
    }
    // Both branches were exercised.
    assert!(ok > 1000 && bad > 1000, "ok {ok} bad {bad}");
}

#[test]
fn random_torques_and_events_decode_iff_valid() {
    let mut rng = Rng(42);
    for _ in 0..10_000 {
        let mut b = [0u8; 16];
        rng.bytes(&mut b[..8]);
        b[8..].copy_from_slice(&rng.f64_bytes());
        let tau = f64::from_le_bytes(b[8..].try_into().unwrap());
        assert_eq!(codec::decode::<TorqueCommand>(&b).is_ok(), tau.is_finite());

        let mut e = [0u8; 82];
        rng.bytes(&mut e[..8]);
        e[8..16].copy_from_slice(&rng.f64_bytes());
        e[16] = (rng.next() % 4) as u8;
        e[17] = (rng.next() % 4) as u8;
        for i in 0..8 {
            // Mostly finite so that valid events occur.
            let x = if rng.next() & 15 == 0 {
                rng.f64_bytes()
            } else {
                (rng.next() as f64 / 1e15).to_le_bytes()
            };
            e[18 + 8 * i..26 + 8 * i].copy_from_slice(&x);
        }
        let finite =
            |off: usize| f64::from_le_bytes(e[off..off + 8].try_into().unwrap()).is_finite();
        let valid = finite(8) && e[16] <= 2 && e[17] <= 2 && (0..8).all(|i| finite(18 + 8 * i));
        let got = codec::decode::<ModeEvent>(&e);
        assert_eq!(got.is_ok(), valid, "{e:?}: {got:?}");
        if let Ok(ev) = got {
            assert_eq!(codec::encode(&ev), e.to_vec());
        }
    }
}

#[test]
fn random_bytes_never_panic_and_accepted_status_round_trips() {
    let mut rng = Rng(7);
    let mut accepted = 0;
    for round in 0..5_000 {
        let len = (rng.next() % 1200) as usize;
        let mut b = vec![0u8; len];
        rng.bytes(&mut b);
        if round % 2 == 0 && len >= Status::MIN_SIZE {
            // Make the fixed part plausible and the length prefix consistent half the time.
            b[16] %= 5;
            b[17] %= 3;
            for off in [8, 74, 82, 90, 98, 106, 138, 146, 154] {
                b[off..off + 8].copy_from_slice(&1.0f64.to_le_bytes());
            }
            let n = (len - Status::MIN_SIZE) as u64;
            b[162..170].copy_from_slice(&n.to_le_bytes());
            for c in &mut b[170..] {
                *c = b'a' + *c % 26;
            }
        }
        if let Ok(s) = codec::decode::<Status>(&b) {
            accepted += 1;
            assert_eq!(codec::encode(&s), b);
        }
        let _ = codec::decode::<PlantState>(&b);
        let _ = codec::decode::<TorqueCommand>(&b);
        let _ = codec::decode::<ModeEvent>(&b);
        let _ = codec::decode::<Reference>(&b);
    }
    assert!(accepted > 100, "{accepted}");
}

#[test]
#[should_panic(expected = "too small")]
fn encode_into_short_buffer_panics() {
    let mut buf = [0u8; 48];
    codec::encode_into(&example_state(), &mut buf);
}
