"""frame60_summary.py OUTPUT: summarises frame60.sh's output.

The bunny frame (1024x1024, 1 thread) traces 1,048,576 camera rays and 278,412 shadow
rays (its `--stats-json` ray counts; `bench`'s primary and shadow workloads are the same
rays). Bench's Mrays/s for that mix is the harmonic combination of its primary and shadow
figures; each frame's Mrays/s (rays / render phase) is given as a share of it.
"""
import statistics as st
import sys

CAMERA, SHADOW = 1048576, 278412
lines = open(sys.argv[1]).read().split("\n")
frames = [list(map(float, l.split())) for l in lines if l and l[0].isdigit()]
bench = {}
for l in lines:
    if l.startswith("bvh"):
        p = l.split()
        bench[(p[0], p[1])] = float(p[6])
rays = CAMERA + SHADOW
fs = sorted(f[0] for f in frames)
ct = sorted(f[1] / f[2] for f in frames)
print("frames ms min/median/max %.1f/%.1f/%.1f" % (fs[0], st.median(fs), fs[-1]))
for m in ["bvh4-packet", "bvh8-packet"]:
    if (m, "primary") not in bench:
        continue
    mix = rays / (CAMERA / bench[(m, "primary")] + SHADOW / bench[(m, "shadow")])
    r = [rays / (f * 1000) / mix * 100 for f in fs]
    print("%s primary %.2f shadow %.2f mix %.2f Mrays/s; frame share %% min/median/max %.1f/%.1f/%.1f"
          % (m, bench[(m, "primary")], bench[(m, "shadow")], mix, min(r), st.median(r), max(r)))
print("camera/trace min/median/max %.3f/%.3f/%.3f" % (ct[0], st.median(ct), ct[-1]))
