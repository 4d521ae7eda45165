#!/usr/bin/env bash
# ab.sh BASE NEW ROUNDS -- render args... : interleaved render-phase times (ms), min/median/max
B=$1; N=$2; R=$3; shift 4
for i in $(seq $R); do for x in B N; do bin=${!x}
  "$bin" render "$@" -o /tmp/ab_$x.png --quiet --stats-json /tmp/ab_$x.json >/dev/null
  python3 -c "import json;print(json.load(open('/tmp/ab_$x.json'))['time_ms']['render'])" >> /tmp/ab_$x.txt.$$
done; done
for x in B N; do python3 -c "
import statistics,sys;v=[float(l) for l in open('/tmp/ab_$x.txt.$$')];print('$x', 'min %.1f median %.1f max %.1f'%(min(v),statistics.median(v),max(v)))"; rm /tmp/ab_$x.txt.$$; done
