//! `packet-render accel-compare`: every acceleration structure on one scene, side by
//! side: build time, memory, size, mean traversal work per primary ray, and Mrays/s of
//! the BENCHMARK.md workloads traced one ray at a time ([`SingleRay`]).
//!
//! Triangle meshes (OBJ, or a TOML scene with triangles) run the protocol of
//! [`Protocol`] unchanged. A TOML scene with spheres only runs a sphere-aware variant of
//! it ([`SphereProtocol`]): the same framing, camera, light, offsets and random numbers,
//! with the sphere's normal `normalize(p - centre)` in place of the triangle's
//! geometric normal. A scene with both is compared over the more numerous kind (the
//! other is left out, and the report says so): the sphereflake scene runs over its
//! spheres, not its two floor triangles.

use super::{
    BenchCamera, Framing, Protocol, SingleRay, TraceMode, Workload, cosine_dir, median,
    pixel_uniforms, run_mode,
};
use crate::accel::{AccelKind, GridOptions, Primitives, Spheres, TraversalCounts, Triangles};
use crate::error::{Error, Result};
use crate::geometry::Ray;
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Brute force joins the comparison only up to this many primitives, unless asked.
pub const BRUTEFORCE_LIMIT: usize = 5000;

#[derive(Clone, Debug)]
pub struct CompareOptions {
    pub width: u32,
    pub height: u32,
    pub reps: usize,
    pub include_bruteforce: bool,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            width: 256,
            height: 256,
            reps: 3,
            include_bruteforce: false,
        }
    }
}

/// One structure's row.
#[derive(Clone, Debug, Serialize)]
pub struct CompareRow {
    pub structure: String,
    pub primitive_kind: &'static str,
    pub primitives: usize,
    pub build_ms: f64,
    pub memory_bytes: usize,
    pub nodes: usize,
    pub max_depth: usize,
    /// Mean over the primary rays; `None` where the structure has no counting twin.
    pub node_visits_per_ray: Option<f64>,
    pub prim_tests_per_ray: Option<f64>,
    pub primary_mrays: f64,
    pub shadow_mrays: f64,
    pub diffuse_mrays: f64,
    pub primary_hits: u64,
    pub primary_sum_t: f64,
    pub shadow_occluded: u64,
    pub threads: usize,
}

/// What a comparison runs over.
pub enum CompareInput {
    Triangles {
        name: String,
        positions: Vec<Vec3>,
        triangles: Triangles,
    },
    Spheres {
        name: String,
        spheres: Spheres,
    },
}

impl CompareInput {
    /// An OBJ mesh or a TOML scene.
    pub fn load(path: &Path) -> Result<(CompareInput, Option<String>)> {
        let name = path.display().to_string();
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
        {
            let m = super::BenchMesh::from_obj(path)?;
            return Ok((
                CompareInput::Triangles {
                    name,
                    positions: m.positions,
                    triangles: m.triangles,
                },
                None,
            ));
        }
        let scene = crate::scene::load::load_scene(path)?;
        let (tris, spheres) = (scene.mesh.len(), scene.spheres.len());
        let note = (tris > 0 && spheres > 0).then(|| {
            let (used, n, left, m) = if tris >= spheres {
                ("triangles", tris, "spheres", spheres)
            } else {
                ("spheres", spheres, "triangles", tris)
            };
            format!(
                "note: the protocol runs over the scene's {n} {used}; its {m} {left} are left out"
            )
        });
        if tris > 0 && tris >= spheres {
            let positions = (0..scene.mesh.vertex_count() as u32)
                .map(|i| scene.mesh.vertex(i))
                .collect();
            Ok((
                CompareInput::Triangles {
                    name,
                    positions,
                    triangles: Triangles::from_mesh(&scene.mesh),
                },
                note,
            ))
        } else if spheres > 0 {
            Ok((
                CompareInput::Spheres {
                    name,
                    spheres: Spheres::from_set(&scene.spheres),
                },
                note,
            ))
        } else {
            Err(Error::parameter("scene", "the scene has no primitives"))
        }
    }

    pub fn name(&self) -> &str {
        match self {
            CompareInput::Triangles { name, .. } | CompareInput::Spheres { name, .. } => name,
        }
    }

    pub fn primitives(&self) -> usize {
        match self {
            CompareInput::Triangles { triangles, .. } => triangles.count(),
            CompareInput::Spheres { spheres, .. } => spheres.count(),
        }
    }
}

/// The structures compared: every [`AccelKind`] (brute force only when small or asked
/// for) plus the grid without mailboxing, to show what the mailbox saves.
fn variants(n: usize, opts: &CompareOptions) -> Vec<(String, AccelKind, bool)> {
    let mut v = Vec::new();
    for &k in AccelKind::ALL {
        if k == AccelKind::BruteForce && n > BRUTEFORCE_LIMIT && !opts.include_bruteforce {
            continue;
        }
        v.push((k.name().to_string(), k, true));
        if k == AccelKind::Grid {
            v.push(("grid-nomailbox".to_string(), k, false));
        }
    }
    v
}

fn build<P: Primitives + Clone + 'static>(
    prims: &P,
    kind: AccelKind,
    mailbox: bool,
) -> Box<dyn crate::accel::Accel> {
    if kind == AccelKind::Grid && !mailbox {
        Box::new(crate::accel::Grid::build_with(
            prims.clone(),
            GridOptions {
                mailbox: false,
                ..Default::default()
            },
        ))
    } else {
        kind.build(prims.clone())
    }
}

/// Mean counts over `rays`, `None` if the structure has no counting twin.
fn mean_counts(accel: &dyn crate::accel::Accel, rays: &[Ray]) -> Option<(f64, f64)> {
    let total = rays
        .par_iter()
        .map(|r| accel.traversal_counts(r))
        .try_fold(TraversalCounts::default, |acc, c| {
            c.map(|c| TraversalCounts {
                nodes: acc.nodes + c.nodes,
                prim_tests: acc.prim_tests + c.prim_tests,
            })
        })
        .try_reduce(TraversalCounts::default, |a, b| {
            Some(TraversalCounts {
                nodes: a.nodes + b.nodes,
                prim_tests: a.prim_tests + b.prim_tests,
            })
        })?;
    let n = rays.len().max(1) as f64;
    Some((total.nodes as f64 / n, total.prim_tests as f64 / n))
}

fn camera_rays(cam: &BenchCamera) -> Vec<Ray> {
    (0..cam.height)
        .flat_map(|y| (0..cam.width).map(move |x| Ray::new(cam.eye, cam.dir(x, y))))
        .collect()
}

/// Runs the comparison; `report` gets each row as it is measured.
pub fn compare(
    input: &CompareInput,
    opts: &CompareOptions,
    mut report: impl FnMut(&CompareRow),
) -> Result<Vec<CompareRow>> {
    if opts.reps < 1 {
        return Err(Error::parameter("reps", "at least 1 timed pass"));
    }
    crate::scene::limits::validate_dimensions(opts.width, opts.height, 1, 0)?;
    let threads = rayon::current_num_threads();
    let mut rows = Vec::new();
    match input {
        CompareInput::Triangles {
            positions,
            triangles,
            ..
        } => {
            let protocol = Protocol::new(positions, triangles.clone(), opts.width, opts.height);
            let primary = camera_rays(&protocol.camera);
            for (name, kind, mailbox) in variants(triangles.count(), opts) {
                let start = Instant::now();
                let accel = build(triangles, kind, mailbox);
                let build_ms = start.elapsed().as_secs_f64() * 1e3;
                let info = accel.info();
                let counts = mean_counts(accel.as_ref(), &primary);
                let mode = SingleRay {
                    name: "single",
                    accel,
                };
                let bench = run_mode(&protocol, &mode, threads, opts.reps, build_ms);
                let get = |w: &str| bench.iter().find(|r| r.workload == w).expect("workload");
                let row = CompareRow {
                    structure: name,
                    primitive_kind: "triangles",
                    primitives: info.primitives,
                    build_ms,
                    memory_bytes: info.memory_bytes,
                    nodes: info.nodes,
                    max_depth: info.max_depth,
                    node_visits_per_ray: counts.map(|c| c.0),
                    prim_tests_per_ray: counts.map(|c| c.1),
                    primary_mrays: get("primary").mrays_median,
                    shadow_mrays: get("shadow").mrays_median,
                    diffuse_mrays: get("diffuse").mrays_median,
                    primary_hits: get("primary").hits_or_occluded,
                    primary_sum_t: get("primary").sum_t,
                    shadow_occluded: get("shadow").hits_or_occluded,
                    threads,
                };
                report(&row);
                rows.push(row);
            }
        }
        CompareInput::Spheres { spheres, .. } => {
            let protocol = SphereProtocol::new(spheres.clone(), opts.width, opts.height);
            let primary = camera_rays(&protocol.camera);
            for (name, kind, mailbox) in variants(spheres.count(), opts) {
                let start = Instant::now();
                let accel = build(spheres, kind, mailbox);
                let build_ms = start.elapsed().as_secs_f64() * 1e3;
                let info = accel.info();
                let counts = mean_counts(accel.as_ref(), &primary);
                let mode = SingleRay {
                    name: "single",
                    accel,
                };
                let m = protocol.measure_all(&mode, opts.reps);
                let row = CompareRow {
                    structure: name,
                    primitive_kind: "spheres",
                    primitives: info.primitives,
                    build_ms,
                    memory_bytes: info.memory_bytes,
                    nodes: info.nodes,
                    max_depth: info.max_depth,
                    node_visits_per_ray: counts.map(|c| c.0),
                    prim_tests_per_ray: counts.map(|c| c.1),
                    primary_mrays: m[0].mrays,
                    shadow_mrays: m[1].mrays,
                    diffuse_mrays: m[2].mrays,
                    primary_hits: m[0].hits,
                    primary_sum_t: m[0].sum_t,
                    shadow_occluded: m[1].hits,
                    threads,
                };
                report(&row);
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

pub fn table_header() -> String {
    format!(
        "{:<15} {:>9} {:>11} {:>8} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "structure",
        "build ms",
        "memory B",
        "nodes",
        "depth",
        "visits/r",
        "tests/r",
        "primary",
        "shadow",
        "diffuse",
        "hits"
    )
}

pub fn table_row(r: &CompareRow) -> String {
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    format!(
        "{:<15} {:>9.1} {:>11} {:>8} {:>5} {:>9} {:>9} {:>9.2} {:>9.2} {:>9.2} {:>9}",
        r.structure,
        r.build_ms,
        r.memory_bytes,
        r.nodes,
        r.max_depth,
        opt(r.node_visits_per_ray),
        opt(r.prim_tests_per_ray),
        r.primary_mrays,
        r.shadow_mrays,
        r.diffuse_mrays,
        r.primary_hits
    )
}

/// The protocol over spheres: BENCHMARK.md's framing (over the spheres' bounds),
/// camera, light, origin offset and random numbers; the normal at a hit is
/// `normalize(p - centre)`, flipped to face the ray. Pixels are traced in rows handed
/// to threads dynamically.
pub struct SphereProtocol {
    pub spheres: Spheres,
    pub framing: Framing,
    pub camera: BenchCamera,
}

/// Result of one sphere workload: rays, hits (or occluded), sum of t, Mrays/s (median).
#[derive(Clone, Copy, Debug)]
pub struct SphereMeasure {
    pub rays: u64,
    pub hits: u64,
    pub sum_t: f64,
    pub mrays: f64,
}

impl SphereProtocol {
    pub fn new(spheres: Spheres, width: u32, height: u32) -> Self {
        let corners: Vec<Vec3> = (0..spheres.count())
            .flat_map(|i| {
                let b = spheres.bounds(i);
                [b.min, b.max]
            })
            .collect();
        let framing = Framing::new(&corners);
        let camera = BenchCamera::new(&framing, width, height);
        SphereProtocol {
            spheres,
            framing,
            camera,
        }
    }

    fn secondary(&self, w: Workload, x: u32, y: u32, t: f32, prim: u32) -> Ray {
        let dir = self.camera.dir(x, y);
        let p = self.camera.eye + dir * t;
        let mut n = (p - self.spheres.center[prim as usize]).normalize();
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let o = p + n * (1e-4 * self.framing.diagonal) as f32;
        match w {
            Workload::Shadow => {
                let to = self.framing.light.as_vec3() - o;
                let tmax = to.length();
                Ray::segment(o, to * (1.0 / tmax), 0.0, tmax)
            }
            _ => {
                let (u1, u2) = pixel_uniforms(y * self.camera.width + x);
                Ray::new(o, cosine_dir(n, u1, u2))
            }
        }
    }

    /// One pass; per-pixel `(t, prim)` (prim `u32::MAX` for a miss or no ray).
    fn pass(&self, mode: &dyn TraceMode, w: Workload, primary: &[(f32, u32)]) -> Vec<(f32, u32)> {
        let width = self.camera.width;
        (0..self.camera.height)
            .into_par_iter()
            .flat_map_iter(|y| {
                let mut rays = Vec::with_capacity(width as usize);
                let mut slots = Vec::with_capacity(width as usize);
                for x in 0..width {
                    match w {
                        Workload::Primary => {
                            rays.push(Ray::new(self.camera.eye, self.camera.dir(x, y)));
                            slots.push(x);
                        }
                        _ => {
                            let (t, p) = primary[(y * width + x) as usize];
                            if p != u32::MAX {
                                rays.push(self.secondary(w, x, y, t, p));
                                slots.push(x);
                            }
                        }
                    }
                }
                let mut row = vec![(f32::NAN, u32::MAX); width as usize];
                if w == Workload::Shadow {
                    let mut occ = vec![false; rays.len()];
                    mode.occluded(&rays, &mut occ);
                    for (k, &x) in slots.iter().enumerate() {
                        row[x as usize] = (if occ[k] { 1.0 } else { 0.0 }, 0);
                    }
                } else {
                    let mut hits = vec![None; rays.len()];
                    mode.closest(&rays, &mut hits);
                    for (k, &x) in slots.iter().enumerate() {
                        if let Some(h) = hits[k] {
                            row[x as usize] = (h.t, h.prim);
                        }
                    }
                }
                row
            })
            .collect()
    }

    /// Primary, shadow and diffuse: one warm-up and `reps` timed passes each.
    pub fn measure_all(&self, mode: &dyn TraceMode, reps: usize) -> [SphereMeasure; 3] {
        let primary = self.pass(mode, Workload::Primary, &[]);
        Workload::ALL.map(|w| {
            let mut out = self.pass(mode, w, &primary);
            let rays = match w {
                Workload::Primary => out.len() as u64,
                _ => primary.iter().filter(|p| p.1 != u32::MAX).count() as u64,
            };
            let mut rates = Vec::with_capacity(reps);
            for _ in 0..reps {
                let start = Instant::now();
                out = self.pass(mode, w, &primary);
                rates.push(rays as f64 / start.elapsed().as_secs_f64() / 1e6);
            }
            let (hits, sum_t) = match w {
                Workload::Shadow => (out.iter().filter(|o| o.1 == 0 && o.0 == 1.0).count(), 0.0),
                _ => {
                    let h: Vec<_> = out.iter().filter(|o| o.1 != u32::MAX).collect();
                    (h.len(), h.iter().map(|o| o.0 as f64).sum())
                }
            };
            SphereMeasure {
                rays,
                hits: hits as u64,
                sum_t,
                mrays: median(&rates),
            }
        })
    }
}
