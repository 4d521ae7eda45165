//! The `packet-render` binary as a user meets it: renders, stats, bench output, and
//! bad input that exits non-zero with a located message and writes nothing.

use crate::common::bin::{bin, json_lines, run};
use crate::common::temp::temp_dir;
use std::path::Path;
use std::process::{Command, Output};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

#[test]
fn renders_a_shipped_scene_with_stats() {
    let dir = temp_dir("render");
    let out = dir.join("w.png");
    let json = dir.join("w.json");
    let o = run(&[
        "render",
        &scene("whitted.toml"),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "48",
        "--height",
        "32",
        "--stats-json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (48, 32));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rays = &s["rays"];
    assert_eq!(rays["camera"], 48 * 32);
    assert!(rays["shadow"].as_u64().unwrap() > 0 && rays["reflection"].as_u64().unwrap() > 0);
    assert!(
        rays["refraction"].as_u64().unwrap() > 0,
        "the Whitted room has glass"
    );
    for phase in ["load", "film", "build", "render", "write"] {
        assert!(
            s["time_ms"][phase].as_f64().unwrap() >= 0.0,
            "time_ms.{phase}"
        );
    }
    // Page faults by phase: counted on Linux (a render maps fresh memory in some
    // phase), present as counts everywhere.
    let faults: Vec<u64> = ["load", "film", "build", "render", "write"]
        .iter()
        .map(|p| s["page_faults"][p].as_u64().expect("page_faults.{p}"))
        .collect();
    if cfg!(target_os = "linux") {
        assert!(faults.iter().sum::<u64>() > 0, "no page faults counted");
    }
    let features: Vec<&str> = s["features"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert!(features.contains(&"glass") && features.contains(&"mirror"));
    // the stats block names rays by kind and time by phase
    let e = stderr(&o);
    assert!(
        e.contains("rays")
            && e.contains("refraction")
            && e.contains("render")
            && e.contains("Mrays/s"),
        "{e}"
    );
}

#[test]
fn images_are_identical_at_any_thread_count() {
    let dir = temp_dir("threads");
    let mut bytes = Vec::new();
    for t in ["1", "2"] {
        let out = dir.join(format!("t{t}.png"));
        let o = run(&[
            "render",
            &scene("whitted.toml"),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "40",
            "--height",
            "40",
            "--spp",
            "4",
            "--seed",
            "7",
            "--threads",
            t,
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        bytes.push(std::fs::read(&out).unwrap());
    }
    assert_eq!(bytes[0], bytes[1]);
}

/// Runs a render that must fail: non-zero exit, an `error:` line containing `expect`,
/// no panic, and no output file.
fn assert_fails(args: &[&str], out: &Path, expect: &str) {
    let mut all = vec!["render"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["-o", out.to_str().unwrap(), "--quiet"]);
    let o = run(&all);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "args {args:?}: {e}");
    assert!(
        e.starts_with("error: ") && e.contains(expect),
        "args {args:?}: expected '{expect}' in: {e}"
    );
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists(), "args {args:?}: an output file was written");
    let leftovers: Vec<_> = std::fs::read_dir(out.parent().unwrap()).unwrap().collect();
    assert!(leftovers.iter().all(|f| {
        !f.as_ref()
            .unwrap()
            .file_name()
            .to_string_lossy()
            .contains(".tmp")
    }));
}

/// A frame whose film the process cannot have (10.8 GB under a 3 GB address-space
/// limit) is refused before any work with an error, not the allocator's abort; where
/// the machine's available memory is below the buffers' estimate, the budget check
/// refuses it first, with its own message.
#[cfg(target_os = "linux")]
#[test]
fn a_film_too_large_for_memory_is_an_error() {
    let dir = temp_dir("bigfilm");
    let out = dir.join("never.png");
    let o = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 3000000 && exec \"$0\" \"$@\"")
        .arg(bin().get_program())
        .args([
            "render",
            &scene("cornell.toml"),
            "--width",
            "30000",
            "--height",
            "30000",
        ])
        .args(["--threads", "2", "--quiet", "-o", out.to_str().unwrap()])
        .output()
        .expect("sh runs");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.starts_with("error: invalid ")
            && (e.contains("the 30000x30000 film needs 10299.7 MiB")
                || e.contains("buffers would need")),
        "{e}"
    );
    assert!(
        !e.contains("panicked") && !e.contains("memory allocation"),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn bad_input_gives_located_errors_and_writes_nothing() {
    let dir = temp_dir("bad");
    let out = dir.join("never.png");
    let missing = dir.join("missing.toml");
    assert_fails(&[missing.to_str().unwrap()], &out, "missing.toml");

    let syntax = dir.join("syntax.toml");
    std::fs::write(&syntax, "[render]\nwidth = 64\nheight = = 3\n").unwrap();
    assert_fails(&[syntax.to_str().unwrap()], &out, "syntax.toml:3:");

    let nan_obj = dir.join("nan.obj");
    std::fs::write(&nan_obj, "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n").unwrap();
    assert_fails(&[nan_obj.to_str().unwrap()], &out, "nan.obj:3");

    let bad_index = dir.join("index.obj");
    std::fs::write(&bad_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    assert_fails(&[bad_index.to_str().unwrap()], &out, "index.obj:4");

    let whitted = scene("whitted.toml");
    assert_fails(&[&whitted, "--width", "0"], &out, "width");
    assert_fails(&[&whitted, "--spp", "1000000000"], &out, "spp");
    assert_fails(&[&whitted, "--max-depth", "100000"], &out, "depth");

    // an unsupported output format is refused before rendering
    let o = run(&[
        "render",
        &whitted,
        "-o",
        dir.join("x.bmp").to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains(".png"), "{}", stderr(&o));
    assert!(!dir.join("x.bmp").exists());

    // clap rejects unknown structures with exit code 2 and the list of names
    let o = run(&[
        "render",
        &whitted,
        "-o",
        out.to_str().unwrap(),
        "--accel",
        "octopus",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("bvh4"));
}

#[test]
fn bench_prints_the_protocol_fields_and_modes_agree() {
    let o = run(&[
        "bench",
        "--width",
        "64",
        "--height",
        "64",
        "--reps",
        "1",
        "--threads",
        "1",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = json_lines(&o);
    assert_eq!(rows.len(), 21, "7 modes x 3 workloads");
    let fields = [
        "tracer",
        "mode",
        "workload",
        "threads",
        "rays",
        "hits_or_occluded",
        "sum_t",
        "mrays_median",
        "mrays_min",
        "mrays_max",
        "build_ms",
    ];
    for r in &rows {
        for f in fields {
            assert!(!r[f].is_null(), "missing field {f} in {r}");
        }
    }
    // every mode reports the same checksums for the same workload
    for w in ["primary", "shadow", "diffuse"] {
        let of: Vec<_> = rows.iter().filter(|r| r["workload"] == w).collect();
        for r in &of {
            assert_eq!(r["hits_or_occluded"], of[0]["hits_or_occluded"], "{w}");
            let (a, b) = (
                r["sum_t"].as_f64().unwrap(),
                of[0]["sum_t"].as_f64().unwrap(),
            );
            assert!(
                (a - b).abs() <= 1e-6 * b.abs().max(1.0),
                "{w}: sum_t {a} vs {b}"
            );
        }
    }
    assert!(rows[0]["hits_or_occluded"].as_u64().unwrap() > 0);
}

#[test]
fn accel_compare_prints_one_json_row_per_structure_with_equal_checksums() {
    let o = run(&[
        "accel-compare",
        &scene("meshes/gem.obj"),
        "--width",
        "24",
        "--height",
        "16",
        "--reps",
        "1",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = json_lines(&o);
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["structure"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "bruteforce",
            "bvh2",
            "bvh4",
            "bvh8",
            "bvh4c",
            "bvh8c",
            "grid",
            "grid-nomailbox",
            "octree",
            "kdtree"
        ]
    );
    for r in &rows {
        assert_eq!(r["primary_hits"], rows[0]["primary_hits"], "{r}");
        assert_eq!(r["shadow_occluded"], rows[0]["shadow_occluded"], "{r}");
    }
}

#[test]
fn render_accepts_the_spatial_structures() {
    let dir = temp_dir("spatial");
    for accel in ["grid", "octree", "kdtree"] {
        let out = dir.join(format!("{accel}.png"));
        let o = run(&[
            "render",
            &scene("sphereflake.toml"),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "32",
            "--accel",
            accel,
            "--quiet",
        ]);
        assert!(o.status.success(), "{accel}: {}", stderr(&o));
        assert!(out.exists());
    }
}

/// Ctrl-C during a long render: the process exits 130 and leaves neither the image nor
/// a temporary file (the handler removes writes in progress; see film::output).
#[test]
fn interrupted_render_leaves_no_image_and_no_temp_file() {
    let dir = temp_dir("sigint");
    let out = dir.join("slow.png");
    let mut child = bin()
        .args([
            "render",
            &scene("whitted.toml"),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "2048",
            "--height",
            "2048",
            "--spp",
            "256",
            "--threads",
            "1",
            "-q",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("binary starts");
    // Long enough for the handler to be installed and the render to be under way.
    std::thread::sleep(std::time::Duration::from_millis(1000));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the render finished before it could be interrupted"
    );
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(kill.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn precision_prints_one_json_row_per_case_and_kernel() {
    let o = run(&["precision", "--rays", "50", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = json_lines(&o);
    assert!(rows.len() >= 3 * 10, "{} rows", rows.len());
    for r in &rows {
        assert!(r["t_rel_max"].as_f64().unwrap() < 1e-3, "{r}");
        assert!(["scalar", "bvh4-single", "bvh4-packet"].contains(&r["kernel"].as_str().unwrap()));
    }
}

// ------------------------------------------------ resources and outputs (issue 13)

#[test]
fn threads_above_the_cap_are_refused_before_work() {
    let dir = temp_dir("threads");
    let out = dir.join("t.png");
    // Used to run for 16 minutes and then panic setting up 100000 thread stacks.
    assert_fails(
        &[&scene("whitted.toml"), "--threads", "100000"],
        &out,
        "at most 1024 worker threads",
    );
    let o = run(&["render", "--help"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("at most 1024"));
}

#[test]
fn sample_products_are_validated_before_work() {
    let dir = temp_dir("products");
    let out = dir.join("p.png");
    let dof = scene("dof_area.toml");
    // 65536 x 1024 camera rays per pixel: aborted on a failed 2.4 GB allocation (134)
    assert_fails(
        &[
            &dof,
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "65536",
            "--lens-samples",
            "1024",
        ],
        &out,
        "67108864 camera rays per pixel",
    );
    // representable, but each of 256 workers holds the camera rays and radiance of up
    // to two pixels of 2^24 camera rays (the wavefront's waves are bounded, its pixels
    // in flight are not): about 570 GiB of buffers, refused with the estimate. (Before
    // the waves were bounded, one 16x16 tile's queues alone asked for that much.)
    assert_fails(
        &[
            &dof,
            "--width",
            "256",
            "--height",
            "256",
            "--threads",
            "256",
            "--spp",
            "65536",
            "--lens-samples",
            "256",
        ],
        &out,
        "GiB (estimated from the sample counts",
    );
}

#[test]
fn output_paths_are_checked_before_loading() {
    let dir = temp_dir("outputs");
    let whitted = scene("whitted.toml");
    // A missing scene *and* a missing output directory: the output is named, so it
    // was checked before the scene was even read (and long before rendering).
    let missing_dir = dir.join("nonexistent_dir").join("x.png");
    let o = run(&[
        "render",
        dir.join("missing.toml").to_str().unwrap(),
        "-o",
        missing_dir.to_str().unwrap(),
        "--quiet",
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("nonexistent_dir") && e.contains("not usable") && !e.contains("missing.toml"),
        "{e}"
    );
    // --stats-json naming the image: refused, nothing written (used to replace the
    // PNG with JSON and exit 0)
    let img = dir.join("same.png");
    let img_s = img.to_str().unwrap();
    assert_fails(
        &[
            &whitted,
            "--width",
            "8",
            "--height",
            "8",
            "--stats-json",
            img_s,
        ],
        &img,
        "same file",
    );
    // the same file spelled differently
    std::fs::create_dir(dir.join("sub")).unwrap();
    let other = dir.join("sub").join("..").join("same.png");
    assert_fails(
        &[&whitted, "--stats-json", other.to_str().unwrap()],
        &img,
        "same file",
    );
    // --stats-json into a missing directory: used to exit 1 after writing the image
    assert_fails(
        &[&whitted, "--stats-json", "/nonexistent_dir_13/x.json"],
        &img,
        "nonexistent_dir_13",
    );
}

#[test]
fn scenes_where_nothing_can_be_hit_render_with_a_warning() {
    let dir = temp_dir("empty");
    for (name, text, warning) in [
        ("empty.obj", "", "no primitives"),
        ("verts.obj", "v 0 0 0\nv 1 0 0\n", "no primitives"),
        (
            "flat.obj",
            "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
            "all 1 triangles are degenerate",
        ),
        (
            "empty.toml",
            "[render]\nwidth = 8\nheight = 8\n",
            "no primitives",
        ),
    ] {
        let s = dir.join(name);
        std::fs::write(&s, text).unwrap();
        let out = dir.join(format!("{name}.png"));
        let o = run(&[
            "render",
            s.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
            "--quiet",
        ]);
        let e = stderr(&o);
        assert!(o.status.success(), "{name}: {e}");
        assert!(
            e.contains("warning: ") && e.contains(warning),
            "{name}: {e}"
        );
        assert!(out.is_file(), "{name}");
    }
}

/// Issue 14 item 5: the camera flags give the same camera as TOML keys with the same
/// text, so the images are identical byte for byte (Radiance .hdr keeps more than
/// 8 bits, so a one-ulp camera difference would show in most pixels' mantissas).
#[test]
fn camera_flags_reproduce_a_toml_camera_bit_for_bit() {
    let dir = temp_dir("camera-flags");
    let toml = dir.join("cam.toml");
    std::fs::write(
        &toml,
        "[render]\nwidth = 40\nheight = 30\nspp = 1\nmax_depth = 4\n\n\
         [[generator]]\ntype = \"whitted_room\"\n\n\
         [camera]\neye = [0.1, 1.3, 4.7]\ntarget = [-0.3, 0.9, 0.01]\nup = [0.1, 1, 0]\nfov = 37.3\n",
    )
    .unwrap();
    let render = |scene: &str, out: &Path, extra: &[&str]| {
        let mut a = vec!["render", scene, "-o", out.to_str().unwrap(), "--quiet"];
        a.extend_from_slice(extra);
        let o = run(&a);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        std::fs::read(out).unwrap()
    };
    let from_toml = render(toml.to_str().unwrap(), &dir.join("toml.hdr"), &[]);
    let size = ["--width", "40", "--height", "30", "--max-depth", "4"];
    let mut flags = size.to_vec();
    flags.extend_from_slice(&[
        "--eye",
        "0.1,1.3,4.7",
        "--target",
        "-0.3,0.9,0.01",
        "--up",
        "0.1,1,0",
        "--fov",
        "37.3",
    ]);
    let shipped = scene("whitted.toml");
    let from_flags = render(&shipped, &dir.join("flags.hdr"), &flags);
    assert!(from_toml == from_flags, "flag camera renders differently");
    // the camera matters: the generator's own camera gives another image
    let default = render(&shipped, &dir.join("default.hdr"), &size);
    assert!(default != from_toml, "the test camera is the default one");
    // and a one-flag change is seen
    let mut fov = flags.clone();
    *fov.last_mut().unwrap() = "37.4";
    assert!(render(&shipped, &dir.join("fov.hdr"), &fov) != from_toml);
}

#[test]
fn bad_camera_flags_are_refused_before_work() {
    let dir = temp_dir("camera-bad");
    let out = dir.join("never.png");
    let s = scene("whitted.toml");
    assert_fails(
        &[&s, "--fov", "180"],
        &out,
        "--fov must be between 0 and 180",
    );
    assert_fails(
        &[&s, "--fov", "nan"],
        &out,
        "--fov must be between 0 and 180",
    );
    assert_fails(
        &[&s, "--eye", "1,2,3", "--target", "1,2,3"],
        &out,
        "eye and target are the same point",
    );
    assert_fails(
        &[&s, "--eye", "0,5,0", "--target", "0,0,0", "--up", "0,1,0"],
        &out,
        "up is parallel",
    );
    assert_fails(
        &[&s, "--up", "0,0,0"],
        &out,
        "--up must be a finite non-zero",
    );
    assert_fails(
        &[&s, "--eye", "inf,0,0"],
        &out,
        "--eye must be three finite",
    );
    assert_fails(
        &[&s, "--ortho", "0"],
        &out,
        "orthographic height must be finite and > 0",
    );
    // malformed values are clap's usage errors (exit 2) naming the flag
    for args in [
        ["--eye", "1,2"],
        ["--look-from-side", "under"],
        ["--up-axis", "x"],
    ] {
        let o = run(&["render", &s, "-o", out.to_str().unwrap(), args[0], args[1]]);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(args[0]), "{args:?}: {}", stderr(&o));
        assert!(!out.exists());
    }
}

#[test]
fn ortho_flag_matches_the_toml_orthographic_camera() {
    let dir = temp_dir("camera-ortho");
    let body = "[render]\nwidth = 32\nheight = 24\nspp = 1\nmax_depth = 3\n\n[[generator]]\ntype = \"whitted_room\"\n";
    let plain = dir.join("plain.toml");
    std::fs::write(&plain, body).unwrap();
    let ortho = dir.join("ortho.toml");
    std::fs::write(
        &ortho,
        format!("{body}\n[camera]\neye = [0, 1, 4]\ntarget = [0, 0.5, 0]\nprojection = \"orthographic\"\nheight = 3.3\n"),
    )
    .unwrap();
    let render = |scene: &Path, name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut a = vec![
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--quiet",
        ];
        a.extend_from_slice(extra);
        let o = run(&a);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        std::fs::read(out).unwrap()
    };
    let from_toml = render(&ortho, "t.hdr", &[]);
    let cam = ["--eye", "0,1,4", "--target", "0,0.5,0"];
    let mut flags = cam.to_vec();
    flags.extend_from_slice(&["--ortho", "3.3"]);
    assert!(
        render(&plain, "f.hdr", &flags) == from_toml,
        "--ortho differs from TOML"
    );
    assert!(
        render(&plain, "p.hdr", &cam) != from_toml,
        "perspective looks the same"
    );
}

#[test]
fn bench_triangles_runs_the_procedural_mesh_of_that_size_with_cpu_share_and_memory() {
    let o = run(&[
        "bench",
        "--triangles",
        "3000",
        "--width",
        "32",
        "--height",
        "32",
        "--reps",
        "2",
        "--warmup-ms",
        "0",
        "--threads",
        "1",
        "--modes",
        "scalar-bvh2,bvh8-packet",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = json_lines(&o);
    assert_eq!(rows.len(), 6, "2 modes x 3 workloads");
    for r in &rows {
        // the tessellation's nearest count: within about 2 sqrt(n) above the request
        let n = r["triangles"].as_u64().unwrap();
        assert!((3000..3000 + 2 * 55).contains(&n), "{n} triangles");
        let cpu = r["cpu_util"]
            .as_f64()
            .expect("a CPU clock on this platform");
        // one thread: at most one core's worth (plus clock-read slack), and some
        assert!(cpu > 0.0 && cpu <= 1.05, "cpu share {cpu}");
        let (lo, med, hi) = (
            r["mrays_min"].as_f64().unwrap(),
            r["mrays_median"].as_f64().unwrap(),
            r["mrays_max"].as_f64().unwrap(),
        );
        assert!(lo > 0.0 && lo <= med && med <= hi, "{lo} {med} {hi}");
        let (bmin, bmed, bmax) = (
            r["build_ms_min"].as_f64().unwrap(),
            r["build_ms"].as_f64().unwrap(),
            r["build_ms_max"].as_f64().unwrap(),
        );
        assert!(
            bmin > 0.0 && bmin <= bmed && bmed <= bmax,
            "{bmin} {bmed} {bmax}"
        );
        // a BVH holds at least the triangles' 36 bytes of corners each
        assert!(r["bytes_per_triangle"].as_f64().unwrap() > 36.0, "{r}");
    }
    for w in ["primary", "shadow", "diffuse"] {
        let of: Vec<_> = rows.iter().filter(|r| r["workload"] == w).collect();
        assert_eq!(of[0]["hits_or_occluded"], of[1]["hits_or_occluded"], "{w}");
    }
    assert!(rows[0]["hits_or_occluded"].as_u64().unwrap() > 0);
}

#[test]
fn bench_sweep_reports_every_power_of_ten_up_to_the_limit() {
    let o = run(&[
        "bench",
        "--sweep",
        "--sweep-max",
        "20000",
        "--width",
        "16",
        "--height",
        "16",
        "--reps",
        "1",
        "--warmup-ms",
        "0",
        "--threads",
        "1",
        "--modes",
        "bvh4-packet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let header = out
        .lines()
        .find(|l| l.contains("triangles") && l.contains("bytes/tri") && l.contains("cpu"))
        .expect("a sweep table header");
    assert!(header.contains("build ms"), "{header}");
    // one row per size and workload; sizes 10^3 and 10^4 (10^5 is past the limit)
    let sizes: Vec<u64> = out
        .lines()
        .filter(|l| l.contains("bvh4-packet"))
        .map(|l| l.split_whitespace().next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(sizes.len(), 6, "{out}");
    assert!(
        sizes[..3].iter().all(|&n| (1000..1100).contains(&n)),
        "{sizes:?}"
    );
    assert!(
        sizes[3..].iter().all(|&n| (10000..10300).contains(&n)),
        "{sizes:?}"
    );
}

#[test]
fn bench_rejects_bad_sizes_with_the_flag_named() {
    let o = run(&["bench", "--sweep", "--sweep-max", "500"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("sweep-max"), "{}", stderr(&o));
    let o = run(&["bench", "--triangles", "0", "--width", "8", "--height", "8"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("triangles"), "{}", stderr(&o));
    let o = run(&["bench", "--triangles", "100", "--mesh", "x.obj"]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "clap rejects --triangles with --mesh"
    );
}
