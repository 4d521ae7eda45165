#!/usr/bin/env bash
# wf_vs_rec.sh BIN RUNS : wavefront vs recursive (whitted) render phase and peak RSS, 128x96, 1 thread
B=$1; RUNS=${2:-3}
for s in dof_area area_lights; do for spp in 1 16 256; do
  runs=$RUNS; [ $spp = 256 ] && runs=1
  for i in $(seq $runs); do
    line="$s spp $spp run $i:"
    for integ in whitted wavefront; do
      rss=$( { /usr/bin/time -f %M "$B" render scenes/$s.toml --width 128 --height 96 --spp $spp --threads 1 --integrator $integ --quiet -o /tmp/wfr_$integ.png --stats-json /tmp/wfr_$integ.json >/dev/null; } 2>&1 | tail -1)
      ms=$(python3 -c "import json;print(round(json.load(open('/tmp/wfr_$integ.json'))['time_ms']['render'],1))")
      line="$line $integ ${ms} ms ${rss} KB;"
    done
    w=$(python3 -c "import json;print(json.load(open('/tmp/wfr_whitted.json'))['time_ms']['render']/json.load(open('/tmp/wfr_wavefront.json'))['time_ms']['render'])")
    echo "$line speedup $(printf %.2f $w)x"
  done
done; done
