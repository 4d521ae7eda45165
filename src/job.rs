//! A render job as the CLI runs it: load, build, render, write, with timings and
//! counts for the stats block. Kept in the library so tests and other front ends get
//! the same behaviour as `packet-render render`.

use crate::accel::{AccelInfo, AccelKind, SceneAccel};
use crate::error::{Error, Result};
use crate::film::partial::{self, PartialHeader, PartialImage};
use crate::integrator::{
    FilterKind, IntegratorKind, PixelBounds, RenderOptions, RenderOutput, SamplerKind, budget,
};
use crate::scene::{self, SampleCounts, Scene};
use crate::stats::{
    EffectSamplesDrawn, PhaseFaults, PhaseTimes, RayCounts, StageTimes, ms_since,
    process_page_faults,
};
use serde::Serialize;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Command-line overrides of the scene's render settings.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub spp: Option<u32>,
    pub max_depth: Option<u32>,
    /// Per-effect sample counts (`spp` is the eye count).
    pub shadow_samples: Option<u32>,
    pub glossy_samples: Option<u32>,
    pub lens_samples: Option<u32>,
    pub time_samples: Option<u32>,
    /// Directions towards the environment per lit shading point.
    pub environment_samples: Option<u32>,
    pub sampler: Option<SamplerKind>,
    pub filter: Option<FilterKind>,
    /// Shadows through glass on or off (`integrator::shadow`).
    pub transmitted_shadows: Option<bool>,
    /// Camera flags (`--eye`, `--target`, `--up`, `--fov`, `--up-axis`,
    /// `--look-from-side`), applied to the loaded scene's camera.
    pub camera: scene::CameraOverrides,
}

/// One render from a scene file to an image file.
#[derive(Clone, Debug)]
pub struct RenderJob {
    pub scene: PathBuf,
    pub output: PathBuf,
    pub overrides: Overrides,
    pub accel: AccelKind,
    pub integrator: IntegratorKind,
    pub seed: u64,
    /// Worker threads; 0 means all cores; at most [`budget::MAX_THREADS`].
    pub threads: usize,
    /// Files the caller writes after the render (`--stats-json`): checked with the
    /// image before any work, and none may be the same file as another.
    pub extra_outputs: Vec<PathBuf>,
    /// Which part of the frame to render (default: all of it).
    pub part: Part,
    /// Exposure and tone mapping (PNG only) and EXR precision of the output image.
    pub image: crate::film::ImageOptions,
}

/// A part of a frame for distributed rendering (docs/distributed.md): a pixel
/// rectangle (`crop`, or the `tile.0`-th of `tile.1` balanced bands) and a slice of the
/// eye samples. A `.partial` output keeps the exact pixel sums for `packet-render merge`.
#[derive(Clone, Debug, Default)]
pub struct Part {
    pub crop: Option<PixelBounds>,
    pub tile: Option<(u32, u32)>,
    pub sample_range: Option<Range<u32>>,
}

/// What a render did, printed as the stats block and written by `--stats-json`.
#[derive(Clone, Debug, Serialize)]
pub struct RenderReport {
    pub scene: String,
    pub output: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Per-effect sample counts requested (an effect the scene lacks ignores its count).
    pub samples: SampleCounts,
    pub sampler: SamplerKind,
    pub filter: FilterKind,
    pub threads: usize,
    pub seed: u64,
    pub integrator: IntegratorKind,
    /// The part rendered (pixels and samples), absent for a whole frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<String>,
    pub primitives: PrimitiveCounts,
    pub features: Vec<&'static str>,
    pub accel: Vec<AccelInfo>,
    pub rays: RayTotals,
    pub time_ms: PhaseTimes,
    /// Page faults by phase (the whole process; zero where not counted).
    pub page_faults: PhaseFaults,
    /// Time by stage (wavefront only), summed over threads; a stage the scene does not
    /// need is absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stages_ms: Option<StageTimes>,
    /// Most paths the wavefront's queues held at once in one worker (wavefront only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_queue_paths: Option<u64>,
    /// All rays traced per second of render time, in millions.
    pub mrays_per_s: f64,
    /// Samples whose radiance was NaN or infinite (written as black).
    pub nonfinite_samples: u64,
    /// Lens, time, light and glossy samples drawn (zero for effects the scene lacks).
    pub samples_drawn: EffectSamplesDrawn,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct PrimitiveCounts {
    pub triangles: usize,
    pub spheres: usize,
    /// Placed instances (`[[instance]]`, named meshes drawn in place) and the triangles
    /// they draw (each object stored once).
    pub instances: usize,
    pub instanced_triangles: usize,
    /// Infinite planes.
    pub planes: usize,
    pub lights: usize,
    pub materials: usize,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct RayTotals {
    #[serde(flatten)]
    pub by_kind: RayCounts,
    pub total: u64,
}

/// Progress callback: (units done, units total).
pub type Progress = Arc<dyn Fn(u64, u64) + Send + Sync>;

impl RenderJob {
    /// Runs the job in a thread pool of the requested size. Nothing is written unless
    /// every step before the write succeeded, and the write itself is atomic.
    pub fn run(&self, progress: Option<Progress>) -> Result<RenderReport> {
        budget::validate_threads(self.threads)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(self.threads)
            .build()
            .map_err(|e| Error::parameter("threads", e.to_string()))?;
        let threads = pool.current_num_threads();
        pool.install(|| self.run_in_pool(threads, progress))
    }

    fn run_in_pool(&self, threads: usize, progress: Option<Progress>) -> Result<RenderReport> {
        let partial = crate::film::partial::is_partial_path(&self.output);
        if !partial {
            crate::film::check_image_path(&self.output)?;
        }
        // A bad exposure, or AOVs for a format that cannot hold them, is refused before
        // any work, not after the render.
        self.image.validate()?;
        self.check_aovs(partial)?;
        let outputs: Vec<&std::path::Path> = std::iter::once(&self.output)
            .chain(&self.extra_outputs)
            .map(PathBuf::as_path)
            .collect();
        crate::film::check_output_paths(&outputs)?;
        let mut time = PhaseTimes::default();
        let mut faults = PhaseFaults::default();
        let mut mapped = process_page_faults();
        let mut faults_lap = || {
            let before = std::mem::replace(&mut mapped, process_page_faults());
            mapped.saturating_sub(before)
        };
        let t = Instant::now();
        let mut scene = scene::load::load_scene(&self.scene)?;
        self.overrides.camera.apply_to_scene(&mut scene)?;
        time.load = ms_since(t);
        faults.load = faults_lap();
        if let Some(w) = scene::nothing_visible_warning(&scene, &self.scene.display().to_string()) {
            eprintln!("warning: {w}");
        }

        let mut opts = self.options(&scene)?;
        opts.progress = progress;
        opts.keep_sums = partial;
        let products = budget::validate_sample_products(&scene, &opts)?;
        let estimate = budget::peak_buffer_bytes(self.integrator, &products, &opts, threads);
        budget::check_memory(estimate, budget::available_memory(), self.integrator)?;
        // The film taken now, its pages mapped, so that a machine without the memory
        // fails here and the render writes into memory it already has
        // (`Film::committed`).
        let t = Instant::now();
        let region = opts.region();
        let film = crate::film::Film::committed(region.width(), region.height())?;
        time.film = ms_since(t);
        faults.film = faults_lap();

        let t = Instant::now();
        let accel = SceneAccel::build(&scene, self.accel);
        time.build = ms_since(t);
        faults.build = faults_lap();

        let out = self.integrator.render_into(&scene, &accel, &opts, film);
        time.render = out.render_ms;
        faults.render = faults_lap();

        let t = Instant::now();
        if partial {
            self.partial_image(&scene, &opts, &out)?
                .save(&self.output)?;
        } else {
            self.save_image(&scene, &accel, &opts, &out)?;
        }
        time.write = ms_since(t);
        faults.write = faults_lap();

        let total = out.rays.total();
        Ok(RenderReport {
            scene: self.scene.display().to_string(),
            output: self.output.display().to_string(),
            width: opts.width,
            height: opts.height,
            spp: opts.spp,
            samples: opts.samples,
            sampler: opts.sampler,
            filter: opts.filter,
            threads,
            seed: self.seed,
            integrator: self.integrator,
            part: (opts.crop.is_some() || opts.sample_range.is_some()).then(|| {
                let r = opts.sample_range.clone().unwrap_or(0..opts.spp);
                format!("pixels {}, samples {}..{}", out.region, r.start, r.end)
            }),
            primitives: PrimitiveCounts {
                triangles: scene.mesh.len(),
                spheres: scene.spheres.len(),
                instances: scene.instances.instances.len(),
                instanced_triangles: scene.instances.instanced_triangles(),
                planes: scene.planes.len(),
                lights: scene.lights.len(),
                materials: scene.materials.len(),
            },
            features: scene.features.names(),
            accel: accel.info(),
            rays: RayTotals {
                by_kind: out.rays,
                total,
            },
            time_ms: time,
            page_faults: faults,
            peak_queue_paths: out.stages_ms.is_some().then_some(out.peak_queue_paths),
            stages_ms: out.stages_ms,
            mrays_per_s: total as f64 / (time.render.max(1e-6) * 1e3),
            nonfinite_samples: out.nonfinite_samples,
            samples_drawn: out.samples_drawn,
        })
    }

    /// The scene's settings with the command-line overrides applied, validated.
    pub fn options(&self, scene: &Scene) -> Result<RenderOptions> {
        let mut o = RenderOptions::from_scene(scene);
        let ov = &self.overrides;
        o.width = ov.width.unwrap_or(o.width);
        o.height = ov.height.unwrap_or(o.height);
        o.spp = ov.spp.unwrap_or(o.spp);
        o.max_depth = ov.max_depth.unwrap_or(o.max_depth);
        o.samples.shadow = ov.shadow_samples.unwrap_or(o.samples.shadow);
        o.samples.glossy = ov.glossy_samples.unwrap_or(o.samples.glossy);
        o.samples.lens = ov.lens_samples.unwrap_or(o.samples.lens);
        o.samples.time = ov.time_samples.unwrap_or(o.samples.time);
        o.samples.environment = ov.environment_samples.unwrap_or(o.samples.environment);
        o.sampler = ov.sampler.unwrap_or(o.sampler);
        o.filter = ov.filter.unwrap_or(o.filter);
        o.transmitted_shadows = ov.transmitted_shadows.unwrap_or(o.transmitted_shadows);
        o.seed = self.seed;
        o.crop = match (self.part.crop, self.part.tile) {
            (Some(_), Some(_)) => {
                return Err(Error::parameter("crop", "give --crop or --tile, not both"));
            }
            (crop, None) => crop,
            (None, Some((i, n))) => Some(PixelBounds::tile(i, n, o.width, o.height)?),
        };
        o.sample_range = self.part.sample_range.clone();
        o.validate()?;
        Ok(o)
    }

    /// The text of every setting that changes pixel values (for the fingerprint of a
    /// partial image). The integrator and the structure are in it: the two integrators
    /// agree only up to float summation order, and structures may break ties between
    /// equally near hits differently.
    fn options_text(&self, o: &RenderOptions) -> String {
        format!(
            "{}x{}, spp {}, seed {}, max depth {}, min contribution {:e}, samples {:?}, sampler {}, filter {}, transmitted shadows {}, integrator {}, accel {:?}",
            o.width,
            o.height,
            o.spp,
            o.seed,
            o.max_depth,
            o.min_contribution,
            o.samples,
            o.sampler,
            o.filter,
            o.transmitted_shadows,
            self.integrator,
            self.accel
        )
    }

    /// The partial image of a render made with `opts.keep_sums`.
    fn check_aovs(&self, partial: bool) -> Result<()> {
        let exr = self
            .output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if self.image.aovs && (partial || !exr) {
            return Err(Error::parameter(
                "--aovs",
                format!(
                    "{}: depth, normal and albedo layers need an .exr output",
                    self.output.display()
                ),
            ));
        }
        Ok(())
    }

    /// The film, plus the AOV layers when asked for (one centre ray per pixel).
    fn save_image(
        &self,
        scene: &Scene,
        accel: &SceneAccel,
        opts: &RenderOptions,
        out: &RenderOutput,
    ) -> Result<()> {
        let extra = if self.image.aovs {
            let aovs = crate::integrator::aov::Aovs::render(
                scene,
                accel,
                opts.width,
                opts.height,
                out.region,
            );
            aovs.channels()
        } else {
            Vec::new()
        };
        out.film
            .save_with_channels(&self.output, &self.image, &extra)
    }

    fn partial_image(
        &self,
        scene: &Scene,
        opts: &RenderOptions,
        out: &RenderOutput,
    ) -> Result<PartialImage> {
        let text = self.options_text(opts);
        Ok(PartialImage {
            header: PartialHeader {
                width: opts.width,
                height: opts.height,
                bounds: out.region,
                samples: opts.sample_range.clone().unwrap_or(0..opts.spp),
                spp: opts.spp,
                seed: opts.seed,
                fingerprint: partial::fingerprint(scene, &text),
                description: format!("{}: {text}", self.scene.display()),
            },
            pixels: out
                .sums
                .clone()
                .ok_or_else(|| Error::parameter("partial image", "render kept no sums"))?,
        })
    }
}

impl RenderReport {
    /// The human-readable stats block.
    pub fn summary(&self) -> String {
        let r = &self.rays.by_kind;
        let accel: Vec<String> = self
            .accel
            .iter()
            .map(|a| {
                format!(
                    "{} over {} prims: {} nodes, {} leaves, depth {}, SAH {:.2}, {:.1} MiB, {:.1} ms",
                    a.name,
                    a.primitives,
                    a.nodes,
                    a.leaves,
                    a.max_depth,
                    a.sah_cost,
                    a.memory_bytes as f64 / (1 << 20) as f64,
                    a.build_ms
                )
            })
            .collect();
        let t = &self.time_ms;
        let mut s = String::new();
        s += &format!(
            "scene    {}: {} triangles, {} spheres, {} lights, {} materials\n",
            self.scene,
            self.primitives.triangles,
            self.primitives.spheres,
            self.primitives.lights,
            self.primitives.materials
        );
        s += &format!("features {}\n", self.features.join(", "));
        for a in accel {
            s += &format!("accel    {a}\n");
        }
        s += &format!(
            "image    {} ({}x{}, {} spp, seed {})\n",
            self.output, self.width, self.height, self.spp, self.seed
        );
        if let Some(part) = &self.part {
            s += &format!("part     {part}\n");
        }
        s += &format!(
            "samples  eye {} x shadow {} x glossy {} x lens {} x time {}, environment {}, {} sampler, {} filter\n",
            self.spp,
            self.samples.shadow,
            self.samples.glossy,
            self.samples.lens,
            self.samples.time,
            self.samples.environment,
            self.sampler,
            self.filter
        );
        s += &format!(
            "rays     camera {}, shadow {} ({} traced again through glass), reflection {}, refraction {}, glossy {}, translucency {}; total {}\n",
            r.camera,
            r.shadow,
            r.transmitted_shadow,
            r.reflection,
            r.refraction,
            r.glossy,
            r.translucency,
            self.rays.total
        );
        s += &format!(
            "time     load {:.1} ms, film {:.1} ms, build {:.1} ms, render {:.1} ms, write {:.1} ms; total {:.1} ms\n",
            t.load,
            t.film,
            t.build,
            t.render,
            t.write,
            t.total()
        );
        let f = &self.page_faults;
        s += &format!(
            "faults   load {}, film {}, build {}, render {}, write {} (pages the process mapped)\n",
            f.load, f.film, f.build, f.render, f.write
        );
        if let Some(st) = &self.stages_ms {
            let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
            s += &format!(
                "stages   setup {:.1}, camera {:.1}, trace {:.1}, shade {:.1}, shadow {}, area shadow {}, reflection {}, refraction {}, glossy {}, translucency {}, resolve {:.1}, film pages {:.1}, assemble {:.1} (ms, all threads)\n",
                st.setup,
                st.camera,
                st.trace,
                st.shade,
                opt(st.shadow),
                opt(st.area_shadow),
                opt(st.reflection),
                opt(st.refraction),
                opt(st.glossy),
                opt(st.translucency),
                st.resolve,
                st.film,
                st.assemble
            );
        }
        s += &format!(
            "speed    {:.2} Mrays/s on {} threads, {} integrator\n",
            self.mrays_per_s, self.threads, self.integrator
        );
        if self.nonfinite_samples > 0 {
            s += &format!(
                "warning  {} samples were NaN or infinite and were written as black\n",
                self.nonfinite_samples
            );
        }
        s
    }
}
