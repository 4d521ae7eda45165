//! The output flags as a user meets them: `.exr` with `--exr-half` and `--aovs`,
//! `--exposure`/`--tonemap` on PNG, a `.ply` mesh rendered end to end, and the errors
//! for combinations that cannot work (refused before any work, nothing written).

use crate::common::bin::run;
use crate::common::temp::temp_dir;
use std::path::Path;
use std::process::Output;

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

fn render(scene: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        scene,
        "-o",
        out.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "1",
        "--quiet",
    ];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn exr_half_with_aovs_has_ten_half_channels() {
    use exr::prelude::FlatSamples;
    let dir = temp_dir("aovs");
    let out = dir.join("w.exr");
    let o = render(&scene("whitted.toml"), &out, &["--exr-half", "--aovs"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let image = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    let layer = &image.layer_data[0];
    assert_eq!((layer.size.0, layer.size.1), (16, 12));
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(
        names,
        [
            "B", "G", "R", "albedo.B", "albedo.G", "albedo.R", "depth.Z", "normal.X", "normal.Y",
            "normal.Z"
        ]
    );
    for c in &layer.channel_data.list {
        assert!(
            matches!(c.sample_data, FlatSamples::F16(_)),
            "{} is not half",
            c.name
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exposure_changes_png_but_not_exr() {
    let dir = temp_dir("exposure");
    let (a, b) = (dir.join("a.png"), dir.join("b.png"));
    let (c, d) = (dir.join("c.exr"), dir.join("d.exr"));
    let s = scene("whitted.toml");
    for (out, extra) in [
        (&a, &[][..]),
        (&b, &["--exposure", "-1.5", "--tonemap", "filmic"][..]),
        (&c, &[][..]),
        (&d, &["--exposure", "-1.5", "--tonemap", "filmic"][..]),
    ] {
        let o = render(&s, out, extra);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let read = |p: &Path| std::fs::read(p).unwrap();
    assert_ne!(read(&a), read(&b), "--exposure did not change the PNG");
    assert_eq!(read(&c), read(&d), "--exposure changed the EXR");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ply_mesh_renders_and_bad_combinations_are_refused_before_work() {
    let dir = temp_dir("ply");
    let ply = dir.join("tri.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
         end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
    )
    .unwrap();
    let out = dir.join("ply.png");
    let o = render(ply.to_str().unwrap(), &out, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());

    let bad = dir.join("bad.ply");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&ply)
            .unwrap()
            .replace("4 0 1 2 3", "4 0 1 2 7"),
    )
    .unwrap();
    let cases: [(&str, &Path, &[&str], &str); 4] = [
        (
            bad.to_str().unwrap(),
            &dir.join("x.png"),
            &[],
            "bad.ply:14: face 0",
        ),
        (
            &scene("whitted.toml"),
            &dir.join("y.png"),
            &["--aovs"],
            "need an .exr output",
        ),
        (
            &scene("whitted.toml"),
            &dir.join("z.png"),
            &["--exposure", "100"],
            "invalid exposure",
        ),
        (
            &scene("whitted.toml"),
            &dir.join("w.png"),
            &["--tonemap", "gamma"],
            "unknown tone mapping",
        ),
    ];
    for (input, out, extra, expect) in cases {
        let o = render(input, out, extra);
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(expect), "{extra:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!out.exists(), "{extra:?} wrote {}", out.display());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
