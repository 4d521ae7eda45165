"""The timed renders shared by the scene scripts: one untimed-for-the-median first render
(Dr.Jit compiles its kernels there), then `reps` timed ones; prints one JSON line."""
import json
import statistics
import time

import drjit as dr
import mitsuba as mi


def time_renders(scene, spp, reps, fields, png=None):
    times, cpu = [], []
    for i in range(reps + 1):
        t0, c0 = time.perf_counter(), time.process_time()
        img = mi.render(scene, spp=spp, seed=i)
        dr.eval(img)
        dr.sync_thread()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    if png:
        mi.util.write_bitmap(png, img)
    warm = times[1:]
    print(json.dumps({"tracer": "mitsuba " + mi.__version__, **fields,
                      "first_s": round(times[0], 4), "warm_min_s": round(min(warm), 4),
                      "warm_median_s": round(statistics.median(warm), 4),
                      "warm_max_s": round(max(warm), 4),
                      "cpu_per_wall": round(sum(cpu[1:]) / sum(warm), 3)}))
