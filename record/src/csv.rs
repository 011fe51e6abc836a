//! CSV files that survive the loss of the process writing them: whole rows only, on disk at
//! least every flush interval.
//!
//! A `BufWriter` hands the file whatever fills its buffer, cut at any byte, so a process killed
//! with SIGKILL leaves a torn last row and loses up to the buffer's size. [`RowWriter`] keeps
//! the rows of the current interval in memory and writes them with one `write(2)` call when the
//! interval ends (or the buffer grows past [`RowWriter::MAX_BUFFER`]): the file only ever grows
//! by whole rows, and a kill loses at most the last interval. (A `write` to a regular file is
//! not interrupted by a signal once it has started.) The plant's `--record` and the
//! [`crate::Recorder`] of `tilting live` both use it.

use std::fs::File;
use std::io::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

/// A CSV file written by whole rows.
pub struct RowWriter {
    file: File,
    buf: Vec<u8>,
    last_flush: Instant,
    interval: Duration,
}

impl RowWriter {
    /// The default flush interval: what a kill can lose at most.
    pub const INTERVAL: Duration = Duration::from_millis(100);
    /// Rows buffered past this many bytes are written at once, whatever the interval.
    pub const MAX_BUFFER: usize = 1 << 18;

    /// Creates (truncates) `path` and writes `header` as its first row at once.
    pub fn create(path: &Path, header: &str, interval: Duration) -> std::io::Result<Self> {
        let mut file = File::create(path)?;
        file.write_all(format!("{header}\n").as_bytes())?;
        Ok(Self {
            file,
            buf: Vec::with_capacity(1 << 16),
            last_flush: Instant::now(),
            interval,
        })
    }

    /// Appends one row (`args` without the line end); writes the buffered rows out when the
    /// interval has passed.
    pub fn row(&mut self, args: std::fmt::Arguments<'_>) -> std::io::Result<()> {
        self.buf.write_fmt(args)?;
        self.buf.push(b'\n');
        self.flush_if_due()
    }

    /// Writes the buffered rows out if the interval has passed or the buffer is full.
    pub fn flush_if_due(&mut self) -> std::io::Result<()> {
        if self.buf.len() >= Self::MAX_BUFFER || self.last_flush.elapsed() >= self.interval {
            self.flush()
        } else {
            Ok(())
        }
    }

    /// Writes the buffered rows out now, with one `write_all`.
    pub fn flush(&mut self) -> std::io::Result<()> {
        if !self.buf.is_empty() {
            self.file.write_all(&self.buf)?;
            self.buf.clear();
        }
        self.last_flush = Instant::now();
        Ok(())
    }
}

impl Drop for RowWriter {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_reach_the_file_whole_and_on_time() {
        let dir = std::env::temp_dir().join(format!("tilting-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rows.csv");
        let mut w = RowWriter::create(&path, "a,b", Duration::from_millis(50)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n");
        w.row(format_args!("{},{}", 1, 2.5)).unwrap();
        // Within the interval the row waits in memory...
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n");
        std::thread::sleep(Duration::from_millis(60));
        // ...and goes out, whole, with the first row after it.
        w.row(format_args!("{},{}", 3, 4)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n1,2.5\n3,4\n");
        // A large burst goes out at MAX_BUFFER, at a row boundary.
        let row = "x".repeat(999);
        for _ in 0..(RowWriter::MAX_BUFFER / 1000 + 1) {
            w.row(format_args!("{row}")).unwrap();
        }
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.len() > RowWriter::MAX_BUFFER && text.ends_with('\n'));
        drop(w);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
