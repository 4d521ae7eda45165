//! The tile scheduler shared by both integrators: the image region cut into tiles,
//! rendered in parallel, and reassembled in a fixed order into the film (and, on
//! request, the encoded filter sums of a partial image).

use super::camera_rays::CameraSampler;
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
    /// Filter sums of each pixel, row-major within the tile.
    pub pixels: Vec<PixelSums>,
    pub rays: RayCounts,
    pub samples_drawn: EffectSamplesDrawn,
    pub nonfinite_samples: u64,
    pub stages: StageTimes,
}

/// Splits the image region (the whole image, or `opts.crop`) into tiles, renders them
/// in parallel with `tile_fn` (each rayon worker reuses one scratch value made by
/// `init`) and reassembles them in a fixed order. Each pixel's filter sums are
/// resolved into its value as its tile finishes, and, with `opts.keep_sums`, also
/// encoded for a partial image ([`crate::film::partial`]). Shared by both integrators.
pub(crate) fn render_tiles<W>(
    scene: &Scene,
    opts: &RenderOptions,
    init: impl Fn() -> W + Sync + Send,
    tile_fn: impl Fn(&mut W, &CameraSampler, Tile) -> TileResult + Sync + Send,
) -> RenderOutput {
    let start = Instant::now();
    let camera = CameraSampler::new(scene, opts);

    let region = opts.region();
    let tiles_x = region.width().div_ceil(TILE);
    let tiles_y = region.height().div_ceil(TILE);
    let total = tiles_x as u64 * tiles_y as u64;
    let done = AtomicU64::new(0);
    let tiles: Vec<(TileResult, Vec<Vec3>, Vec<u8>)> = (0..total)
        .into_par_iter()
        .map_init(&init, |ws, i| {
            let (tx, ty) = ((i % tiles_x as u64) as u32, (i / tiles_x as u64) as u32);
            let tile = Tile {
                x0: region.x0 + tx * TILE,
                y0: region.y0 + ty * TILE,
                x1: (region.x0 + (tx + 1) * TILE).min(region.x1),
                y1: (region.y0 + (ty + 1) * TILE).min(region.y1),
            };
            let mut result = tile_fn(ws, &camera, tile);
            let values = result.pixels.iter().map(PixelSums::value).collect();
            let mut encoded = Vec::new();
            if opts.keep_sums {
                for p in &result.pixels {
                    partial::encode_pixel(p, &mut encoded);
                }
            }
            result.pixels = Vec::new();
            if let Some(progress) = &opts.progress {
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            }
            (result, values, encoded)
        })
        .collect();

    // Encoded sums, row-major over the region: row by row through each row of tiles.
    let sums = opts.keep_sums.then(|| {
        let mut bytes = Vec::new();
        for row in tiles.chunks(tiles_x as usize) {
            let mut rest: Vec<&[u8]> = row.iter().map(|t| &t.2[..]).collect();
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

    let mut film = Film::new(region.width(), region.height());
    let mut rays = RayCounts::default();
    let mut samples_drawn = EffectSamplesDrawn::default();
    let mut stages = StageTimes::default();
    let mut nonfinite_samples = 0;
    for (t, values, _) in tiles {
        let mut values = values.into_iter();
        for y in t.tile.y0..t.tile.y1 {
            for x in t.tile.x0..t.tile.x1 {
                let v = values.next().expect("tile holds all its pixels");
                film.set(x - region.x0, y - region.y0, v);
            }
        }
        rays += t.rays;
        samples_drawn += t.samples_drawn;
        stages += t.stages;
        nonfinite_samples += t.nonfinite_samples;
    }
    RenderOutput {
        film,
        rays,
        render_ms: ms_since(start),
        nonfinite_samples,
        samples_drawn,
        stages_ms: Some(stages),
        region,
        sums,
    }
}
