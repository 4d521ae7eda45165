//! Scratch directories for tests that write files. The suite is one binary whose tests
//! run in parallel threads, so every call gets a directory of its own: named after the
//! calling test file (`#[track_caller]`), the process id, a counter shared by the whole
//! binary and the caller's tag, e.g. `packet-render-load-4242-17-toml`. Two tests with
//! the same tag, in the same file or not, never share a directory. `write` puts a file in
//! one.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty directory under the system temp dir, unique to this call. A stale one
/// left by an earlier process with the same id is removed first.
#[track_caller]
pub fn temp_dir(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let file = Path::new(std::panic::Location::caller().file())
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("test")
        .to_owned();
    let dir = std::env::temp_dir().join(format!(
        "packet-render-{file}-{}-{}-{tag}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `contents` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p
}
