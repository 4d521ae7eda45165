//! Distributed rendering (docs/distributed.md): frames rendered in parts (pixel
//! regions, sample rounds, both) and merged are bit for bit the frame one process
//! renders, with either integrator and any thread count; merge refuses parts that
//! overlap, leave pixels or samples out, come from another setup, or are corrupt.

use crate::common::bin::run;
use crate::common::temp::temp_dir;
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::film::merge::merge;
use packet_render::film::partial::{PartialHeader, PartialImage};
use packet_render::film::{Film, merge::merge_files};
use packet_render::integrator::{
    FilterKind, IntegratorKind, PixelBounds, RenderOptions, SamplerKind,
};
use packet_render::scene::Scene;
use packet_render::scene::load::load_scene;
use std::ops::Range;
use std::path::{Path, PathBuf};

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

/// Depth of field, an area light, the Gaussian filter (footprint wider than a pixel)
/// and a stratified pattern whose positions depend on the total spp: everything a
/// part could get wrong. 37x29 so that regions cut render tiles (16 px) unevenly.
fn setup(spp: u32) -> (Scene, RenderOptions) {
    let scene = load_scene(&scene("dof_area.toml")).unwrap();
    let mut opts = RenderOptions::from_scene(&scene);
    opts.width = 37;
    opts.height = 29;
    opts.spp = spp;
    opts.seed = 11;
    opts.samples.shadow = 2;
    opts.samples.lens = 2;
    opts.sampler = SamplerKind::Jittered;
    opts.filter = FilterKind::Gaussian;
    (scene, opts)
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// One part rendered through the library, as `render -o X.partial` does.
fn part(
    scene: &Scene,
    accel: &SceneAccel,
    integrator: IntegratorKind,
    opts: &RenderOptions,
    crop: Option<PixelBounds>,
    samples: Option<Range<u32>>,
) -> PartialImage {
    let mut o = opts.clone();
    o.crop = crop;
    o.sample_range = samples.clone();
    o.keep_sums = true;
    o.validate().unwrap();
    let out = integrator.render(scene, accel, &o);
    assert_eq!(
        (out.film.width, out.film.height),
        (out.region.width(), out.region.height())
    );
    PartialImage {
        header: PartialHeader {
            width: o.width,
            height: o.height,
            bounds: out.region,
            samples: samples.unwrap_or(0..o.spp),
            spp: o.spp,
            seed: o.seed,
            fingerprint: 42,
            description: "test".into(),
        },
        pixels: out.sums.unwrap(),
    }
}

/// A part: pixels (`None`: all) and eye samples (`None`: all).
type PartSpec = (Option<PixelBounds>, Option<Range<u32>>);

fn names(n: usize) -> Vec<PathBuf> {
    (0..n).map(|i| PathBuf::from(format!("part{i}"))).collect()
}

fn assert_bit_equal(a: &Film, b: &Film, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}");
    for (i, (p, q)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        assert_eq!(
            p.to_array().map(f32::to_bits),
            q.to_array().map(f32::to_bits),
            "{what}: pixel {i}: {p} vs {q}"
        );
    }
}

#[test]
fn regions_and_rounds_merge_into_the_single_render_bit_for_bit() {
    let (scene, opts) = setup(6);
    let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
    let (w, h) = (opts.width, opts.height);
    let crop = |s: &str| Some(PixelBounds::parse(s).unwrap());
    // Bands (--tile), arbitrary rectangles that cut render tiles (--crop), sample
    // rounds (--sample-range), and rectangles and rounds mixed.
    let splits: Vec<(&str, Vec<PartSpec>)> = vec![
        (
            "3 bands",
            (0..3)
                .map(|i| (Some(PixelBounds::tile(i, 3, w, h).unwrap()), None))
                .collect(),
        ),
        (
            "3 rectangles",
            vec![
                (crop("0,13,0,29"), None),
                (crop("13,37,0,10"), None),
                (crop("13,37,10,29"), None),
            ],
        ),
        (
            "3 rounds",
            vec![(None, Some(0..1)), (None, Some(1..4)), (None, Some(4..6))],
        ),
        (
            "rectangles and rounds",
            vec![
                (crop("0,37,0,17"), Some(0..2)),
                (crop("0,20,0,17"), Some(2..6)),
                (crop("20,37,0,17"), Some(2..6)),
                (crop("0,37,17,29"), None),
            ],
        ),
    ];
    for integrator in [IntegratorKind::Whitted, IntegratorKind::Wavefront] {
        // The single render at one thread, the parts at three: threads must not matter.
        let full = in_pool(1, || integrator.render(&scene, &accel, &opts).film);
        for (what, split) in &splits {
            let parts: Vec<PartialImage> = in_pool(3, || {
                split
                    .iter()
                    .map(|(c, s)| part(&scene, &accel, integrator, &opts, *c, s.clone()))
                    .collect()
            });
            let merged = merge(&names(parts.len()), &parts).unwrap();
            assert_bit_equal(&merged.film, &full, &format!("{integrator}, {what}"));
            // A cropped render's own image is the same pixels of the frame.
            if let (Some(c), None) = &split[0] {
                let out = integrator.render(&scene, &accel, &{
                    let mut o = opts.clone();
                    o.crop = Some(*c);
                    o
                });
                for y in c.y0..c.y1 {
                    for x in c.x0..c.x1 {
                        assert_eq!(out.film.get(x - c.x0, y - c.y0), full.get(x, y));
                    }
                }
            }
        }
        // The merged sums equal the sums of a single render kept as a partial image.
        let whole = part(&scene, &accel, integrator, &opts, None, None);
        let parts: Vec<PartialImage> = (0..3)
            .map(|i| {
                let band = PixelBounds::tile(i, 3, w, h).unwrap();
                part(&scene, &accel, integrator, &opts, Some(band), Some(0..6))
            })
            .collect();
        assert_eq!(merge(&names(3), &parts).unwrap().partial, whole);
    }
}

#[test]
fn merge_refuses_bad_sets_of_parts_naming_the_files() {
    let (scene, opts) = setup(4);
    let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
    let wf = IntegratorKind::Wavefront;
    let crop = |s: &str| Some(PixelBounds::parse(s).unwrap());
    let top = part(&scene, &accel, wf, &opts, crop("0,37,0,15"), None);
    let bottom = part(&scene, &accel, wf, &opts, crop("0,37,15,29"), None);
    let refused =
        |parts: Vec<PartialImage>| merge(&names(parts.len()), &parts).unwrap_err().to_string();
    assert!(merge(&names(2), &[top.clone(), bottom.clone()]).is_ok());

    let e = refused(vec![
        top.clone(),
        part(&scene, &accel, wf, &opts, crop("0,37,14,29"), None),
    ]);
    assert!(
        e.contains("part0") && e.contains("part1") && e.contains("overlap"),
        "{e}"
    );
    let e = refused(vec![top.clone()]);
    assert!(e.contains("missing") && e.contains("pixel (0, 15)"), "{e}");
    // Rounds of the bottom band that are not contiguous: 0..1 and 2..4.
    let e = refused(vec![
        top.clone(),
        part(&scene, &accel, wf, &opts, crop("0,37,15,29"), Some(0..1)),
        part(&scene, &accel, wf, &opts, crop("0,37,15,29"), Some(2..4)),
    ]);
    assert!(
        e.contains("lacks samples 1..2 of 0..4") && e.contains("part2"),
        "{e}"
    );
    // Rounds that overlap in samples.
    let e = refused(vec![
        top.clone(),
        part(&scene, &accel, wf, &opts, crop("0,37,15,29"), Some(0..3)),
        part(&scene, &accel, wf, &opts, crop("0,37,15,29"), Some(2..4)),
    ]);
    assert!(
        e.contains("part1") && e.contains("part2") && e.contains("overlap"),
        "{e}"
    );
    // Another setup: seed, size, spp, scene or options.
    let changed = |f: &dyn Fn(&mut PartialHeader)| {
        let mut b = bottom.clone();
        f(&mut b.header);
        refused(vec![top.clone(), b])
    };
    assert!(changed(&|h| h.seed = 12).contains("seed 11 vs 12"));
    assert!(changed(&|h| h.spp = 8).contains("spp 4 vs 8"));
    assert!(changed(&|h| h.height = 30).contains("image size 37x29 vs 37x30"));
    let e = changed(&|h| {
        h.fingerprint = 43;
        h.description = "other".into();
    });
    assert!(
        e.contains("scene or options differ") && e.contains("other"),
        "{e}"
    );
    assert!(refused(vec![]).contains("no parts"));
}

/// The commands a scheduler's tasks run: `render --tile I/N --sample-range` to
/// `.partial` files, then `merge`. The merged sums are byte for byte those of one
/// `render -o full.partial`, and the merged PNG is that render's PNG.
#[test]
fn cli_tiles_and_rounds_merge_to_the_single_render() {
    let dir = temp_dir("cli");
    let s = scene("dof_area.toml").display().to_string();
    let common = [
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "4",
        "--quiet",
        "--threads",
        "2",
    ];
    let render = |out: &Path, extra: &[&str]| {
        let mut args = vec!["render", &s, "-o", out.to_str().unwrap()];
        args.extend_from_slice(&common);
        if !extra.contains(&"--seed") {
            args.extend_from_slice(&["--seed", "5"]);
        }
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    render(&dir.join("full.partial"), &[]);
    render(&dir.join("full.png"), &[]);
    let mut parts = Vec::new();
    for i in 0..3 {
        for (k, r) in ["0..1", "1..4"].iter().enumerate() {
            let p = dir.join(format!("t{i}r{k}.partial"));
            render(&p, &["--tile", &format!("{i}/3"), "--sample-range", r]);
            parts.push(p.display().to_string());
        }
    }
    for out in ["merged.partial", "merged.png"] {
        let mut args = vec!["merge".to_string()];
        args.extend(parts.iter().cloned());
        args.extend(["-o".into(), dir.join(out).display().to_string()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let read = |n: &str| std::fs::read(dir.join(n)).unwrap();
    assert!(
        read("full.partial") == read("merged.partial"),
        "merged sums differ"
    );
    assert!(read("full.png") == read("merged.png"), "merged PNG differs");
    // The library's reader agrees.
    let merged = merge_files(&[dir.join("merged.partial")]).unwrap();
    assert_eq!((merged.film.width, merged.film.height), (40, 30));

    // Refusals exit non-zero, name the file, and write nothing.
    let refused = |args: &[&str], needle: &str| {
        let o = run(args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(
            !o.status.success() && err.contains(needle),
            "{args:?}: {err}"
        );
        assert!(!dir.join("bad.png").exists());
    };
    let bad = dir.join("bad.png").display().to_string();
    refused(
        &["merge", &parts[0], &parts[1], "-o", &bad],
        "missing parts",
    );
    let corrupt = dir.join("corrupt.partial");
    let mut bytes = read("t0r0.partial");
    bytes.truncate(bytes.len() / 2);
    std::fs::write(&corrupt, bytes).unwrap();
    let c = corrupt.display().to_string();
    refused(
        &["merge", &c, "-o", &bad],
        "corrupt.partial: corrupt or truncated",
    );
    std::fs::write(&corrupt, b"P6\n1 1\n255\n...").unwrap();
    refused(&["merge", &c, "-o", &bad], "bad magic");
    refused(
        &["merge", "/nonexistent/x.partial", "-o", &bad],
        "/nonexistent/x.partial",
    );
    let seed6 = dir.join("seed6.partial");
    render(&seed6, &["--tile", "2/3", "--seed", "6"]);
    refused(
        &[
            "merge",
            &parts[0],
            &parts[1],
            &parts[2],
            &parts[3],
            &seed6.display().to_string(),
            "-o",
            &bad,
        ],
        "seed 5 vs 6",
    );
    let other = dir.join("other.partial");
    render(&other, &["--tile", "2/3", "--max-depth", "1"]);
    refused(
        &[
            "merge",
            &parts[0],
            &parts[1],
            &parts[2],
            &parts[3],
            &other.display().to_string(),
            "-o",
            &bad,
        ],
        "scene or options differ",
    );
    // Bad part arguments are refused before rendering.
    let png = dir.join("x.png").display().to_string();
    let bad_render = |extra: &[&str], needle: &str| {
        let mut args = vec!["render", &s, "-o", &png];
        args.extend_from_slice(&common);
        args.extend_from_slice(extra);
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(
            !o.status.success() && err.contains(needle),
            "{extra:?}: {err}"
        );
    };
    bad_render(&["--crop", "0,41,0,30"], "not inside the 40x30 image");
    bad_render(&["--tile", "3/3"], "need 0 <= I < N");
    bad_render(&["--sample-range", "2..5"], "need a < b <= spp (4)");
    bad_render(&["--crop", "0,4,0,4", "--tile", "0/2"], "not both");
    bad_render(&["--sample-range", "3..3"], "expected a..b");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The film's shortcuts give the bits of the exact sums. Without `keep_sums` a tile
/// resolves each pixel straight into its value: at 1 ray per pixel without building
/// any sums (`PixelSums::one_sample_value`), with more on the stack; with `keep_sums`
/// every pixel goes through kept sums, the general path (and the partial image they
/// encode, merged alone, gives the same frame again). Real renders of shipped scenes,
/// both integrators, both filters, 1 and 4 eye samples, lens samples, pixel for pixel,
/// at a size (37x29) whose tiles are cut at the right and bottom edges.
#[test]
fn the_film_shortcuts_give_the_frame_of_the_kept_sums_pixel_for_pixel() {
    let mut cases = 0;
    for name in ["whitted.toml", "dof_area.toml", "cornell.toml"] {
        let scene = load_scene(&scene(name)).unwrap();
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        for (spp, lens, filter) in [
            (1, 1, FilterKind::Box),
            (1, 1, FilterKind::Gaussian),
            (4, 1, FilterKind::Box),
            (1, 3, FilterKind::Gaussian),
        ] {
            let mut opts = RenderOptions::from_scene(&scene);
            (opts.width, opts.height, opts.spp) = (37, 29, spp);
            opts.samples.lens = lens;
            opts.filter = filter;
            opts.validate().unwrap();
            for integrator in [IntegratorKind::Wavefront, IntegratorKind::Whitted] {
                let what = format!("{name} spp {spp} lens {lens} {filter} {integrator:?}");
                let fast = integrator.render(&scene, &accel, &opts);
                assert!(fast.sums.is_none(), "{what}");
                let kept = part(&scene, &accel, integrator, &opts, None, None);
                let mut o = opts.clone();
                o.keep_sums = true;
                let general = integrator.render(&scene, &accel, &o);
                assert_bit_equal(&fast.film, &general.film, &what);
                let merged = merge(&names(1), &[kept]).unwrap();
                assert_bit_equal(&fast.film, &merged.film, &what);
                assert_eq!(fast.nonfinite_samples, general.nonfinite_samples, "{what}");
                // Not a black frame: the comparison compares something.
                assert!(fast.film.mean().max_element() > 0.01, "{what}");
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 3 * 4 * 2);
}
