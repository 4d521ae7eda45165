//! Bad input that never hurts, beyond what `tests/suite/load.rs` and `tests/suite/cli.rs` cover:
//! unreadable paths, values that overflow to infinity, inputs found by fuzzing. Each
//! must exit non-zero with a message naming the file (and line where there is one),
//! and write nothing: no image and no temporary file.

use crate::common::bin::{BIN, bin};
use crate::common::temp::{temp_dir, write};
use std::path::Path;
use std::process::Command;

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Renders `scene` to `dir/out.png`: must fail with `expect` in the message, and leave
/// exactly the files `dir` held before.
fn assert_fails(dir: &Path, scene: &Path, extra: &[&str], expect: &str) {
    let before = entries(dir);
    let out = dir.join("out.png");
    let o = bin()
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(&out)
        .args(["-q", "--width", "8", "--height", "8"])
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{}: {err}", scene.display());
    assert!(err.contains(expect), "expected `{expect}` in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        entries(dir),
        before,
        "files written for {}",
        scene.display()
    );
}

#[test]
fn directories_where_files_are_expected() {
    let dir = temp_dir("dirs");
    let scene_dir = dir.join("scene.toml");
    std::fs::create_dir(&scene_dir).unwrap();
    assert_fails(&dir, &scene_dir, &[], "scene.toml");
    let obj_dir = dir.join("mesh.obj");
    std::fs::create_dir(&obj_dir).unwrap();
    assert_fails(&dir, &obj_dir, &[], "mesh.obj");
    // A mesh entry naming a directory.
    let toml = write(&dir, "m.toml", "[[mesh]]\nfile = \"mesh.obj\"\n");
    assert_fails(&dir, &toml, &[], "m.toml:2");
    // The output path is a directory: the rename fails, the temp file is removed.
    let s = write(
        &dir,
        "s.toml",
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n",
    );
    std::fs::create_dir(dir.join("out.png")).unwrap();
    assert_fails(&dir, &s, &[], "out.png");
    // ... and so is writing into a directory that does not exist.
    let o = bin()
        .args(["render", s.to_str().unwrap(), "-q", "-o"])
        .arg(dir.join("no-such-dir").join("x.png"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no-such-dir"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A scene without read permission. Tests often run as root, for whom permission bits
/// do not stop reads: then the binary runs as the unprivileged user 65534 through
/// `setpriv` (util-linux), and the test prints SKIPPED only when that is impossible.
#[cfg(unix)]
#[test]
fn unreadable_scene_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp_dir("perm");
    let s = write(
        &dir,
        "s.toml",
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n",
    );
    std::fs::set_permissions(&s, std::fs::Permissions::from_mode(0o000)).unwrap();
    if std::fs::read(&s).is_err() {
        assert_fails(&dir, &s, &[], "s.toml");
    } else if let Some(prefix) = unprivileged_prefix() {
        // the unprivileged user may write the output directory, but not read the scene
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
        let before = entries(&dir);
        let o = Command::new(&prefix[0])
            .args(&prefix[1..])
            .arg(BIN)
            .arg("render")
            .arg(&s)
            .arg("-o")
            .arg(dir.join("out.png"))
            .args(["-q", "--width", "8", "--height", "8"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains("s.toml") && err.contains("ermission denied"),
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(entries(&dir), before);
    } else {
        eprintln!(
            "SKIPPED: unreadable_scene_file: running as root, which reads any file, and \
             `setpriv` cannot drop to an unprivileged user here"
        );
    }
    std::fs::set_permissions(&s, std::fs::Permissions::from_mode(0o644)).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `setpriv` arguments that run a command as the unprivileged user and group 65534
/// (nobody), if that works here (it needs root and util-linux).
#[cfg(unix)]
fn unprivileged_prefix() -> Option<Vec<String>> {
    let prefix: Vec<String> = [
        "setpriv",
        "--reuid=65534",
        "--regid=65534",
        "--clear-groups",
    ]
    .map(String::from)
    .to_vec();
    let ok = Command::new(&prefix[0])
        .args(&prefix[1..])
        .arg(BIN)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(prefix)
}

#[test]
fn values_that_overflow_to_infinity() {
    let dir = temp_dir("overflow");
    // 1e39 parses to an f32 infinity.
    let obj = write(&dir, "big.obj", "v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_fails(&dir, &obj, &[], "big.obj:1");
    let r = write(
        &dir,
        "r.toml",
        "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1e39\n",
    );
    assert_fails(&dir, &r, &[], "r.toml:3");
    let c = write(
        &dir,
        "c.toml",
        "[[sphere]]\ncenter = [0, -1e39, 0]\nradius = 1\n",
    );
    assert_fails(&dir, &c, &[], "c.toml:2");
    // Finite vertices pushed past f32::MAX by the mesh transform: located at the entry.
    write(&dir, "m.obj", "v 1e10 0 0\nv 0 1e10 0\nv 0 0 1\nf 1 2 3\n");
    let t = write(&dir, "t.toml", "[[mesh]]\nfile = \"m.obj\"\nscale = 1e30\n");
    assert_fails(&dir, &t, &[], "t.toml:2");
    let t = write(
        &dir,
        "u.toml",
        "[[mesh]]\nfile = \"m.obj\"\ntranslate = [3e38, 0, 0]\nscale = 3e38\n",
    );
    assert_fails(&dir, &t, &[], "u.toml:2");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn malformed_obj_records() {
    let dir = temp_dir("obj");
    for (name, text, expect) in [
        ("noverts.obj", "f 1 2 3\n", "noverts.obj:1"),
        ("neg.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -5\n", "neg.obj:3"),
        (
            "vn.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 inf 1\nf 1//1 2//1 3//1\n",
            "vn.obj:4",
        ),
        ("text.obj", "v zero 0 0\n", "text.obj:1"),
    ] {
        let p = write(&dir, name, text);
        assert_fails(&dir, &p, &[], expect);
    }
    // Valid UTF-8 control and non-ASCII characters on an unknown record are ignored like
    // any unknown record; with no face left this used to fail only for "no triangles",
    // and is now an empty mesh rendered with warnings (issue 13).
    let p = write(&dir, "utf8.obj", "v 0 0 0\n\u{0}\u{ff}");
    let o = bin()
        .arg("render")
        .arg(&p)
        .arg("-o")
        .arg(dir.join("utf8.png"))
        .args(["-q", "--width", "8", "--height", "8"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("utf8.obj: no triangles") && err.contains("no primitives"),
        "{err}"
    );
    std::fs::remove_file(dir.join("utf8.png")).unwrap();
    let bytes = dir.join("bin.obj");
    std::fs::write(&bytes, [b'v', b' ', 0xff, 0xfe, b'\n']).unwrap();
    assert_fails(&dir, &bytes, &[], "bin.obj:1");
    std::fs::remove_dir_all(&dir).unwrap();
}
