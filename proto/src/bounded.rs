//! Bounded reads of the files a user hands the programs: parameter and scenario files, zenoh
//! and access-control configurations, certificate manifests, recordings. One helper for every
//! such read, so that no file (`/dev/zero`, a named pipe, a log given by mistake) can make a
//! program read until memory runs out: beyond its limit a read stops with an error that names
//! the file, the limit and what the file was meant to be.
//!
//! ```
//! use tilting_proto::bounded::{read_to_string, CONFIG_LIMIT};
//! let e = read_to_string("/dev/zero".as_ref(), CONFIG_LIMIT, "a parameter file").unwrap_err();
//! assert!(e.to_string().contains("larger than the 1048576-byte limit"), "{e}");
//! ```

use std::io::Read as _;
use std::path::Path;

/// Largest configuration file read (bytes): parameters, scenarios, zenoh configurations,
/// manifests. The largest the project writes is a router configuration of a few kB.
pub const CONFIG_LIMIT: u64 = 1 << 20;

/// Largest recording read (bytes): an MCAP file (read whole) or a CSV file of a run. A 20 s
/// live run at 1 kHz records about 1.4 MB of MCAP and 3 MB of CSV, so this is hours of
/// recording.
pub const RECORDING_LIMIT: u64 = 1 << 30;

/// Reads the whole of `path`, at most `limit` bytes; `what` names the file's purpose in the
/// error (`"a parameter file"`). A longer file (or an endless one) is an error of kind
/// [`std::io::ErrorKind::InvalidData`] whose text says so; the other errors are the system's.
/// The buffer grows with what is actually read, never from the file's stated size alone.
pub fn read(path: &Path, limit: u64, what: &str) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let stated = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut bytes = Vec::with_capacity(stated.min(limit) as usize);
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "{} is larger than the {limit}-byte limit for {what} (not {what}?)",
                path.display()
            ),
        ));
    }
    Ok(bytes)
}

/// [`read`] as UTF-8 text (an error of kind [`std::io::ErrorKind::InvalidData`] if it is not).
pub fn read_to_string(path: &Path, limit: u64, what: &str) -> std::io::Result<String> {
    String::from_utf8(read(path, limit, what)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "{} is not UTF-8 text (byte {}), so not {what}",
                path.display(),
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_within_the_limit_reads_whole_and_one_beyond_is_refused() {
        let dir = std::env::temp_dir().join(format!("bounded-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("f.txt");
        std::fs::write(&path, "0123456789").unwrap();
        // Exactly at the limit: read; one byte over: refused, naming the file and the limit.
        assert_eq!(read_to_string(&path, 10, "x").unwrap(), "0123456789");
        let e = read(&path, 9, "a scenario file").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        let text = e.to_string();
        assert!(
            text.contains("f.txt") && text.contains("9-byte limit"),
            "{text}"
        );
        assert!(text.contains("a scenario file"), "{text}");
        // An endless file stops at the limit.
        let e = read(Path::new("/dev/zero"), 4096, "x").unwrap_err();
        assert!(e.to_string().contains("4096-byte limit"), "{e}");
        // Not text.
        std::fs::write(&path, [b'a', 0xff, b'b']).unwrap();
        let e = read_to_string(&path, 10, "a parameter file").unwrap_err();
        assert!(e.to_string().contains("not UTF-8 text (byte 1)"), "{e}");
        // A missing file: the system's error.
        let e = read(&dir.join("nope"), 10, "x").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
