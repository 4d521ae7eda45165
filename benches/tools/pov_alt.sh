#!/usr/bin/env bash
# benches/tools/pov_alt.sh A_BIN B_BIN THREADS ROUNDS: whitted_base as run.sh meets it, each of
# our runs right after a POV-Ray run of the same scene (POV-Ray whitted, A, POV-Ray, B, ...).
# Prints per run POV-Ray's trace seconds, our render phase and film phase (ms), the render
# phase's page faults and the wavefront's camera / trace / shade / film stages (ms, all threads).
# Run from the project root; needs povray (apt-get install -y povray).
set -u
A=$1; B=$2; T=$3; R=$4
S=../shared/anchors/povray/scenes; out=$(mktemp -d)
for _ in $(seq "$R"); do for X in "$A" "$B"; do
  p=$(povray +I"$S/whitted.pov" +O"$out/p.png" +W1024 +H768 -A -D -V +FN +WT"$T" 2>&1 | sed -n 's/.*Trace Time:.*(\([0-9.]*\) seconds).*/\1/p' | tail -1)
  "$X" render "$S/whitted_base.toml" -o "$out/o.png" --threads "$T" --quiet --stats-json "$out/s.json" >/dev/null
  python3 -c "
import json,sys;d=json.load(open(sys.argv[1]));t=d['time_ms'];s=d['stages_ms']
print(sys.argv[2],'povray',sys.argv[3],'render',round(t['render'],1),'film phase',round(t.get('film',0),1),'faults',d['page_faults']['render'],' '.join(f'{k}={v:.1f}' for k,v in s.items() if k in ('camera','trace','shade','film')))" "$out/s.json" "$X" "$p"
done; done
rm -rf "$out"
