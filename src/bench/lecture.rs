//! `packet-render lecture-table`: the lecture's table of render time against primitive
//! count, reproduced: sphereflakes of levels 1..5 (10, 91, 820, 7381, 66430 spheres)
//! rendered small by the Whitted integrator (diffuse spheres, one point light: primary
//! plus one shadow ray per hit) with every structure. Times are build plus render; the
//! comparison with the lecture is by ratios (time at n / time at 10 spheres), since its
//! seconds come from another machine and another decade.
//!
//! Brute force is measured while its predicted time (the last measured time scaled
//! linearly by the sphere count) stays under a cap, and extrapolated linearly past it.

use crate::accel::{AccelKind, SceneAccel};
use crate::error::{Error, Result};
use crate::integrator::{RenderOptions, recursive};
use crate::plot::{Series, loglog_svg};
use crate::scene::{Light, Material, Scene, SceneBuilder, procedural};
use glam::Vec3;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// The lecture's render times (seconds) for 10, 91, 820, 7381 and 66430 spheres.
pub const LECTURE_BRUTEFORCE_S: [f64; 5] = [2.5, 11.4, 115.0, 2677.0, 24891.0];
/// The lecture's bottom-up bounding-volume hierarchy, same counts.
pub const LECTURE_HIERARCHY_S: [f64; 5] = [2.1, 3.0, 4.5, 6.5, 10.2];

#[derive(Clone, Debug)]
pub struct LectureOptions {
    pub width: u32,
    pub height: u32,
    /// Timed renders per figure; the fastest is kept.
    pub reps: usize,
    /// Brute force is extrapolated once its predicted time exceeds this.
    pub cap_seconds: f64,
    pub csv: Option<PathBuf>,
    pub svg: Option<PathBuf>,
}

impl Default for LectureOptions {
    fn default() -> Self {
        LectureOptions {
            width: 128,
            height: 128,
            reps: 2,
            cap_seconds: 5.0,
            csv: None,
            svg: None,
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct LectureRow {
    pub structure: &'static str,
    pub level: u32,
    pub spheres: usize,
    pub build_ms: f64,
    pub render_ms: f64,
    pub total_ms: f64,
    /// `total_ms` divided by this structure's `total_ms` at level 1.
    pub ratio: f64,
    /// True where brute force was not run but extrapolated linearly.
    pub extrapolated: bool,
}

/// A sphereflake of `level` under one light, framed by the protocol's camera.
pub fn flake_scene(level: u32, width: u32, height: u32) -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::diffuse("flake", Vec3::new(0.7, 0.6, 0.5)));
    procedural::sphereflake(&mut b, level, Vec3::ZERO, 1.0, m);
    b.add_light(Light::Point {
        position: Vec3::new(4.0, 6.0, 3.0),
        intensity: Vec3::splat(40.0),
    });
    b.camera = Some(crate::scene::Camera::framing(&b.bounds()));
    b.settings.width = width;
    b.settings.height = height;
    b.settings.spp = 1;
    b.settings.max_depth = 1;
    b.finish()
}

/// Best-of-`reps` (build ms, render ms) of one structure on one scene.
fn time_render(scene: &Scene, kind: AccelKind, reps: usize) -> (f64, f64) {
    let opts = RenderOptions::from_scene(scene);
    let mut best = (f64::INFINITY, f64::INFINITY);
    for _ in 0..reps.max(1) {
        let start = Instant::now();
        let accel = SceneAccel::build(scene, kind);
        let build = start.elapsed().as_secs_f64() * 1e3;
        let out = recursive::render(scene, &accel, &opts);
        if build + out.render_ms < best.0 + best.1 {
            best = (build, out.render_ms);
        }
    }
    best
}

/// Runs the table; `report` gets each row as it is measured.
pub fn run(opts: &LectureOptions, mut report: impl FnMut(&LectureRow)) -> Result<Vec<LectureRow>> {
    crate::scene::limits::validate_dimensions(opts.width, opts.height, 1, 1)?;
    if opts.cap_seconds.is_nan() || opts.cap_seconds <= 0.0 {
        return Err(Error::parameter("cap-seconds", "must be positive"));
    }
    let scenes: Vec<Scene> = (1..=5)
        .map(|l| flake_scene(l, opts.width, opts.height))
        .collect::<Result<_>>()?;
    // Warm-up (thread pool start, page faults), untimed.
    time_render(&scenes[0], AccelKind::Bvh2, 1);
    let mut rows = Vec::new();
    for &kind in AccelKind::ALL {
        let mut first_total = None;
        let mut last: Option<(usize, f64)> = None;
        for (i, scene) in scenes.iter().enumerate() {
            let n = scene.spheres.len();
            let predicted = last.map(|(m, t)| t * n as f64 / m as f64);
            let (build_ms, render_ms, total_ms, extrapolated) = match predicted {
                Some(p) if kind == AccelKind::BruteForce && p > opts.cap_seconds * 1e3 => {
                    (f64::NAN, f64::NAN, p, true)
                }
                _ => {
                    let reps = if kind == AccelKind::BruteForce {
                        1
                    } else {
                        opts.reps
                    };
                    let (b, r) = time_render(scene, kind, reps);
                    (b, r, b + r, false)
                }
            };
            if !extrapolated {
                last = Some((n, total_ms));
            }
            let first = *first_total.get_or_insert(total_ms);
            let row = LectureRow {
                structure: kind.name(),
                level: i as u32 + 1,
                spheres: n,
                build_ms,
                render_ms,
                total_ms,
                ratio: total_ms / first,
                extrapolated,
            };
            report(&row);
            rows.push(row);
        }
    }
    if let Some(path) = &opts.csv {
        let mut s = String::from(
            "structure,level,spheres,build_ms,render_ms,total_ms,ratio_to_10,extrapolated\n",
        );
        for r in &rows {
            s += &format!(
                "{},{},{},{:.3},{:.3},{:.3},{:.3},{}\n",
                r.structure,
                r.level,
                r.spheres,
                r.build_ms,
                r.render_ms,
                r.total_ms,
                r.ratio,
                r.extrapolated
            );
        }
        for (name, refs) in [
            ("lecture-bruteforce", LECTURE_BRUTEFORCE_S),
            ("lecture-hierarchy", LECTURE_HIERARCHY_S),
        ] {
            for (i, t) in refs.iter().enumerate() {
                s += &format!(
                    "{name},{},{},,,{:.3},{:.3},false\n",
                    i + 1,
                    procedural::sphereflake_count(i as u32 + 1),
                    t * 1e3,
                    t / refs[0]
                );
            }
        }
        crate::film::write_atomic(path, |out| {
            use std::io::Write;
            out.write_all(s.as_bytes()).map_err(|e| Error::io(path, e))
        })?;
    }
    if let Some(path) = &opts.svg {
        let mut series: Vec<Series> = AccelKind::ALL
            .iter()
            .map(|k| Series {
                name: format!(
                    "{}{}",
                    k.name(),
                    if *k == AccelKind::BruteForce {
                        " (extrapolated past the cap)"
                    } else {
                        ""
                    }
                ),
                points: rows
                    .iter()
                    .filter(|r| r.structure == k.name())
                    .map(|r| (r.spheres as f64, r.total_ms))
                    .collect(),
            })
            .collect();
        // The lecture's lines, scaled to our brute force and BVH2 at 10 spheres.
        let at10 = |name: &str| {
            rows.iter()
                .find(|r| r.structure == name && r.level == 1)
                .map_or(1.0, |r| r.total_ms)
        };
        for (name, refs, ours) in [
            (
                "lecture brute force (scaled to ours at n=10)",
                LECTURE_BRUTEFORCE_S,
                "bruteforce",
            ),
            (
                "lecture hierarchy (scaled to our bvh2 at n=10)",
                LECTURE_HIERARCHY_S,
                "bvh2",
            ),
        ] {
            let k = at10(ours) / refs[0];
            series.push(Series {
                name: name.into(),
                points: refs
                    .iter()
                    .enumerate()
                    .map(|(i, t)| (procedural::sphereflake_count(i as u32 + 1) as f64, t * k))
                    .collect(),
            });
        }
        loglog_svg(
            path,
            &format!(
                "Sphereflake, {}x{}, Whitted (primary + shadow): build + render time",
                opts.width, opts.height
            ),
            "spheres",
            "time (ms)",
            &series,
        )?;
    }
    Ok(rows)
}

/// The table as markdown: one row per structure, time (ms) and ratio per sphere count,
/// and the lecture's ratios for comparison.
pub fn markdown(rows: &[LectureRow]) -> String {
    let counts: Vec<usize> = (1..=5).map(procedural::sphereflake_count).collect();
    let mut s = String::from("| structure |");
    for n in &counts {
        s += &format!(" n={n} |");
    }
    s += "\n|---|";
    s += &"---:|".repeat(counts.len());
    s += "\n";
    for k in AccelKind::ALL {
        s += &format!("| {} |", k.name());
        for r in rows.iter().filter(|r| r.structure == k.name()) {
            s += &format!(
                " {:.1} ms ({:.1}x){} |",
                r.total_ms,
                r.ratio,
                if r.extrapolated { "*" } else { "" }
            );
        }
        s += "\n";
    }
    for (name, refs) in [
        ("lecture: brute force", LECTURE_BRUTEFORCE_S),
        ("lecture: hierarchy", LECTURE_HIERARCHY_S),
    ] {
        s += &format!("| {name} |");
        for t in refs {
            s += &format!(" {t} s ({:.1}x) |", t / refs[0]);
        }
        s += "\n";
    }
    s += "\nTimes are build + render (best of the repetitions); (Nx) is the ratio to the same \
          structure's time at 10 spheres. * = extrapolated linearly from the last measured \
          count (brute force past the time cap).\n";
    s
}
