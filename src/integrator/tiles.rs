//! The tile scheduler shared by both integrators: the image region cut into tiles,
//! rendered in parallel straight into the film (and, on request, the encoded filter
//! sums of a partial image, assembled in a fixed order).

use super::camera_rays::CameraSampler;
use super::pixel_filter::TileOut;
use super::{RenderOptions, RenderOutput};
use crate::film::{Film, PixelSums, partial};
use crate::pages::populate_for_writing;
use crate::scene::Scene;
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes, ms_since};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Tile edge in pixels: 1024 pixels amortise rayon's per-task cost and the wavefront's
/// per-wave costs while leaving many tiles per thread for load balance on uneven
/// scenes (768 tiles at 1024x768).
///
/// Was 16 (256 pixels). In a tile of whitted_base the waves after the camera's are
/// small (about 145 reflected and 145 refracted rays at depth one, fewer after), so
/// each wave's fixed costs (material sort, stage timers, part-filled lane groups) weigh
/// more; 32 holds four times the rays per wave, and a 32x32 tile at one ray per pixel
/// still fits one camera batch (1,024 < 1,365 rays on the Whitted rows, 1,638 on the
/// bunny). Measured (helper fr24, 2026-11-29) with a temporary build reading the edge
/// from the environment, one binary, the render phase's process CPU time
/// (`CLOCK_PROCESS_CPUTIME_ID` around `IntegratorKind::render`), 1 thread, AVX-512,
/// interleaved rounds on a host loaded 6-7 by other builds (wall time meant nothing
/// there), min/median ms: whitted_base 16: 54.5/55.3, 32: 52.2/52.3, 64: 52.4/52.7
/// (5 rounds; waves of 16,384 paths instead of 8,192: 53.1 at 32, 53.9 at 64);
/// bunny 1024x1024 50.8/51.9 -> 48.6/49.1 (5 rounds); whitted aa3x3 465.0/465.4 ->
/// 457.0/458.7, area64 714.7/717.6 -> 707.8/712.7, blur16 858.0/874.6 -> 849.9/874.5
/// (3 rounds each). At 2 threads whitted_base 55.1/55.9 -> 53.8/54.2 (both threads'
/// CPU, 7 rounds). Images byte-identical (a pixel's sums do not depend on which
/// tile or wave batch holds it).
pub(crate) const TILE: u32 = 32;

#[derive(Clone, Copy, Debug)]
pub(crate) struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Tile {
    fn width(&self) -> usize {
        (self.x1 - self.x0) as usize
    }

    fn pixels(&self) -> usize {
        self.width() * (self.y1 - self.y0) as usize
    }
}

pub(crate) struct TileResult {
    pub tile: Tile,
    pub rays: RayCounts,
    pub samples_drawn: EffectSamplesDrawn,
    pub nonfinite_samples: u64,
    pub stages: StageTimes,
    /// Most paths the wavefront's queues held at once (0 for the recursive integrator).
    pub peak_queue_paths: u64,
}

/// Splits the image region (the whole image, or `opts.crop`) into tiles and renders
/// them in parallel with `tile_fn`, straight into the film. Each worker thread of the
/// pool keeps one scratch value made by `init` on its first tile ([`PerWorker`]).
/// `tile_fn` writes each pixel's value into the worker's tile buffer ([`TileOut`],
/// row-major in the tile), copied into the tile's rows of the film when it returns,
/// and, with `opts.keep_sums`, its filter sums into the worker's buffer, which are
/// encoded for a partial image ([`crate::film::partial`]). Shared by both integrators.
///
/// The film is `committed` when the caller made it before the render, its memory
/// mapped ([`Film::committed`], as the CLI does), and must then be the region's size;
/// otherwise a fresh [`Film::new`], each band's pages mapped by the band's task before
/// its tiles write them (the `film` stage).
///
/// The film is cut into bands of `TILE` rows, one parallel task each; a band cuts its
/// rows at the tile edges and renders its tiles in parallel, each tile owning its row
/// spans. So all the work of the render phase runs in the tiles: the frame is not
/// zero-filled first (`Film::new` allocates zeroed pages), nothing is laid out again
/// at the end, and a band merges its own counts and sums.
///
/// Every band and every tile is a job of its own (`with_max_len(1)`), which an idle
/// worker can take. With rayon's adaptive splitting a job held a run of a band's tiles
/// (up to 16 of 64 at 2 threads), rendered in order by one thread, so a worker that ran
/// out of work waited for the other's run to end. Timelines of tiles per worker
/// (temporary timers, 2 threads, load 4-5, 6-8 interleaved frames each): the time from
/// the first worker's last tile to the end of the frame was 0.02-11.3 ms before against
/// 0.01-5.6 ms after on whitted_base 1024x768 (frames 77-173 ms), 0.9-13.5 against
/// 0.2-7.2 ms on dof_area 320x240 (150-320 ms). What remains is a worker preempted by
/// the host in its last tile, and the other worker's start: its first tile began
/// 0.4-11.5 ms into the frame (rayon waking a sleeping thread under that load).
///
/// Before, the tiles wrote a tile-major copy of the frame (zero-filled first, 9.4 MB at
/// 1024x768) that was laid out row-major into the film after the last tile, and every
/// rayon job split off made a new scratch value (`map_init`: 16-18 per frame on 2
/// threads, each growing its queues again). Measured with temporary timers on
/// whitted_base 1024x768 (loaded machine, load 5): fill 5-11 ms and layout 7-17 ms,
/// serial, of a 200-250 ms render phase, at 1 and 2 threads.
pub(crate) fn render_tiles<W: Send>(
    scene: &Scene,
    opts: &RenderOptions,
    committed: Option<Film>,
    init: impl Fn() -> W + Sync + Send,
    tile_fn: impl Fn(&mut W, &CameraSampler, Tile, &mut TileOut) -> TileResult + Sync + Send,
) -> RenderOutput {
    let start = Instant::now();
    let camera = CameraSampler::new(scene, opts);
    let region = opts.region();
    let (width, height) = (region.width(), region.height());
    let tiles_x = width.div_ceil(TILE) as usize;
    let total = tiles_x as u64 * height.div_ceil(TILE) as u64;
    let done = AtomicU64::new(0);
    let keep = opts.keep_sums;
    // A film committed by the caller ([`Film::committed`]) has its pages mapped
    // already; a fresh one has its bands mapped by the tiles below.
    let fresh = committed.is_none();
    let mut film = match committed {
        Some(film) => {
            assert_eq!(
                (film.width, film.height),
                (width, height),
                "a committed film the size of the render's region"
            );
            film
        }
        None => Film::new(width, height),
    };
    let workers = PerWorker::new(rayon::current_num_threads());
    let row = (width as usize).max(1);
    let setup = ms_since(start);

    let bands: Vec<Band> = film
        .pixels
        .par_chunks_mut(row * TILE as usize)
        .enumerate()
        .with_max_len(1)
        .map(|(ty, band)| {
            // The band's pages mapped in one call, not one fault per page as its tiles
            // copy their rows in (`pages::populate_for_writing`); counted as `film`.
            let t = Instant::now();
            if fresh {
                populate_for_writing(band);
            }
            let populate = ms_since(t);
            let y0 = region.y0 + ty as u32 * TILE;
            let rows = band.len() / row;
            // The band's rows cut at the tile edges, listed tile by tile: tile `tx`
            // owns `spans[tx * rows..(tx + 1) * rows]`, one span per row.
            let mut cut: Vec<_> = band
                .chunks_mut(row)
                .map(|r| r.chunks_mut(TILE as usize))
                .collect();
            let mut spans: Vec<&mut [Vec3]> = Vec::with_capacity(tiles_x * rows);
            for _ in 0..tiles_x {
                for r in &mut cut {
                    spans.extend(r.next());
                }
            }
            let tiles: Vec<(TileResult, Vec<u8>)> = spans
                .par_chunks_mut(rows.max(1))
                .enumerate()
                .with_max_len(1)
                .map(|(tx, spans)| {
                    let tile = Tile {
                        x0: region.x0 + tx as u32 * TILE,
                        y0,
                        x1: (region.x0 + (tx as u32 + 1) * TILE).min(region.x1),
                        y1: (y0 + TILE).min(region.y1),
                    };
                    let out = workers.with(
                        || Scratch {
                            ws: init(),
                            values: Vec::new(),
                            sums: Vec::new(),
                        },
                        |s| s.render(&tile_fn, &camera, tile, keep, spans),
                    );
                    if let Some(progress) = &opts.progress {
                        progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                    }
                    out
                })
                .collect();
            let mut band = Band::merge(tiles, keep);
            band.stages.film += populate;
            band
        })
        .collect();

    let assembling = Instant::now();
    drop(workers);
    let mut all = Band::default();
    for b in &bands {
        all.add(b);
    }
    let sums = keep.then(|| {
        bands
            .into_iter()
            .map(|b| b.sums)
            .collect::<Vec<_>>()
            .concat()
    });
    let mut stages = all.stages;
    stages.setup = setup;
    stages.assemble = ms_since(assembling);
    RenderOutput {
        film,
        rays: all.rays,
        render_ms: ms_since(start),
        nonfinite_samples: all.nonfinite_samples,
        samples_drawn: all.samples_drawn,
        stages_ms: Some(stages),
        peak_queue_paths: all.peak_queue_paths,
        region,
        sums,
    }
}

/// One value per worker thread of the current rayon pool, made on the thread's first
/// use and kept for the rest of the frame. A thread outside the pool, or one that
/// finds its value in use (a nested task on the same thread), gets a fresh one.
struct PerWorker<S> {
    slots: Vec<Mutex<Option<S>>>,
}

impl<S> PerWorker<S> {
    fn new(threads: usize) -> Self {
        PerWorker {
            slots: (0..threads).map(|_| Mutex::new(None)).collect(),
        }
    }

    fn with<R>(&self, make: impl FnOnce() -> S, f: impl FnOnce(&mut S) -> R) -> R {
        let slot = rayon::current_thread_index()
            .and_then(|i| self.slots.get(i))
            .and_then(|m| m.try_lock().ok());
        match slot {
            Some(mut held) => f(held.get_or_insert_with(make)),
            None => f(&mut make()),
        }
    }
}

/// A worker's scratch: the integrator's own, and the tile's pixel values and sums.
struct Scratch<W> {
    ws: W,
    values: Vec<Vec3>,
    sums: Vec<PixelSums>,
}

impl<W> Scratch<W> {
    /// Renders `tile` into the scratch buffers, copies its values into its row spans
    /// of the film and encodes its sums (with `keep`); the copy and the encoding count
    /// in the `resolve` stage.
    fn render(
        &mut self,
        tile_fn: &impl Fn(&mut W, &CameraSampler, Tile, &mut TileOut) -> TileResult,
        camera: &CameraSampler,
        tile: Tile,
        keep: bool,
        spans: &mut [&mut [Vec3]],
    ) -> (TileResult, Vec<u8>) {
        let n = tile.pixels();
        self.values.clear();
        self.values.resize(n, Vec3::ZERO);
        if keep {
            self.sums.clear();
            self.sums.resize(n, PixelSums::default());
        }
        let mut out = TileOut {
            values: &mut self.values,
            sums: keep.then_some(&mut self.sums[..]),
        };
        let mut result = tile_fn(&mut self.ws, camera, tile, &mut out);
        let t = Instant::now();
        for (span, values) in spans.iter_mut().zip(self.values.chunks_exact(tile.width())) {
            span.copy_from_slice(values);
        }
        let mut encoded = Vec::new();
        if keep {
            for p in &self.sums {
                partial::encode_pixel(p, &mut encoded);
            }
        }
        result.stages.resolve += ms_since(t);
        (result, encoded)
    }
}

/// A band's tiles merged: their counts, and the encoded sums of its pixels row-major.
#[derive(Default)]
struct Band {
    rays: RayCounts,
    samples_drawn: EffectSamplesDrawn,
    nonfinite_samples: u64,
    stages: StageTimes,
    peak_queue_paths: u64,
    sums: Vec<u8>,
}

impl Band {
    fn merge(tiles: Vec<(TileResult, Vec<u8>)>, keep: bool) -> Band {
        let mut band = Band::default();
        for (t, _) in &tiles {
            band.rays += t.rays;
            band.samples_drawn += t.samples_drawn;
            band.stages += t.stages;
            band.peak_queue_paths = band.peak_queue_paths.max(t.peak_queue_paths);
            band.nonfinite_samples += t.nonfinite_samples;
        }
        if keep && let Some((first, _)) = tiles.first() {
            // Row by row through the band's tiles, each tile's part of the row.
            let mut rest: Vec<&[u8]> = tiles.iter().map(|t| &t.1[..]).collect();
            for _ in first.tile.y0..first.tile.y1 {
                for (t, r) in tiles.iter().zip(&mut rest) {
                    let len = partial::encoded_len(r, t.0.tile.width());
                    band.sums.extend_from_slice(&r[..len]);
                    *r = &r[len..];
                }
            }
        }
        band
    }

    fn add(&mut self, b: &Band) {
        self.rays += b.rays;
        self.samples_drawn += b.samples_drawn;
        self.stages += b.stages;
        self.peak_queue_paths = self.peak_queue_paths.max(b.peak_queue_paths);
        self.nonfinite_samples += b.nonfinite_samples;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::PixelBounds;
    use crate::scene::{Material, SceneBuilder};
    use std::sync::atomic::AtomicUsize;

    fn scene() -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::default());
        b.add_sphere(Vec3::ZERO, 1.0, m);
        b.finish().unwrap()
    }

    /// What the fake integrator below writes for pixel `(x, y)`: distinct per pixel.
    fn value(x: u32, y: u32) -> Vec3 {
        Vec3::new(x as f32, y as f32, (7 * x + 3 * y) as f32 + 0.5)
    }

    fn sums(x: u32, y: u32) -> PixelSums {
        let mut s = PixelSums::default();
        s.add_sample(1.0, value(x, y));
        s.add_sample(0.25, Vec3::splat(y as f32));
        s
    }

    /// Regions that are and are not whole tiles, cropped or not, with and without
    /// kept sums, into a fresh film or one committed before (whose own pixels are
    /// written), on 1, 2 and 3 threads: every pixel lands at its place in the film
    /// (row-major over the region), the kept sums come row-major too, the tiles'
    /// counts and stage times add up, and each worker thread makes one scratch value
    /// (the old `map_init` made one per rayon job: 16-18 per frame on 2 threads).
    #[test]
    fn tiles_land_in_place_with_one_scratch_per_worker() {
        let scene = scene();
        let mut cases = 0;
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            for (w, h, crop) in [
                (37, 21, None),
                (64, 48, None),
                (1, 1, None),
                (50, 40, Some((3, 45, 17, 39))),
            ] {
                for (keep, committed) in
                    [(false, false), (true, false), (false, true), (true, true)]
                {
                    let mut opts = RenderOptions::from_scene(&scene);
                    (opts.width, opts.height, opts.keep_sums) = (w, h, keep);
                    opts.crop = crop.map(|(x0, x1, y0, y1)| PixelBounds { x0, x1, y0, y1 });
                    let inits = AtomicUsize::new(0);
                    let region = opts.region();
                    let film = committed.then(|| {
                        pool.install(|| Film::committed(region.width(), region.height()))
                            .expect("film")
                    });
                    // The committed film's own pixels come back, written in place.
                    let given = film.as_ref().map(|f| f.pixels.as_ptr());
                    let out = pool.install(|| {
                        render_tiles(
                            &scene,
                            &opts,
                            film,
                            || {
                                inits.fetch_add(1, Ordering::Relaxed);
                            },
                            |_, _, tile, out| {
                                let tw = tile.x1 - tile.x0;
                                for y in tile.y0..tile.y1 {
                                    for x in tile.x0..tile.x1 {
                                        let a = ((y - tile.y0) * tw + x - tile.x0) as usize;
                                        out.values[a] = value(x, y);
                                        if let Some(s) = &mut out.sums {
                                            s[a] = sums(x, y);
                                        }
                                    }
                                }
                                TileResult {
                                    tile,
                                    rays: RayCounts {
                                        camera: tile.pixels() as u64,
                                        ..Default::default()
                                    },
                                    samples_drawn: EffectSamplesDrawn::default(),
                                    nonfinite_samples: 1,
                                    stages: StageTimes {
                                        trace: 1.0,
                                        shadow: Some(2.0),
                                        ..Default::default()
                                    },
                                    peak_queue_paths: (tile.x0 + tile.y0) as u64,
                                }
                            },
                        )
                    });
                    let (rw, rh) = (region.width(), region.height());
                    let case = format!(
                        "{w}x{h} crop {crop:?} keep {keep} committed {committed}, {threads} threads"
                    );
                    assert_eq!((out.film.width, out.film.height), (rw, rh), "{case}");
                    if let Some(p) = given {
                        assert_eq!(out.film.pixels.as_ptr(), p, "{case}");
                    }
                    let mut want_sums = Vec::new();
                    for y in region.y0..region.y1 {
                        for x in region.x0..region.x1 {
                            let i = ((y - region.y0) * rw + x - region.x0) as usize;
                            assert_eq!(out.film.pixels[i], value(x, y), "({x}, {y}) {case}");
                            partial::encode_pixel(&sums(x, y), &mut want_sums);
                        }
                    }
                    assert_eq!(out.sums, keep.then_some(want_sums), "{case}");
                    let tiles = (rw.div_ceil(TILE) * rh.div_ceil(TILE)) as u64;
                    assert_eq!(out.rays.camera, region.area(), "{case}");
                    assert_eq!(out.nonfinite_samples, tiles, "{case}");
                    let stages = out.stages_ms.unwrap();
                    assert_eq!(stages.trace, tiles as f64, "{case}");
                    assert_eq!(stages.shadow, Some(2.0 * tiles as f64), "{case}");
                    let last =
                        (region.x0 + (rw - 1) / TILE * TILE) + (region.y0 + (rh - 1) / TILE * TILE);
                    assert_eq!(out.peak_queue_paths, last as u64, "{case}");
                    let made = inits.load(Ordering::Relaxed);
                    assert!(
                        made >= 1 && made <= threads,
                        "{made} scratch values: {case}"
                    );
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 3 * 4 * 4);
    }
}
