//! The source of a message: which zenoh session published it, as the publisher says.
//!
//! Our publishers attach their session's identity (its 16-byte `ZenohId`) to every message
//! ([`SourceId::attachment`]: the 4 bytes `TSRC` and the id, 20 bytes, as the zenoh sample's
//! attachment; the payload is unchanged). A receiver **pins** the source of a stream to the
//! first believed message's ([`SourcePin`]) and refuses, and counts, messages from another
//! session while the pinned one keeps talking: a second plant or controller on the same
//! robot's keys, a replay, a test tool.
//!
//! The identity is the publisher's claim, not a proof: any publisher may attach any bytes, so
//! one that copies the plant's id from a sample it received passes (zenoh's own `SourceInfo`
//! is likewise set by the publisher, and only with zenoh's unstable API). Authentication is the
//! secure deployment's: mutual TLS and access control per link (README, *Security*).

use std::fmt;
use std::time::{Duration, Instant};

use std::str::FromStr;

/// The tag that starts a source attachment.
pub const ATTACHMENT_TAG: [u8; 4] = *b"TSRC";

/// Size of a source attachment (bytes): the tag and the 16-byte id.
pub const ATTACHMENT_SIZE: usize = 20;

/// A zenoh session's identity: its `ZenohId` as 16 little-endian bytes (`ZenohId::to_le_bytes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SourceId(pub [u8; 16]);

impl SourceId {
    /// The attachment that says "published by this session": [`ATTACHMENT_TAG`] then the id.
    pub fn attachment(&self) -> [u8; ATTACHMENT_SIZE] {
        let mut a = [0u8; ATTACHMENT_SIZE];
        a[..4].copy_from_slice(&ATTACHMENT_TAG);
        a[4..].copy_from_slice(&self.0);
        a
    }

    /// The source an attachment names; `None` for anything but a source attachment (no
    /// attachment, another size, another tag).
    pub fn from_attachment(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != ATTACHMENT_SIZE || bytes[..4] != ATTACHMENT_TAG {
            return None;
        }
        let mut id = [0u8; 16];
        id.copy_from_slice(&bytes[4..]);
        Some(Self(id))
    }
}

/// A source as zenoh writes a `ZenohId` (its `id` configuration field, [`fmt::Display`]): 1 to 32
/// hexadecimal digits, not all zero, read as one little-endian number.
impl FromStr for SourceId {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || {
            format!(
                "invalid zenoh id {s:?}: allowed 1 to 32 hexadecimal digits (0-9, a-f), not all zero"
            )
        };
        if s.is_empty() || s.len() > 32 || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad());
        }
        let n = u128::from_str_radix(s, 16).map_err(|_| bad())?;
        if n == 0 {
            return Err(bad());
        }
        Ok(Self(n.to_le_bytes()))
    }
}

/// As zenoh prints a `ZenohId`: the id as a hexadecimal number.
impl fmt::Display for SourceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:x}", u128::from_le_bytes(self.0))
    }
}

/// A source in words: its id, or "no source" for a message that names none.
pub fn describe(source: Option<SourceId>) -> String {
    source.map_or_else(|| "no source attached".into(), |s| format!("session {s}"))
}

/// The source a stream is pinned to, as one receiver believes it.
///
/// - A pin made with [`SourcePin::expect`] holds its source from the start and never lapses:
///   every message from another source, or naming none, is refused (the source was known
///   before the first message: `tilting live` chooses its nodes' zenoh ids, and a node started
///   by hand is told its peer's id with `--plant-id` / `--controller-id`).
/// - Otherwise, before any believed message that names a source, every message is admitted (a
///   peer that attaches no source is never pinned: "where known").
/// - The first believed message that names a source pins it ([`SourcePin::believe`]).
/// - While pinned, a message from another source, or naming none, is refused
///   ([`SourcePin::admits`]), unless the pinned source has said nothing believed for
///   [`SourcePin::lapse`]: then the pin has lapsed and the next believed message pins anew (a
///   controller restarted after a crash is a new session).
#[derive(Debug, Clone)]
pub struct SourcePin {
    /// How long the pinned source may be silent before another may take its place.
    pub lapse: Duration,
    /// The pinned source and when it last sent a believed message.
    pinned: Option<(SourceId, Instant)>,
    /// The source was known in advance ([`SourcePin::expect`]): the pin never lapses.
    expected: bool,
}

impl SourcePin {
    /// An empty pin that lapses after `lapse` of silence.
    pub fn new(lapse: Duration) -> Self {
        Self {
            lapse,
            pinned: None,
            expected: false,
        }
    }

    /// A pin held by `source` from the start, which never lapses and never moves.
    pub fn expect(source: SourceId) -> Self {
        Self {
            lapse: Duration::MAX,
            pinned: Some((source, Instant::now())),
            expected: true,
        }
    }

    /// An expected pin for `source` if it is known, else an empty pin that lapses after `lapse`.
    pub fn expect_or_new(source: Option<SourceId>, lapse: Duration) -> Self {
        source.map_or_else(|| Self::new(lapse), Self::expect)
    }

    /// Was the source known in advance ([`SourcePin::expect`])?
    pub fn is_expected(&self) -> bool {
        self.expected
    }

    /// The pinned source, if any.
    pub fn pinned(&self) -> Option<SourceId> {
        self.pinned.map(|p| p.0)
    }

    /// Whether a message from `source` (`None`: it names none), received at `now`, may be
    /// believed: `Err` with the pinned source if another source holds a live pin.
    pub fn admits(&self, source: Option<SourceId>, now: Instant) -> Result<(), SourceId> {
        match self.pinned {
            Some((p, _)) if source == Some(p) => Ok(()),
            Some((p, _)) if self.expected => Err(p),
            Some((p, last)) if now.saturating_duration_since(last) < self.lapse => Err(p),
            _ => Ok(()),
        }
    }

    /// A message from `source` received at `now` was believed (after [`SourcePin::admits`]
    /// and every other rule): it pins its source, or keeps the pin alive.
    pub fn believe(&mut self, source: Option<SourceId>, now: Instant) {
        if self.expected {
            // Only the expected source is ever admitted: nothing to move.
            return;
        }
        match (source, self.pinned) {
            (Some(s), _) => self.pinned = Some((s, now)),
            // Admitted without a source: the pin had lapsed.
            (None, Some(_)) => self.pinned = None,
            (None, None) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attachments_round_trip_and_nothing_else_is_a_source() {
        let id = SourceId([7; 16]);
        assert_eq!(SourceId::from_attachment(&id.attachment()), Some(id));
        assert_eq!(SourceId::from_attachment(&[]), None);
        assert_eq!(SourceId::from_attachment(&id.attachment()[..19]), None);
        let mut other = id.attachment();
        other[0] = b'X';
        assert_eq!(SourceId::from_attachment(&other), None);
        // Printed as zenoh prints a ZenohId: the little-endian bytes as one hex number.
        let mut b = [0u8; 16];
        b[0] = 0xab;
        b[1] = 0x01;
        assert_eq!(SourceId(b).to_string(), "1ab");
    }

    #[test]
    fn the_first_believed_source_holds_the_pin_until_it_lapses() {
        let (a, b) = (Some(SourceId([1; 16])), Some(SourceId([2; 16])));
        let t0 = Instant::now();
        let ms = |n: u64| t0 + Duration::from_millis(n);
        let mut pin = SourcePin::new(Duration::from_millis(100));
        // Nothing pinned: all admitted, and a message without a source pins nothing.
        assert!(pin.admits(None, t0).is_ok() && pin.admits(b, t0).is_ok());
        pin.believe(None, t0);
        assert_eq!(pin.pinned(), None);
        pin.believe(a, t0);
        assert_eq!(pin.pinned(), a);
        // Pinned to a: b and "no source" are refused while a talks, a is admitted.
        for t in [0, 50, 99] {
            assert_eq!(pin.admits(b, ms(t)), Err(a.unwrap()), "{t} ms");
            assert_eq!(pin.admits(None, ms(t)), Err(a.unwrap()));
            assert!(pin.admits(a, ms(t)).is_ok());
        }
        // a keeps the pin alive by talking.
        pin.believe(a, ms(90));
        assert!(pin.admits(b, ms(180)).is_err());
        // 100 ms of silence from a: the pin lapses, b takes it, and a is the foreign one.
        assert!(pin.admits(b, ms(190)).is_ok());
        pin.believe(b, ms(190));
        assert_eq!(pin.pinned(), b);
        assert_eq!(pin.admits(a, ms(200)), Err(b.unwrap()));
        // A lapsed pin and a believed message without a source: unpinned.
        pin.believe(None, ms(400));
        assert_eq!(pin.pinned(), None);
    }

    #[test]
    fn an_expected_source_holds_the_pin_before_any_message_and_forever() {
        let (a, b) = (SourceId([1; 16]), SourceId([2; 16]));
        let t0 = Instant::now();
        let mut pin = SourcePin::expect(a);
        assert!(pin.is_expected());
        // Before a's first message, b (the rogue that talks first) and "no source" are refused.
        assert_eq!(pin.admits(Some(b), t0), Err(a));
        assert_eq!(pin.admits(None, t0), Err(a));
        // Even if the caller believes them, the pin does not move.
        pin.believe(Some(b), t0);
        pin.believe(None, t0);
        assert_eq!(pin.pinned(), Some(a));
        // No lapse: an hour of silence from a, b still refused; a admitted.
        let hour = t0 + Duration::from_secs(3600);
        assert_eq!(pin.admits(Some(b), hour), Err(a));
        assert!(pin.admits(Some(a), hour).is_ok());
        // Without an expected source, the same rogue would have taken the pin.
        let mut open = SourcePin::expect_or_new(None, Duration::from_millis(500));
        assert!(open.admits(Some(b), t0).is_ok());
        open.believe(Some(b), t0);
        assert_eq!(open.pinned(), Some(b));
    }

    #[test]
    fn zenoh_ids_parse_as_zenoh_prints_them() {
        // Display and FromStr are inverse on random-looking ids (round trip) ...
        for n in [
            1u128,
            0x1ab,
            u128::MAX,
            0x0123_4567_89ab_cdef_0011_2233_4455_6677,
        ] {
            let id = SourceId(n.to_le_bytes());
            assert_eq!(id.to_string().parse::<SourceId>(), Ok(id), "{n:x}");
        }
        // ... and "1ab" is the little-endian bytes ab 01 00 .. (as zenoh's ZenohId::to_le_bytes).
        let id: SourceId = "1ab".parse().unwrap();
        assert_eq!(&id.0[..3], &[0xab, 0x01, 0x00]);
        assert_eq!("1AB".parse::<SourceId>(), Ok(id));
        for bad in ["", "0", "000", "xyz", "-1", &"f".repeat(33)] {
            let e = bad.parse::<SourceId>().unwrap_err();
            assert!(e.contains("hexadecimal digits"), "{bad}: {e}");
        }
    }
}
