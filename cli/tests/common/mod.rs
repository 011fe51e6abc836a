//! Helpers shared by the command-line tests of `tilting`.

#![allow(dead_code)] // each test file uses a part

use std::path::Path;

/// The front door, built by cargo for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_tilting");

/// A fresh directory (the `tempfile` crate's), removed on drop unless the test failed (then it
/// is kept for a look and its path printed).
pub struct TempDir(Option<tempfile::TempDir>);

impl TempDir {
    /// A new empty directory whose name holds `tag`.
    pub fn new(tag: &str) -> Self {
        let d = tempfile::Builder::new()
            .prefix(&format!("tilting-cli-{tag}-"))
            .tempdir()
            .expect("cannot create a temp dir");
        TempDir(Some(d))
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        self.0.as_ref().expect("present until drop").path()
    }

    /// Writes `contents` to the file `name` in the directory and returns its path.
    pub fn file(&self, name: &str, contents: &str) -> String {
        let p = self.path().join(name);
        std::fs::write(&p, contents).expect("cannot write a temp file");
        p.to_string_lossy().into_owned()
    }

    /// The directory as a command-line argument.
    pub fn arg(&self) -> String {
        self.path().to_string_lossy().into_owned()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if let Some(d) = self.0.take() {
            if std::thread::panicking() {
                eprintln!("kept {}", d.keep().display());
            }
        }
    }
}
