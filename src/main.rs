//! `packet-render`: argument parsing and dispatch, nothing else (the work lives in the
//! library so that tests and other front ends share it).

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use packet_render::accel::AccelKind;
use packet_render::film::write_atomic;
use packet_render::job::{Overrides, Progress, RenderJob};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(
    name = "packet-render",
    version,
    about = "A data-oriented CPU ray tracer"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.toml) or a mesh (.obj or .ply, framed automatically) to an image
    /// (.png; .hdr or .exr for linear float; .partial for a part that `merge` assembles).
    Render(RenderArgs),
    /// Time the ray-throughput protocol of shared/BENCHMARK.md (Mrays/s for primary,
    /// shadow and diffuse rays) for each tracing mode, at 1 thread and all cores.
    Bench(BenchArgs),
    /// Error against run time (Cook et al. 1984): a high-sample reference, then each
    /// sample pattern and eye/shadow split at a series of budgets; prints the table and
    /// the fitted log-log slopes, writes a CSV and an SVG plot.
    Converge(ConvergeArgs),
    /// Every acceleration structure side by side on one scene (.toml) or mesh (.obj):
    /// build time, memory, size, traversal work per primary ray, and Mrays/s of the
    /// BENCHMARK.md workloads traced one ray at a time.
    AccelCompare(AccelCompareArgs),
    /// The lecture's table: build + render time of every structure on sphereflakes of
    /// 10 to 66430 spheres, as ratios to the time at 10, with CSV and log-log SVG.
    LectureTable(LectureTableArgs),
    /// Assemble partial images (`render ... -o X.partial` with --crop, --tile or
    /// --sample-range) into the frame; refuses overlapping, missing or mismatched parts.
    Merge(MergeArgs),
    /// Error of the f32 intersection kernels against an f64 reference (scales 1e-6..1e6,
    /// offsets up to 1e7, grazing rays, tiny primitives).
    Precision {
        /// Rays per case.
        #[arg(long, default_value_t = 2000)]
        rays: usize,
        /// Print one JSON object per line instead of the table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(clap::Args)]
struct MergeArgs {
    /// Partial images (.partial).
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output: .png, .hdr, or .partial (the merged sums, for a merge of merges).
    #[arg(short, long)]
    output: PathBuf,
}

/// Distributed rendering (docs/distributed.md): which part of the frame to render.
#[derive(clap::Args)]
struct PartArgs {
    /// Render only the pixels x0 <= x < x1, y0 <= y < y1 (as pbrt's --pixelbounds).
    #[arg(long, value_name = "x0,x1,y0,y1", value_parser = parse_crop)]
    crop: Option<packet_render::integrator::PixelBounds>,
    /// Render only the I-th (0-based) of N balanced bands of rows.
    #[arg(long, value_name = "I/N", value_parser = parse_tile)]
    tile: Option<(u32, u32)>,
    /// Render only eye samples a <= s < b of each pixel's spp.
    #[arg(long, value_name = "a..b", value_parser = parse_sample_range)]
    sample_range: Option<std::ops::Range<u32>>,
}

fn parse_crop(s: &str) -> Result<packet_render::integrator::PixelBounds, String> {
    packet_render::integrator::PixelBounds::parse(s).map_err(|e| e.to_string())
}

fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    packet_render::integrator::region::parse_tile(s).map_err(|e| e.to_string())
}

fn parse_sample_range(s: &str) -> Result<std::ops::Range<u32>, String> {
    packet_render::integrator::region::parse_sample_range(s).map_err(|e| e.to_string())
}

#[derive(clap::Args)]
struct ConvergeArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    #[arg(long, default_value_t = 64)]
    width: u32,
    #[arg(long, default_value_t = 64)]
    height: u32,
    /// Reference eye samples (jittered).
    #[arg(long, default_value_t = 1024)]
    reference_eye: u32,
    /// Reference shadow samples per area light.
    #[arg(long, default_value_t = 16)]
    reference_shadow: u32,
    /// Sample budgets (eye x shadow per pixel), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1u32, 4, 16, 64])]
    budgets: Vec<u32>,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads; 0 = all cores; at most 1024.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// CSV of every render.
    #[arg(long, default_value = "convergence.csv")]
    csv: PathBuf,
    /// SVG plot, log-log display RMSE (clamped, sRGB) against seconds.
    #[arg(long, default_value = "convergence.svg")]
    plot: PathBuf,
    /// Acceleration structure.
    #[arg(long, default_value = "bvh4", value_parser = parse_accel)]
    accel: AccelKind,
    /// Renders per measurement, the fastest one's seconds reported.
    #[arg(long, default_value_t = 1)]
    reps: u32,
    /// Sample patterns measured with all samples on the eye (`B x 1`), comma-separated
    /// (default: all of them).
    #[arg(long, value_delimiter = ',', value_parser = parse_sampler)]
    samplers: Option<Vec<packet_render::integrator::SamplerKind>>,
    /// Leave out the eye/shadow splits (`jittered 1xB`, `jittered √Bx√B`).
    #[arg(long)]
    no_splits: bool,
}

#[derive(clap::Args)]
struct AccelCompareArgs {
    /// A TOML scene or an OBJ mesh.
    scene: PathBuf,
    #[arg(long, default_value_t = 256)]
    width: u32,
    #[arg(long, default_value_t = 256)]
    height: u32,
    /// Timed passes per workload (after one warm-up); the median is reported.
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Include brute force above 5000 primitives.
    #[arg(long)]
    include_bruteforce: bool,
    /// Print one JSON object per line instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct LectureTableArgs {
    #[arg(long, default_value_t = 128)]
    width: u32,
    #[arg(long, default_value_t = 128)]
    height: u32,
    /// Timed renders per figure; the fastest is kept.
    #[arg(long, default_value_t = 2)]
    reps: usize,
    /// Brute force is extrapolated linearly once its predicted time exceeds this.
    #[arg(long, default_value_t = 5.0)]
    cap_seconds: f64,
    /// Write the table as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Write a log-log plot of time against sphere count (SVG).
    #[arg(long)]
    svg: Option<PathBuf>,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// OBJ mesh (default: the procedural Bunny-scale mesh, 69,696 triangles: the tessellation nearest the Bunny's 69,451).
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// The procedural mesh (a bumpy sphere) with about this many triangles instead.
    #[arg(long, conflicts_with = "mesh")]
    triangles: Option<usize>,
    /// Run on procedural meshes of 10^3, 10^4, ... triangles up to --sweep-max, one
    /// table with build time and bytes per triangle per size.
    #[arg(long, conflicts_with_all = ["mesh", "triangles"])]
    sweep: bool,
    /// Largest mesh of --sweep, in triangles.
    #[arg(long, default_value_t = packet_render::bench::sweep::SWEEP_MAX_TRIANGLES, requires = "sweep")]
    sweep_max: usize,
    /// Untimed warm-up before each figure, in ms (at least one pass).
    #[arg(long, default_value_t = 300.0)]
    warmup_ms: f64,
    /// Repeat a figure up to this many more times while the process got less than 98 %
    /// of its cores (other load), keeping the attempt with the highest share.
    #[arg(long, default_value_t = 0)]
    retry_busy: usize,
    /// Tracing modes, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = packet_render::bench::MODES.iter().map(|s| s.to_string()))]
    modes: Vec<String>,
    /// Thread counts, comma-separated; 0 = all cores.
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 0])]
    threads: Vec<usize>,
    /// Timed passes per figure (after one warm-up); the median is reported.
    #[arg(long, default_value_t = 7)]
    reps: usize,
    #[arg(long, default_value_t = 1024)]
    width: u32,
    #[arg(long, default_value_t = 1024)]
    height: u32,
    /// Print one JSON object per line instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Scene file: a TOML scene (see scenes/README.md) or an OBJ mesh.
    scene: PathBuf,
    /// Output image: .png (8-bit sRGB), .hdr (Radiance, linear), .exr (OpenEXR, linear
    /// float), or .partial (exact pixel sums for `merge`).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    part: PartArgs,
    #[command(flatten)]
    image: ImageArgs,
    /// Image width in pixels (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel (default: the scene's).
    #[arg(long)]
    spp: Option<u32>,
    /// Maximum recursion depth for reflection and refraction (default: the scene's).
    #[arg(long)]
    max_depth: Option<u32>,
    /// Shadow rays through glass attenuated by its transmission (`true`, the default
    /// unless the scene says otherwise) or blocked (`false`).
    #[arg(long)]
    transmitted_shadows: Option<bool>,
    #[command(flatten)]
    sampling: SamplingArgs,
    #[command(flatten)]
    camera: CameraArgs,
    /// Worker threads; 0 = all cores; at most 1024.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Acceleration structure.
    #[arg(long, default_value = "bvh4", value_parser = parse_accel)]
    accel: AccelKind,
    /// Integrator: `whitted` (recursive reference) or `wavefront` (ray queues, packets).
    #[arg(long, default_value = "wavefront", value_parser = parse_integrator)]
    integrator: packet_render::integrator::IntegratorKind,
    /// Seed of the per-pixel random streams (same seed, same image, any thread count).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also write the stats as JSON to this file.
    #[arg(long)]
    stats_json: Option<PathBuf>,
    /// No progress bar and no stats block.
    #[arg(short, long)]
    quiet: bool,
    #[command(flatten)]
    progressive: ProgressiveArgs,
}

/// Progressive, adaptive rendering (docs/progressive.md): passes until a limit, the
/// image rewritten after each.
#[derive(clap::Args)]
struct ProgressiveArgs {
    /// Render in passes, adding samples where the estimated error is largest, and stop
    /// before a pass that would end later than this many seconds after the start.
    #[arg(long, value_name = "SECONDS")]
    time_limit: Option<f64>,
    /// Render in passes until the estimated display RMSE is at most this.
    #[arg(long, value_name = "E")]
    target_error: Option<f64>,
}

/// How the image file is written: exposure and tone mapping for PNG, precision for EXR.
#[derive(clap::Args)]
struct ImageArgs {
    /// Exposure in stops (radiance times 2^STOPS) before tone mapping; PNG only, never
    /// applied to .hdr or .exr.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Tone mapping for PNG: clamp, reinhard (c / (1 + c)) or filmic (ACES-like).
    #[arg(long, default_value = "clamp")]
    tonemap: packet_render::film::ToneMap,
    /// Write .exr channels as 16-bit half floats (default: 32-bit float).
    #[arg(long)]
    exr_half: bool,
    /// Add depth (`depth.Z`), normal (`normal.X/Y/Z`) and albedo (`albedo.R/G/B`)
    /// layers to the .exr output, from one centre ray per pixel.
    #[arg(long)]
    aovs: bool,
}

impl ImageArgs {
    fn options(&self) -> packet_render::film::ImageOptions {
        packet_render::film::ImageOptions {
            exposure: self.exposure,
            tonemap: self.tonemap,
            exr_half: self.exr_half,
            aovs: self.aovs,
        }
    }
}

/// Distribution ray tracing: sample patterns, filter and per-effect sample counts
/// (`--spp` is the eye count).
#[derive(clap::Args)]
struct SamplingArgs {
    /// Sample pattern for pixel, lens, time, light and glossy sets.
    #[arg(long, value_parser = parse_sampler)]
    sampler: Option<packet_render::integrator::SamplerKind>,
    /// Pixel reconstruction filter.
    #[arg(long, value_parser = parse_filter)]
    filter: Option<packet_render::integrator::FilterKind>,
    /// Points per area light per shading point (default: the scene's).
    #[arg(long)]
    shadow_samples: Option<u32>,
    /// Rays per glossy/translucent lobe at first hits (default: the scene's).
    #[arg(long)]
    glossy_samples: Option<u32>,
    /// Lens points per eye sample (default: the scene's).
    #[arg(long)]
    lens_samples: Option<u32>,
    /// Shutter times per lens sample (default: the scene's).
    #[arg(long)]
    time_samples: Option<u32>,
    /// Directions towards the environment per lit shading point (default: the scene's).
    #[arg(long)]
    environment_samples: Option<u32>,
}

/// Camera flags (README.md, "Camera from the command line"): replace the scene's camera
/// or parts of it.
#[derive(clap::Args)]
struct CameraArgs {
    /// Eye position (replaces the scene camera's `eye`).
    #[arg(long, value_name = "x,y,z", value_parser = packet_render::scene::parse_vec3, allow_hyphen_values = true)]
    eye: Option<glam::Vec3>,
    /// Point looked at (replaces `target`).
    #[arg(long, value_name = "x,y,z", value_parser = packet_render::scene::parse_vec3, allow_hyphen_values = true)]
    target: Option<glam::Vec3>,
    /// Up direction (replaces `up`).
    #[arg(long, value_name = "x,y,z", value_parser = packet_render::scene::parse_vec3, allow_hyphen_values = true)]
    up: Option<glam::Vec3>,
    /// Vertical field of view in degrees, 0 < fov < 180 (replaces `fov`).
    #[arg(long, value_name = "DEG", value_parser = parse_f32_like_toml)]
    fov: Option<f32>,
    /// The model's up axis, `y` or `z` (Z-up scans): re-frames the camera around the
    /// scene bounds with that axis up.
    #[arg(long, value_parser = parse_up_axis)]
    up_axis: Option<packet_render::scene::UpAxis>,
    /// Re-frame the camera around the scene bounds, looking from this side:
    /// front, back, left, right or top.
    #[arg(long, value_name = "SIDE", value_parser = parse_side)]
    look_from_side: Option<packet_render::scene::Side>,
    /// Orthographic camera with this image height in world units (TOML `projection =
    /// "orthographic"`, `height`).
    #[arg(long, value_name = "HEIGHT", value_parser = parse_f32_like_toml)]
    ortho: Option<f32>,
}

impl CameraArgs {
    fn overrides(&self) -> packet_render::scene::CameraOverrides {
        packet_render::scene::CameraOverrides {
            eye: self.eye,
            target: self.target,
            up: self.up,
            fov: self.fov,
            up_axis: self.up_axis,
            side: self.look_from_side,
            ortho: self.ortho,
        }
    }
}

/// A number read as `f64` and rounded to `f32`, as the TOML loader reads one.
fn parse_f32_like_toml(s: &str) -> Result<f32, String> {
    s.trim()
        .parse::<f64>()
        .map(|x| x as f32)
        .map_err(|_| format!("`{s}` is not a number"))
}

fn parse_up_axis(s: &str) -> Result<packet_render::scene::UpAxis, String> {
    s.parse()
}

fn parse_side(s: &str) -> Result<packet_render::scene::Side, String> {
    s.parse()
}

fn parse_sampler(s: &str) -> Result<packet_render::integrator::SamplerKind, String> {
    s.parse().map_err(|e: packet_render::Error| e.to_string())
}

fn parse_filter(s: &str) -> Result<packet_render::integrator::FilterKind, String> {
    s.parse().map_err(|e: packet_render::Error| e.to_string())
}

fn parse_integrator(s: &str) -> Result<packet_render::integrator::IntegratorKind, String> {
    s.parse().map_err(|e: packet_render::Error| e.to_string())
}

fn parse_accel(s: &str) -> Result<AccelKind, String> {
    s.parse().map_err(|e: packet_render::Error| e.to_string())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = packet_render::film::install_interrupt_handler() {
        eprintln!("warning: {e}");
    }
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Bench(args) => bench(args),
        Command::Converge(args) => converge(args),
        Command::AccelCompare(args) => accel_compare(args),
        Command::LectureTable(args) => lecture_table(args),
        Command::Merge(args) => merge(args),
        Command::Precision { rays, json } => {
            precision(rays, json);
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn render(args: RenderArgs) -> packet_render::Result<()> {
    let start = Instant::now();
    let job = RenderJob {
        scene: args.scene,
        output: args.output,
        overrides: Overrides {
            width: args.width,
            height: args.height,
            spp: args.spp,
            max_depth: args.max_depth,
            shadow_samples: args.sampling.shadow_samples,
            glossy_samples: args.sampling.glossy_samples,
            lens_samples: args.sampling.lens_samples,
            time_samples: args.sampling.time_samples,
            environment_samples: args.sampling.environment_samples,
            sampler: args.sampling.sampler,
            filter: args.sampling.filter,
            transmitted_shadows: args.transmitted_shadows,
            camera: args.camera.overrides(),
        },
        accel: args.accel,
        integrator: args.integrator,
        seed: args.seed,
        threads: args.threads,
        part: packet_render::job::Part {
            crop: args.part.crop,
            tile: args.part.tile,
            sample_range: args.part.sample_range,
        },
        extra_outputs: args.stats_json.iter().cloned().collect(),
        image: args.image.options(),
    };
    if args.progressive.time_limit.is_some() || args.progressive.target_error.is_some() {
        return render_progressive(&job, &args.progressive, args.quiet, args.stats_json, start);
    }
    let bar = (!args.quiet).then(progress_bar);
    let report = job.run(bar.as_ref().map(|(_, p)| p.clone()))?;
    if let Some((bar, _)) = bar {
        bar.finish_and_clear();
    }
    if !args.quiet {
        eprint!("{}", report.summary());
    }
    if let Some(path) = args.stats_json {
        let json = serde_json::to_string_pretty(&report).expect("report serialises");
        write_atomic(&path, |out| {
            out.write_all(json.as_bytes())
                .map_err(|e| packet_render::Error::io(&path, e))
        })?;
    }
    Ok(())
}

fn render_progressive(
    job: &RenderJob,
    p: &ProgressiveArgs,
    quiet: bool,
    stats_json: Option<PathBuf>,
    start: Instant,
) -> packet_render::Result<()> {
    let a = packet_render::integrator::adaptive::AdaptiveOptions {
        time_limit: p.time_limit,
        target_error: p.target_error,
        ..Default::default()
    };
    let report = packet_render::progressive::run(job, &a, start, |p| {
        if !quiet {
            eprintln!(
                "pass {:>3}: {:.2} s, mean {:.1} spp, estimated display RMSE {}",
                p.pass,
                p.seconds,
                p.mean_spp,
                p.estimated_error.map_or("-".into(), |e| format!("{e:.5}"))
            );
        }
    })?;
    if !quiet {
        eprint!("{}", report.summary());
    }
    if let Some(path) = &stats_json {
        let json = serde_json::to_string_pretty(&report).expect("report serialises");
        write_atomic(path, |out| {
            out.write_all(json.as_bytes())
                .map_err(|e| packet_render::Error::io(path, e))
        })?;
    }
    Ok(())
}

fn merge(args: MergeArgs) -> packet_render::Result<()> {
    use packet_render::film::{merge, partial};
    if !partial::is_partial_path(&args.output) {
        packet_render::film::check_image_path(&args.output)?;
    }
    let merged = merge::merge_files(&args.parts)?;
    if partial::is_partial_path(&args.output) {
        merged.partial.save(&args.output)
    } else {
        merged.film.save(&args.output)
    }
}

fn bench(args: BenchArgs) -> packet_render::Result<()> {
    use packet_render::bench;
    let opts = bench::BenchOptions {
        modes: args.modes,
        threads: args.threads,
        reps: args.reps,
        width: args.width,
        height: args.height,
        warmup_s: args.warmup_ms * 1e-3,
        retry_busy: args.retry_busy,
    };
    let preamble = |what: String| {
        println!(
            "{what}; {}x{}; kernels built for {}, {}-ray packets; {} timed passes after {} ms of warm-up, median",
            opts.width,
            opts.height,
            bench::instruction_set(),
            packet_render::simd::PACKET_WIDTH,
            opts.reps,
            args.warmup_ms
        )
    };
    let print = |row: &bench::BenchRow, table: fn(&bench::BenchRow) -> String| {
        if args.json {
            println!("{}", serde_json::to_string(row).expect("row serialises"));
        } else {
            println!("{}", table(row));
        }
    };
    if args.sweep {
        let sizes = bench::sweep::sweep_sizes(args.sweep_max)?;
        if !args.json {
            preamble(format!(
                "sweep over the procedural mesh: {} to {} triangles",
                sizes[0],
                sizes[sizes.len() - 1]
            ));
            println!("{}", bench::sweep_table_header());
        }
        bench::sweep::run_sweep(
            args.sweep_max,
            &opts,
            |_| {},
            |row| print(row, bench::sweep_table_row),
        )?;
        return Ok(());
    }
    let mesh = match (&args.mesh, args.triangles) {
        (Some(p), _) => bench::BenchMesh::from_obj(p)?,
        (None, Some(n)) => {
            bench::sweep::check_triangles("triangles", n)?;
            bench::BenchMesh::procedural(n)
        }
        (None, None) => bench::BenchMesh::procedural(bench::DEFAULT_MESH_TRIANGLES),
    };
    if !args.json {
        preamble(format!(
            "mesh {}: {} triangles",
            mesh.name,
            mesh.triangles.v0.len()
        ));
        println!("{}", bench::table_header());
    }
    bench::run(&mesh, &opts, |row| print(row, bench::table_row))?;
    Ok(())
}

fn converge(args: ConvergeArgs) -> packet_render::Result<()> {
    use packet_render::bench::converge;
    packet_render::integrator::budget::validate_threads(args.threads)?;
    let scene = packet_render::scene::load::load_scene(&args.scene)?;
    let opts = converge::ConvergeOptions {
        width: args.width,
        height: args.height,
        seed: args.seed,
        reference_eye: args.reference_eye,
        reference_shadow: args.reference_shadow,
        budgets: args.budgets,
        accel: args.accel,
        reps: args.reps,
        samplers: args
            .samplers
            .unwrap_or_else(|| packet_render::integrator::SamplerKind::ALL.to_vec()),
        splits: !args.no_splits,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build()
        .map_err(|e| packet_render::Error::parameter("threads", e.to_string()))?;
    let report = pool.install(|| {
        converge::run(&scene, &opts, |r| {
            eprintln!(
                "{:>18} budget {:>4}: {:.4} s, RMSE {:.5}, display RMSE {:.5}",
                r.strategy, r.budget, r.seconds, r.rmse, r.display_rmse
            )
        })
    })?;
    println!(
        "reference: {} eye x {} shadow, {:.2} s\n",
        opts.reference_eye, opts.reference_shadow, report.reference_seconds
    );
    println!("{}", report.table());
    println!("{}", report.slope_table());
    println!("{}", report.equal_time_table());
    report.write_csv(&args.csv)?;
    report.write_plot(
        &args.plot,
        &format!("{}: display RMSE against render time", args.scene.display()),
    )?;
    Ok(())
}

fn accel_compare(args: AccelCompareArgs) -> packet_render::Result<()> {
    use packet_render::bench::compare;
    let (input, note) = compare::CompareInput::load(&args.scene)?;
    let opts = compare::CompareOptions {
        width: args.width,
        height: args.height,
        reps: args.reps,
        include_bruteforce: args.include_bruteforce,
    };
    if !args.json {
        println!(
            "{}: {} primitives; {}x{}; single-ray traversal, {} threads; Mrays/s median of {} passes",
            input.name(),
            input.primitives(),
            opts.width,
            opts.height,
            rayon::current_num_threads(),
            opts.reps
        );
        if let Some(n) = &note {
            println!("{n}");
        }
        println!("{}", compare::table_header());
    }
    compare::compare(&input, &opts, |row| {
        if args.json {
            println!("{}", serde_json::to_string(row).expect("row serialises"));
        } else {
            println!("{}", compare::table_row(row));
        }
    })?;
    Ok(())
}

fn lecture_table(args: LectureTableArgs) -> packet_render::Result<()> {
    use packet_render::bench::lecture;
    let opts = lecture::LectureOptions {
        width: args.width,
        height: args.height,
        reps: args.reps,
        cap_seconds: args.cap_seconds,
        csv: args.csv,
        svg: args.svg,
    };
    let rows = lecture::run(&opts, |r| {
        eprintln!(
            "{:<10} {:>6} spheres: {:>10.1} ms{}",
            r.structure,
            r.spheres,
            r.total_ms,
            if r.extrapolated {
                " (extrapolated)"
            } else {
                ""
            }
        )
    })?;
    print!("{}", lecture::markdown(&rows));
    Ok(())
}

fn precision(rays: usize, json: bool) {
    use packet_render::bench::precision;
    if !json {
        println!("{}", precision::table_header());
    }
    for case in precision::standard_cases(rays) {
        for row in precision::measure(&case) {
            if json {
                println!("{}", serde_json::to_string(&row).expect("row serialises"));
            } else {
                println!("{}", precision::table_row(&row));
            }
        }
    }
}

/// A progress bar that stays hidden for the first second, so short renders print
/// nothing but the stats block.
fn progress_bar() -> (ProgressBar, Progress) {
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} tiles, eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let start = Instant::now();
    let shown = std::sync::atomic::AtomicBool::new(false);
    let b = bar.clone();
    let callback: Progress = Arc::new(move |done, total| {
        b.set_length(total);
        b.set_position(done);
        if start.elapsed() > Duration::from_secs(1)
            && !shown.swap(true, std::sync::atomic::Ordering::Relaxed)
        {
            b.set_draw_target(ProgressDrawTarget::stderr());
        }
    });
    (bar, callback)
}
