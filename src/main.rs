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
    /// Render a scene (.toml) or a mesh (.obj, framed automatically) to an image
    /// (.png, or .hdr for linear float).
    Render(RenderArgs),
    /// Time the ray-throughput protocol of shared/BENCHMARK.md (Mrays/s for primary,
    /// shadow and diffuse rays) for each tracing mode, at 1 thread and all cores.
    Bench(BenchArgs),
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
struct BenchArgs {
    /// OBJ mesh (default: the procedural Bunny-scale mesh of 69,451 triangles).
    #[arg(long)]
    mesh: Option<PathBuf>,
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
    /// Output image: .png (8-bit sRGB) or .hdr (Radiance, linear).
    #[arg(short, long)]
    output: PathBuf,
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
    /// Worker threads; 0 = all cores.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Acceleration structure.
    #[arg(long, default_value = "bvh4", value_parser = parse_accel)]
    accel: AccelKind,
    /// Seed of the per-pixel random streams (same seed, same image, any thread count).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also write the stats as JSON to this file.
    #[arg(long)]
    stats_json: Option<PathBuf>,
    /// No progress bar and no stats block.
    #[arg(short, long)]
    quiet: bool,
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
    let job = RenderJob {
        scene: args.scene,
        output: args.output,
        overrides: Overrides {
            width: args.width,
            height: args.height,
            spp: args.spp,
            max_depth: args.max_depth,
        },
        accel: args.accel,
        seed: args.seed,
        threads: args.threads,
    };
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

fn bench(args: BenchArgs) -> packet_render::Result<()> {
    use packet_render::bench;
    let mesh = match &args.mesh {
        Some(p) => bench::BenchMesh::from_obj(p)?,
        None => bench::BenchMesh::procedural(bench::DEFAULT_MESH_TRIANGLES),
    };
    let opts = bench::BenchOptions {
        modes: args.modes,
        threads: args.threads,
        reps: args.reps,
        width: args.width,
        height: args.height,
    };
    if !args.json {
        println!(
            "mesh {}: {} triangles; {}x{}; kernels built for {}, {}-ray packets; {} timed passes, median",
            mesh.name,
            mesh.triangles.v0.len(),
            opts.width,
            opts.height,
            bench::instruction_set(),
            packet_render::simd::PACKET_WIDTH,
            opts.reps
        );
        println!("{}", bench::table_header());
    }
    bench::run(&mesh, &opts, |row| {
        if args.json {
            println!("{}", serde_json::to_string(row).expect("row serialises"));
        } else {
            println!("{}", bench::table_row(row));
        }
    })?;
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
