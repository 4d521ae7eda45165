//! The tile scheduler shared by both integrators: the image region cut into tiles,
//! rendered in parallel, and reassembled in a fixed order into the film (and, on
//! request, the encoded filter sums of a partial image).

use super::camera_rays::CameraSampler;
use super::pixel_filter::TileOut;
use super::{RenderOptions, RenderOutput};
use crate::film::{Film, PixelSums, partial};
use crate::scene::Scene;
use crate::stats::{EffectSamplesDrawn, RayCounts, StageTimes, ms_since};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Tile edge in pixels: 256 pixels amortise rayon's per-task cost while leaving many
/// tiles per thread for load balance on uneven scenes.
pub(crate) const TILE: u32 = 16;

#[derive(Clone, Copy, Debug)]
pub(crate) struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
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

/// Splits the image region (the whole image, or `opts.crop`) into tiles, renders them
/// in parallel with `tile_fn` (each rayon worker reuses one scratch value made by
/// `init`) and reassembles them in a fixed order. `tile_fn` writes each pixel's value
/// into its tile's block of the frame ([`TileOut`], row-major in the tile) and, with
/// `opts.keep_sums`, its filter sums into the worker's buffer, which are encoded for a
/// partial image ([`crate::film::partial`]). Shared by both integrators.
///
/// The frame is held tile-major while the tiles render (tile `i` owns the `TILE²`
/// values from `i * TILE²`), so that every tile writes its own slice with no
/// allocation, fill or copy of its own, and is laid out row-major once at the end.
/// Before, each tile built a buffer of 256 filter sums (136 bytes a pixel, allocated
/// and filled per tile) and a vector of values, copied pixel by pixel into the film:
/// together about 16-19 % of the bunny frame's render phase (`perf`, 1024x1024, 1
/// thread).
pub(crate) fn render_tiles<W>(
    scene: &Scene,
    opts: &RenderOptions,
    init: impl Fn() -> W + Sync + Send,
    tile_fn: impl Fn(&mut W, &CameraSampler, Tile, &mut TileOut) -> TileResult + Sync + Send,
) -> RenderOutput {
    let start = Instant::now();
    let camera = CameraSampler::new(scene, opts);

    let region = opts.region();
    let tiles_x = region.width().div_ceil(TILE);
    let tiles_y = region.height().div_ceil(TILE);
    let total = tiles_x as usize * tiles_y as usize;
    let cells = (TILE * TILE) as usize;
    let tile_at = |i: usize| {
        let (tx, ty) = ((i % tiles_x as usize) as u32, (i / tiles_x as usize) as u32);
        Tile {
            x0: region.x0 + tx * TILE,
            y0: region.y0 + ty * TILE,
            x1: (region.x0 + (tx + 1) * TILE).min(region.x1),
            y1: (region.y0 + (ty + 1) * TILE).min(region.y1),
        }
    };
    let done = AtomicU64::new(0);
    let keep = opts.keep_sums;
    let mut blocks = vec![Vec3::ZERO; total * cells];
    let tiles: Vec<(TileResult, Vec<u8>)> = blocks
        .par_chunks_mut(cells)
        .enumerate()
        .map_init(
            || (init(), Vec::<PixelSums>::new()),
            |(ws, sums), (i, block)| {
                let tile = tile_at(i);
                let n = ((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize;
                if keep {
                    sums.clear();
                    sums.resize(n, PixelSums::default());
                }
                let mut out = TileOut {
                    values: &mut block[..n],
                    sums: keep.then_some(&mut sums[..]),
                };
                let result = tile_fn(ws, &camera, tile, &mut out);
                let mut encoded = Vec::new();
                if keep {
                    for p in sums.iter() {
                        partial::encode_pixel(p, &mut encoded);
                    }
                }
                if let Some(progress) = &opts.progress {
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, total as u64);
                }
                (result, encoded)
            },
        )
        .collect();

    // Encoded sums, row-major over the region: row by row through each row of tiles.
    let sums = opts.keep_sums.then(|| {
        let mut bytes = Vec::new();
        for row in tiles.chunks(tiles_x.max(1) as usize) {
            let mut rest: Vec<&[u8]> = row.iter().map(|t| &t.1[..]).collect();
            for _ in row[0].0.tile.y0..row[0].0.tile.y1 {
                for (t, r) in row.iter().zip(&mut rest) {
                    let n = (t.0.tile.x1 - t.0.tile.x0) as usize;
                    let len = partial::encoded_len(r, n);
                    bytes.extend_from_slice(&r[..len]);
                    *r = &r[len..];
                }
            }
        }
        bytes
    });

    // The values, row-major over the region: each tile row's rows, tile by tile.
    let (width, height) = (region.width(), region.height());
    let mut pixels = Vec::with_capacity(width as usize * height as usize);
    for (row, blocks) in tiles
        .chunks(tiles_x as usize)
        .zip(blocks.chunks(tiles_x.max(1) as usize * cells))
    {
        for y in 0..(row[0].0.tile.y1 - row[0].0.tile.y0) as usize {
            for (t, block) in row.iter().zip(blocks.chunks(cells)) {
                let w = (t.0.tile.x1 - t.0.tile.x0) as usize;
                pixels.extend_from_slice(&block[y * w..(y + 1) * w]);
            }
        }
    }
    drop(blocks);
    let film = Film {
        width,
        height,
        pixels,
    };
    let mut rays = RayCounts::default();
    let mut samples_drawn = EffectSamplesDrawn::default();
    let mut stages = StageTimes::default();
    let mut peak_queue_paths = 0;
    let mut nonfinite_samples = 0;
    for (t, _) in tiles {
        rays += t.rays;
        samples_drawn += t.samples_drawn;
        stages += t.stages;
        peak_queue_paths = peak_queue_paths.max(t.peak_queue_paths);
        nonfinite_samples += t.nonfinite_samples;
    }
    RenderOutput {
        film,
        rays,
        render_ms: ms_since(start),
        nonfinite_samples,
        samples_drawn,
        stages_ms: Some(stages),
        peak_queue_paths,
        region,
        sums,
    }
}
