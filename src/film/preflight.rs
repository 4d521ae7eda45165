//! Checks on output paths made before any work starts (issue 13): a render that cannot
//! write its results fails in milliseconds, not after the whole frame.

use crate::error::{Error, Result};
use std::fs::OpenOptions;
use std::path::{Path, PathBuf};

/// Checks that every path in `outputs` can be written: it has a file name, its
/// directory exists and a file can be created there (a probe file is created and
/// removed again), it is not an existing directory, and no two outputs are the same
/// file (compared by canonical directory plus file name, so `a/../x.png` equals
/// `x.png`). The error names the path.
pub fn check_output_paths(outputs: &[&Path]) -> Result<()> {
    let mut seen: Vec<(PathBuf, &Path)> = Vec::new();
    for &path in outputs {
        let key = writable_target(path)?;
        if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
            return Err(Error::parameter(
                "output path",
                format!(
                    "{} and {} are the same file: every output needs its own path",
                    first.display(),
                    path.display()
                ),
            ));
        }
        seen.push((key, path));
    }
    Ok(())
}

/// The canonical identity (directory + file name) of a writable output path.
fn writable_target(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        Error::parameter(
            "output path",
            format!("{} has no file name", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let dir = dir.canonicalize().map_err(|e| {
        Error::parameter(
            "output path",
            format!(
                "{}: directory {} is not usable: {e}",
                path.display(),
                dir.display()
            ),
        )
    })?;
    let target = dir.join(name);
    if target.is_dir() {
        return Err(Error::parameter(
            "output path",
            format!("{} is a directory", path.display()),
        ));
    }
    // Writable? Create (and remove) a probe file where the atomic write will put its
    // temporary file.
    let probe = dir.join(format!(
        ".{}.probe-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| {
            Error::parameter(
                "output path",
                format!(
                    "{}: cannot create files in {}: {e}",
                    path.display(),
                    dir.display()
                ),
            )
        })?;
    let _ = std::fs::remove_file(&probe);
    Ok(target)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_file_by_two_spellings_is_refused() {
        let dir = std::env::temp_dir().join(format!("preflight-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let a = dir.join("x.png");
        let b = dir.join("sub").join("..").join("x.png");
        let e = check_output_paths(&[&a, &b]).unwrap_err().to_string();
        assert!(e.contains("same file"), "{e}");
        assert!(check_output_paths(&[&a, &dir.join("x.json")]).is_ok());
        let e = check_output_paths(&[&dir.join("missing").join("x.png")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing") && e.contains("not usable"), "{e}");
        let e = check_output_paths(&[&dir.join("sub")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a directory"), "{e}");
        // no probe file is left behind
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert_eq!(left.len(), 1, "{left:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
