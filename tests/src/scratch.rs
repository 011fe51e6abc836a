//! [`Scratch`]: the one temporary-directory helper of the project's tests. The process tests
//! use it through `tilting_tests::Scratch`; the command-line tests of `cli/tests` include this
//! file (`#[path]`), as they cannot depend on this crate (it depends on theirs).

use std::path::Path;

/// A scratch directory for one test (the `tempfile` crate's), removed on drop unless the test
/// failed or `TILTING_TESTS_KEEP` is set (then it is kept for a look and its path printed).
pub struct Scratch(Option<tempfile::TempDir>);

impl Scratch {
    /// A new empty directory named after `tag` under the system's temp directory.
    pub fn new(tag: &str) -> Self {
        let dir = tempfile::Builder::new()
            .prefix(&format!("tilting-tests-{tag}-"))
            .tempdir()
            .expect("cannot create a scratch directory");
        Self(Some(dir))
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        self.0.as_ref().expect("present until drop").path()
    }

    /// The directory as a command-line argument.
    pub fn arg(&self) -> String {
        self.path().to_string_lossy().into_owned()
    }

    /// Writes `contents` to the file `name` in the directory and returns its path as a
    /// command-line argument.
    pub fn file(&self, name: &str, contents: &str) -> String {
        let p = self.path().join(name);
        std::fs::write(&p, contents).expect("cannot write a scratch file");
        p.to_string_lossy().into_owned()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if let Some(dir) = self.0.take() {
            if std::env::var_os("TILTING_TESTS_KEEP").is_some() || std::thread::panicking() {
                eprintln!("kept {}", dir.keep().display());
            }
        }
    }
}
