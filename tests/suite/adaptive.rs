//! Progressive, adaptive rendering (docs/progressive.md): unbiased (the mean over many
//! seeds matches a high-sample reference, pixel by pixel), deterministic for a seed
//! whatever the thread count, samples where the error is, and the CLI's
//! `--time-limit` keeps to its limit while writing a valid image every pass.

use crate::common::temp::temp_dir;
use packet_render::accel::{AccelKind, SceneAccel};
use packet_render::film::{Film, luminance};
use packet_render::integrator::adaptive::{self, AdaptiveOptions, AdaptiveOutput};
use packet_render::integrator::{RenderOptions, SamplerKind, recursive};
use packet_render::scene::Scene;
use packet_render::scene::load::load_scene;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

/// A scene with depth of field and an area light (`dof_area.toml`, `product.toml`),
/// 1 shadow ray and 1 lens sample per eye sample.
fn setup_scene(name: &str, size: u32) -> (Scene, SceneAccel, RenderOptions) {
    let scene = load_scene(&scene(name)).unwrap();
    let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
    let mut opts = RenderOptions::from_scene(&scene);
    opts.width = size;
    opts.height = size;
    opts.samples.shadow = 1;
    opts.samples.lens = 1;
    (scene, accel, opts)
}

fn setup(size: u32) -> (Scene, SceneAccel, RenderOptions) {
    setup_scene("dof_area.toml", size)
}

fn budget(mean_spp: f64) -> AdaptiveOptions {
    AdaptiveOptions {
        max_mean_spp: Some(mean_spp),
        ..Default::default()
    }
}

fn run(
    scene: &Scene,
    accel: &SceneAccel,
    opts: &RenderOptions,
    a: &AdaptiveOptions,
) -> AdaptiveOutput {
    adaptive::render(scene, accel, opts, a, Instant::now(), |_, _| Ok(())).unwrap()
}

fn lum(f: &Film) -> Vec<f64> {
    f.pixels.iter().map(|p| luminance(*p) as f64).collect()
}

/// Per pixel, the mean of the adaptive estimate over `S` seeds against a jittered
/// 4096-sample reference: `z_p = (mean_p - ref_p) / (s_p / √S)` with `s_p` the
/// pixels' standard deviation over the seeds. For an unbiased estimator `z_p` is
/// t-distributed (S - 1 dof, E[z²] = (S-1)/(S-3) ≈ 1.07 at S = 32), and the mean of
/// `z²` over the `n` pixels tested has standard deviation about `sqrt(2 / n)`
/// (more with heavy tails); the reference's own noise (4096 stratified samples against
/// the 32 x 8 of the means) adds at most 1/16 to the variance. Tolerance: mean z² <
/// 1.07 * (1 + 1/16) + 5 * sqrt(2 / n). A bias of a fifth of the seeds' standard error
/// in every pixel would not be seen; one of a standard error would (mean z² ≈ 2).
///
/// Which pixels are tested: `s_p / √S` is a standard error only if the seeds' values
/// are spread enough for the mean to be near normal. Pixels where every seed gives the
/// same value (the background; an umbra that every sample sees as umbra) have none and
/// are shown, not tested. So are *rare-event* pixels, where fewer than 4 of the 32
/// seeds differ from the most common value at all: there `s_p` measures the one or
/// two seeds that happened to see the event, not its probability, and the t-statistic
/// is meaningless. The case that made this rule (dof_area, pixel 96, the red sphere's
/// umbra, ambient only: (0.016, 0.003, 0.002)): 31 seeds give exactly that, one gives
/// 0.016038 (one of its 16 samples saw a sliver of the light), and the 4096-sample
/// reference, which sees the sliver more often, is 6.5 % brighter in luminance: z² =
/// 758,199 from an `s_p` of 2.4e-6. A uniform `sobol` render of 16 samples, unbiased
/// by construction, misses it the same way (printed for every rare-event pixel). The
/// old cut, `var > 1e-12`, separated such pixels from the tested ones only by luck. The
/// test asserts that such pixels are few (at most 4 of 144), so that the rule cannot
/// hide a systematic error.
fn check_unbiased(name: &str) {
    let (scene, accel, mut opts) = setup_scene(name, 12);
    let seeds = 32u64;
    let mut values = vec![Vec::new(); 144];
    let mut spread = 0u32;
    for s in 0..seeds {
        opts.seed = 100 + s;
        let out = run(&scene, &accel, &opts, &budget(8.0));
        let (lo, hi) = (
            out.counts.iter().min().unwrap(),
            out.counts.iter().max().unwrap(),
        );
        spread = spread.max(hi - lo);
        for (p, v) in lum(&out.film).into_iter().enumerate() {
            values[p].push(v);
        }
    }
    // The allocation is adaptive: counts differ between pixels.
    assert!(spread >= 8, "{name}: sample counts spread only {spread}");
    let mut r = opts.clone();
    r.sampler = SamplerKind::Jittered;
    r.spp = 4096;
    r.seed = 9;
    let reference = lum(&recursive::render(&scene, &accel, &r).film);
    let n = seeds as f64;
    let mut z2 = Vec::new();
    let (mut constant, mut rare) = (0, Vec::new());
    for (p, v) in values.iter().enumerate() {
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let modal = v
            .iter()
            .map(|a| v.iter().filter(|b| *b == a).count())
            .max()
            .unwrap();
        let deviating = v.len() - modal;
        if deviating == 0 {
            constant += 1;
        } else if deviating < 4 {
            eprintln!(
                "{name}: rare-event pixel {p}: {deviating} of {seeds} seeds differ; mean {mean} vs reference {}",
                reference[p]
            );
            rare.push(p);
        } else {
            z2.push((mean - reference[p]).powi(2) / (var / n));
        }
    }
    if !rare.is_empty() {
        // The same seeds, uniform sobol, 16 samples: misses the rare event alike.
        let mut u = opts.clone();
        u.sampler = SamplerKind::Sobol;
        u.spp = 16;
        let mut sum = vec![0.0f64; 144];
        for s in 0..seeds {
            u.seed = 100 + s;
            for (p, v) in lum(&recursive::render(&scene, &accel, &u).film)
                .into_iter()
                .enumerate()
            {
                sum[p] += v / n;
            }
        }
        for &p in &rare {
            eprintln!(
                "{name}: pixel {p}: uniform sobol 16 spp, mean over the seeds {}",
                sum[p]
            );
        }
    }
    let k = z2.len() as f64;
    let mean_z2 = z2.iter().sum::<f64>() / k;
    let bound = 1.07 * (1.0 + 1.0 / 16.0) + 5.0 * (2.0 / k).sqrt();
    eprintln!(
        "{name}: mean z² {mean_z2:.3} over {k} pixels (bound {bound:.3}), {constant} constant, {} rare-event",
        rare.len()
    );
    assert!(k > 50.0, "{name}: only {k} pixels vary");
    assert!(rare.len() <= 4, "{name}: {} rare-event pixels", rare.len());
    assert!(
        mean_z2 < bound,
        "{name}: mean z² {mean_z2:.3} >= {bound:.3}"
    );
}

#[test]
fn adaptive_estimates_are_unbiased_pixel_by_pixel() {
    check_unbiased("dof_area.toml");
}

#[test]
fn adaptive_estimates_are_unbiased_pixel_by_pixel_on_the_product_shot() {
    check_unbiased("product.toml");
}

/// The pilot's samples are kept: each pilot pass's image is, bit for bit, the image a
/// uniform `sobol` render of that many samples per pixel gives (the same samples,
/// summed in the same order), and after the pilot every pixel has exactly `pilot`
/// samples.
#[test]
fn kept_pilot_passes_equal_uniform_sobol_renders() {
    let (scene, accel, mut opts) = setup_scene("product.toml", 16);
    opts.seed = 3;
    let a = budget(12.0);
    let mut films = Vec::new();
    let out = adaptive::render(&scene, &accel, &opts, &a, Instant::now(), |f, info| {
        films.push((f.clone(), info.clone()));
        Ok(())
    })
    .unwrap();
    assert!(films.len() > a.pilot as usize, "{} passes", films.len());
    for (i, (film, info)) in films.iter().take(a.pilot as usize).enumerate() {
        let mut u = opts.clone();
        u.sampler = SamplerKind::Sobol;
        u.spp = i as u32 + 1;
        let uniform = recursive::render(&scene, &accel, &u).film;
        assert_eq!(info.mean_spp, (i + 1) as f64);
        assert!(info.estimated_error.is_none());
        assert!(
            film == &uniform,
            "pilot pass {i} differs from a uniform {}-sample render",
            i + 1
        );
    }
    // After the pilot the counts move away from uniform, never below the pilot.
    assert!(out.counts.iter().all(|&c| c >= a.pilot));
    assert!(out.counts.iter().any(|&c| c > 12));
}

/// Every pass's image and the counts are a function of the seed: the same with 1
/// and 2 threads; the estimated error falls pass by pass and the render stops at
/// the first pass that reaches the target.
#[test]
fn passes_are_deterministic_and_stop_at_the_target_error() {
    let (scene, accel, mut opts) = setup(16);
    opts.seed = 5;
    let a = AdaptiveOptions {
        target_error: Some(0.02),
        ..Default::default()
    };
    let in_pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut films = Vec::new();
                let out = adaptive::render(&scene, &accel, &opts, &a, Instant::now(), |f, _| {
                    films.push(f.clone());
                    Ok(())
                })
                .unwrap();
                (films, out)
            })
    };
    let (films1, out1) = in_pool(1);
    let (films2, out2) = in_pool(2);
    assert_eq!(films1, films2);
    assert_eq!(out1.counts, out2.counts);
    assert!(films1.len() >= 3, "{} passes", films1.len());
    assert_eq!(films1.last().unwrap(), &out1.film);
    let errors: Vec<f64> = out1
        .passes
        .iter()
        .filter_map(|p| p.estimated_error)
        .collect();
    assert!(errors.windows(2).all(|w| w[1] < w[0]), "{errors:?}");
    let last = *errors.last().unwrap();
    assert!(last <= 0.02, "{errors:?}");
    assert!(errors[errors.len() - 2] > 0.02, "{errors:?}");
    // Each pass's samples are added on top: counts never fall.
    assert!(out1.passes.windows(2).all(|w| w[1].samples > w[0].samples));
}

/// `--time-limit 2` on a slow scene (dof_area at 640 x 480 with 16 shadow points per
/// hit: 7.1 s of wall time for its full sample count, test-profile binary, 2 threads)
/// stops early and writes a complete image, atomically. What is asserted is that the
/// limit ended the render before all samples were drawn; the wall time is printed, not
/// asserted (timings are benchmarks here, not tests: on a loaded 2-core machine pass 0
/// alone took 2.5 s once). The criterion, the image within 2.5 s of wall time, is
/// measured in docs/progressive.md.
#[test]
fn cli_time_limit_writes_an_image_within_the_limit() {
    let dir = temp_dir("time-limit");
    let out = dir.join("progressive.png");
    let s = scene("dof_area.toml").display().to_string();
    let t = Instant::now();
    let o = crate::common::bin::run(&[
        "render",
        &s,
        "-o",
        out.to_str().unwrap(),
        "--width",
        "640",
        "--height",
        "480",
        "--shadow-samples",
        "16",
        "--time-limit",
        "2",
    ]);
    let wall = t.elapsed();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    eprintln!("--time-limit 2: {wall:?} of wall time");
    assert!(stderr.contains("pass   0"), "{stderr}");
    // The summary's "mean X spp" (the last on stderr): stopped by the limit, short of
    // the scene's 16 samples per pixel.
    let mean_spp: f64 = stderr
        .split("mean ")
        .last()
        .and_then(|r| r.split(" spp").next())
        .and_then(|x| x.trim().parse().ok())
        .unwrap_or_else(|| panic!("no mean spp in {stderr}"));
    assert!(
        mean_spp < 16.0,
        "the limit did not stop the render: {stderr}"
    );
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (640, 480));
    // No temporary file left next to the image.
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(names.len(), 1, "{names:?}");

    // Bad input: clear errors, nothing written.
    for (args, needle) in [
        (
            vec!["--time-limit", "0"],
            "time-limit must be a positive number",
        ),
        (vec!["--time-limit", "1", "--sampler", "jittered"], "sobol"),
        (
            vec!["--target-error", "nan"],
            "target-error must be a positive number",
        ),
    ] {
        let bad = dir.join("bad.png");
        let mut all = vec![
            "render",
            &s,
            "-o",
            bad.to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
        ];
        all.extend(args);
        let o = crate::common::bin::run(&all);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert!(stderr.contains(needle), "{stderr}");
        assert!(!bad.exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}
