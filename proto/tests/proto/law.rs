//! Protocol 3's `LawReference` (any law by name with its parameters) and `AnyReference` (what a
//! controller reads on the reference key). Expected bytes are built by hand from `to_le_bytes`,
//! never with bincode.

use tilting_proto::codec;
use tilting_proto::{AnyReference, DecodeError, LawReference, Reference, ValidationError};

const PROTOCOL_MD: &str = include_str!("../../../docs/protocol.md");

/// The toy of docs/protocol.md's worked example: plain PD, `kp = 400`, `kd = 56.56`, hold.
fn toy() -> LawReference {
    LawReference {
        trajectory: Reference::HOLD,
        amplitude: 0.0,
        omega: 0.0,
        law: "plain-pd".into(),
        parameters: vec![400.0, 56.56],
    }
}

/// The paper's law in protocol 2's layout (the wire tests' example).
fn paper() -> Reference {
    crate::wire::example_reference()
}

/// The layout of docs/protocol.md, by hand.
fn by_hand(l: &LawReference) -> Vec<u8> {
    let mut b = vec![3, l.trajectory];
    b.extend_from_slice(&l.amplitude.to_le_bytes());
    b.extend_from_slice(&l.omega.to_le_bytes());
    let mut name = [0u8; 24];
    name[..l.law.len()].copy_from_slice(l.law.as_bytes());
    b.extend_from_slice(&name);
    b.push(l.parameters.len() as u8);
    for i in 0..8 {
        b.extend_from_slice(&l.parameters.get(i).copied().unwrap_or(0.0).to_le_bytes());
    }
    b
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn err_text<T: tilting_proto::Message + std::fmt::Debug>(bytes: &[u8]) -> String {
    codec::decode::<T>(bytes).unwrap_err().to_string()
}

#[test]
fn a_law_reference_is_the_hand_built_layout_and_the_docs_worked_example() {
    let want = by_hand(&toy());
    assert_eq!(want.len(), 107);
    assert_eq!(LawReference::SIZE, 107);
    assert_eq!(codec::encode(&toy()), want);
    assert_eq!(codec::decode::<LawReference>(&want), Ok(toy()));
    assert_eq!(
        codec::decode::<AnyReference>(&want),
        Ok(AnyReference::Law(toy()))
    );
    let h = hex(&want);
    assert!(
        PROTOCOL_MD.contains(&h),
        "docs/protocol.md lacks the LawReference worked example {h}"
    );
    assert!(PROTOCOL_MD.contains("### LawReference — 107 bytes"));
}

#[test]
fn the_paper_laws_reference_is_unchanged_and_reads_as_its_generic_form() {
    let r = paper();
    let bytes = codec::encode(&r);
    assert_eq!(bytes.len(), 57);
    // Either layout encodes as itself: the paper's law's bytes are protocol 2's.
    assert_eq!(codec::encode(&AnyReference::Paper(r)), bytes);
    let any = codec::decode::<AnyReference>(&bytes).unwrap();
    assert_eq!(any, AnyReference::Paper(r));
    let generic = any.law();
    assert_eq!(generic.law, "computed-torque");
    assert_eq!(
        (generic.trajectory, generic.amplitude, generic.omega),
        (r.kind, r.amplitude, r.omega)
    );
    assert_eq!(
        generic.parameters,
        [r.kp, r.kd, r.k, r.energy_avg, r.torque_limit]
    );
    assert_eq!(
        LawReference::PAPER_PARAMETERS.len(),
        generic.parameters.len()
    );
    // The generic form of the paper's law goes back to the protocol-2 message; another
    // law's, or a list of another length, does not.
    assert_eq!(generic.to_paper(), Some(r));
    assert_eq!(toy().to_paper(), None);
    let short = LawReference {
        parameters: vec![1.0; 4],
        ..generic.clone()
    };
    assert_eq!(short.to_paper(), None);
    // The paper's law can travel in the generic layout too: 107 bytes, the same law.
    let b = codec::encode(&generic);
    assert_eq!(b, by_hand(&generic));
    assert_eq!(codec::decode::<AnyReference>(&b).unwrap().law(), generic);
}

#[test]
fn a_protocol_2_peer_refuses_a_law_reference_by_its_size_and_never_misreads_it() {
    // `Reference` and `decode::<Reference>` are protocol 2's, unchanged: this is what a
    // protocol-2 controller (or recorder) runs on the reference key.
    let bytes = codec::encode(&toy());
    let e = codec::decode::<Reference>(&bytes).unwrap_err();
    assert_eq!(
        e,
        DecodeError::WrongSize {
            message: "Reference",
            expected: 57,
            got: 107
        }
    );
    // Cut to protocol 2's size, byte 0 (the marker 3) is still out of the kind's range.
    let e = err_text::<Reference>(&bytes[..57]);
    assert!(
        e.contains("Reference.kind = 3") && e.contains("0..=2"),
        "{e}"
    );
}

#[test]
fn malformed_law_references_are_refused_naming_the_field_and_its_range() {
    let good = by_hand(&toy());
    let at_count = 2 + 16 + 24;
    // More parameters than the bound.
    let mut b = good.clone();
    b[at_count] = 9;
    let e = err_text::<LawReference>(&b);
    assert!(
        e.contains("LawReference.count = 9") && e.contains("0..=8"),
        "{e}"
    );
    // A parameter not finite, named by its slot.
    for bad in [f64::NAN, f64::INFINITY] {
        let l = LawReference {
            parameters: vec![400.0, bad],
            ..toy()
        };
        let e = err_text::<AnyReference>(&by_hand(&l));
        assert!(
            e.contains("parameters[1]") && e.contains("not finite"),
            "{e}"
        );
    }
    // A value in a slot past `count`.
    let mut b = good.clone();
    let slot = at_count + 1 + 8 * 2;
    b[slot..slot + 8].copy_from_slice(&1.5f64.to_le_bytes());
    let e = err_text::<LawReference>(&b);
    assert!(
        e.contains("parameters") && e.contains("past `count`"),
        "{e}"
    );
    // The name: a byte after its NUL padding, a character outside the alphabet, empty.
    let mut b = good.clone();
    b[18 + 20] = b'x';
    let e = err_text::<LawReference>(&b);
    assert!(
        e.contains("LawReference.law") && e.contains("NUL-padded"),
        "{e}"
    );
    for name in ["Plain-PD", "plain pd", ""] {
        let l = LawReference {
            law: name.into(),
            ..toy()
        };
        let e = err_text::<LawReference>(&by_hand(&l));
        assert!(
            e.contains("LawReference.law") && e.contains("a-z, 0-9"),
            "{e}"
        );
    }
    let long = LawReference {
        law: "a".repeat(25),
        ..toy()
    };
    assert_eq!(
        long.validate(),
        Err(ValidationError::TooLong {
            message: "LawReference",
            field: "law",
            len: 25,
            max: 24
        })
    );
    let many = LawReference {
        parameters: vec![0.0; 9],
        ..toy()
    };
    let e = many.validate().unwrap_err().to_string();
    assert!(e.contains("count = 9") && e.contains("0..=8"), "{e}");
    // The trajectory and its frequency.
    let l = LawReference {
        trajectory: 3,
        ..toy()
    };
    let e = err_text::<LawReference>(&by_hand(&l));
    assert!(e.contains("trajectory = 3") && e.contains("0..=2"), "{e}");
    let l = LawReference {
        trajectory: Reference::SINUSOID,
        omega: 0.0,
        ..toy()
    };
    let e = err_text::<LawReference>(&by_hand(&l));
    assert!(e.contains("omega = 0") && e.contains("> 0"), "{e}");
    // Byte 0 of neither layout; the generic layout under another marker.
    let mut b = good.clone();
    b[0] = 4;
    let e = err_text::<AnyReference>(&b);
    assert!(
        e.contains("byte 0 = 4") && e.contains("(0..=2)") && e.contains("(3)"),
        "{e}"
    );
    let e = err_text::<LawReference>(&b);
    assert!(
        e.contains("LawReference.marker = 4") && e.contains("protocol-3"),
        "{e}"
    );
    // Sizes: one byte short or long.
    let e = err_text::<LawReference>(&good[..106]);
    assert!(e.contains("expected 107") && e.contains("got 106"), "{e}");
    let e = err_text::<AnyReference>(&good[..106]);
    assert!(e.contains("ends early"), "{e}");
    let mut b = good.clone();
    b.push(0);
    let e = err_text::<AnyReference>(&b);
    assert!(e.contains("too large") && e.contains("at most 107"), "{e}");
    let mut b = codec::encode(&paper());
    b.push(0);
    assert!(err_text::<AnyReference>(&b).contains("1 trailing bytes"));
}

#[test]
fn every_count_from_0_to_8_round_trips_bit_for_bit() {
    for n in 0..=8 {
        let l = LawReference {
            parameters: (0..n).map(|i| -1.25 + i as f64 * 1e-3).collect(),
            law: format!("law-{n}"),
            ..toy()
        };
        let b = codec::encode(&l);
        assert_eq!(b, by_hand(&l));
        assert_eq!(codec::decode::<AnyReference>(&b), Ok(AnyReference::Law(l)));
    }
}
