"""Mitsuba 3 (llvm_ad_rgb) render of BENCHMARK.md's bunny frame, for issue 11."""
import math
import sys
import drjit as dr
import mitsuba as mi
from timing import time_renders

obj, W, H, threads, reps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
variant = sys.argv[6] if len(sys.argv) > 6 else "llvm_ad_rgb"
mi.set_variant(variant)
dr.set_thread_count(threads)

verts = []
with open(obj) as f:
    for line in f:
        if line.startswith("v "):
            p = line.split(); verts.append((float(p[1]), float(p[2]), float(p[3])))
lo = [min(v[i] for v in verts) for i in range(3)]
hi = [max(v[i] for v in verts) for i in range(3)]
c = [(lo[i] + hi[i]) / 2 for i in range(3)]
d = math.sqrt(sum((hi[i] - lo[i]) ** 2 for i in range(3)))
n = math.sqrt(0.5 ** 2 + 0.3 ** 2 + 1.0)
eye = [c[0] + 1.2 * d * 0.5 / n, c[1] + 1.2 * d * 0.3 / n, c[2] + 1.2 * d * 1.0 / n]
light = [c[0] + d * 0.8, c[1] + d * 1.2, c[2] + d * 0.6]

scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
    "sensor": {
        "type": "perspective", "fov": 45, "fov_axis": "y",
        "to_world": mi.ScalarTransform4f().look_at(origin=eye, target=c, up=[0, 1, 0]),
        "sampler": {"type": "independent", "sample_count": 1},
        "film": {"type": "hdrfilm", "width": W, "height": H, "rfilter": {"type": "box"}},
    },
    "bunny": {"type": "obj", "filename": obj, "face_normals": True,
              "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0.8, 0.8]}}},
    "light": {"type": "point", "position": light, "intensity": {"type": "rgb", "value": [d * d] * 3}},
})
time_renders(scene, 1, reps, {"scene": "bunny", "variant": variant, "threads": threads}, sys.argv[7] if len(sys.argv) > 7 else None)
