"""Mitsuba 3 version of scenes/dof_area.toml (16 eye x 4 light samples), for issue 11.
Differences: circular aperture (ours hexagonal), the red sphere diffuse only (ours adds a
Phong lobe), no ambient term, the checker as a 2D texture on the floor's uv."""
import sys
import drjit as dr
import mitsuba as mi
from timing import time_renders

W, H, threads, reps = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
mi.set_variant(sys.argv[5] if len(sys.argv) > 5 else "llvm_ad_rgb")
dr.set_thread_count(threads)
T = mi.ScalarTransform4f
rgb = lambda v: {"type": "rgb", "value": v}
diffuse = lambda v: {"type": "diffuse", "reflectance": rgb(v)}
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 0},
    "sensor": {
        "type": "thinlens", "fov": 40, "fov_axis": "y", "aperture_radius": 0.15, "focus_distance": 6.0,
        "to_world": T().look_at(origin=[0, 1.2, 6], target=[0, 0.7, 0], up=[0, 1, 0]),
        "sampler": {"type": "independent", "sample_count": 16},
        "film": {"type": "hdrfilm", "width": W, "height": H, "rfilter": {"type": "box"}},
    },
    "env": {"type": "constant", "radiance": rgb([0.05, 0.05, 0.08])},
    "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(12),
              "bsdf": {"type": "diffuse", "reflectance": {"type": "checkerboard",
                       "color0": rgb([0.8, 0.8, 0.8]), "color1": rgb([0.3, 0.3, 0.35]),
                       "to_uv": T().scale([24, 24, 1])}}},
    "red": {"type": "sphere", "center": [-1.6, 0.6, 2.2], "radius": 0.6, "bsdf": diffuse([0.8, 0.15, 0.1])},
    "green": {"type": "sphere", "center": [0, 0.7, 0], "radius": 0.7, "bsdf": diffuse([0.15, 0.7, 0.2])},
    "blue": {"type": "sphere", "center": [1.8, 0.8, -3], "radius": 0.8, "bsdf": diffuse([0.15, 0.25, 0.8])},
    "light": {"type": "rectangle", "to_world": T().translate([0, 3.5, 0]).rotate([1, 0, 0], 90).scale(0.75),
              "emitter": {"type": "area", "radiance": rgb([6, 6, 6])}},
})
time_renders(scene, 16, reps, {"scene": "dof_area", "threads": threads}, sys.argv[6] if len(sys.argv) > 6 else None)
