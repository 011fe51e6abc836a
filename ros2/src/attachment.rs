//! The attachment rmw_zenoh (0.2.4 and later) puts on every sample, and drops a sample without.
//!
//! 33 bytes, zenoh-ext serialization of (`int64` sequence number, `int64` source timestamp,
//! `uint8[16]` GID): the sequence number (from 1, little endian), the source timestamp (ns since
//! the Unix epoch, little endian), the length 16 of the GID as one LEB128 byte `0x10`, then the
//! publisher's GID ([`crate::names::gid`]).

use thiserror::Error;

/// Size of an attachment, bytes.
pub const LEN: usize = 33;

/// The attachment of one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// Publication number of the publisher, from 1.
    pub seq: i64,
    /// When the publisher sent it, ns since the Unix epoch (wall clock).
    pub source_timestamp_ns: i64,
    /// The publisher's GID.
    pub gid: [u8; 16],
}

/// An attachment that is not rmw_zenoh's.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum AttachmentError {
    /// No attachment at all.
    #[error("sample has no attachment; allowed: the 33-byte rmw_zenoh attachment")]
    Missing,
    /// Wrong size.
    #[error("attachment is {0} bytes; allowed: exactly 33 (rmw_zenoh >= 0.2.4)")]
    Length(usize),
    /// The GID's length byte is not 16.
    #[error("attachment GID length byte is {0:#04x}; allowed: 0x10")]
    GidLength(u8),
}

impl Attachment {
    /// The 33 bytes.
    pub fn encode(&self) -> [u8; LEN] {
        let mut b = [0u8; LEN];
        b[..8].copy_from_slice(&self.seq.to_le_bytes());
        b[8..16].copy_from_slice(&self.source_timestamp_ns.to_le_bytes());
        b[16] = 16;
        b[17..].copy_from_slice(&self.gid);
        b
    }

    /// Reads the 33 bytes (`None`: the sample had no attachment).
    pub fn decode(bytes: Option<&[u8]>) -> Result<Attachment, AttachmentError> {
        let b = bytes.ok_or(AttachmentError::Missing)?;
        if b.len() != LEN {
            return Err(AttachmentError::Length(b.len()));
        }
        if b[16] != 16 {
            return Err(AttachmentError::GidLength(b[16]));
        }
        let i64_at = |i: usize| i64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        Ok(Attachment {
            seq: i64_at(0),
            source_timestamp_ns: i64_at(8),
            gid: b[17..].try_into().expect("16 bytes"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_by_hand() {
        let a = Attachment {
            seq: 0x0102,
            source_timestamp_ns: -2,
            gid: core::array::from_fn(|i| i as u8 + 0xa0),
        };
        let b = a.encode();
        assert_eq!(&b[..8], &[2, 1, 0, 0, 0, 0, 0, 0]);
        assert_eq!(&b[8..16], &[0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff]);
        assert_eq!(b[16], 0x10);
        assert_eq!(b[17], 0xa0);
        assert_eq!(b[32], 0xaf);
        assert_eq!(Attachment::decode(Some(&b)), Ok(a));
        assert_eq!(Attachment::decode(None), Err(AttachmentError::Missing));
        assert_eq!(
            Attachment::decode(Some(&b[..32])),
            Err(AttachmentError::Length(32))
        );
        let mut c = b;
        c[16] = 24;
        assert_eq!(
            Attachment::decode(Some(&c)),
            Err(AttachmentError::GidLength(24))
        );
    }
}
