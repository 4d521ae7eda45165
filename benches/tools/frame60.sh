#!/usr/bin/env bash
# frame60.sh [BIN] : the bunny frame against `bench` (issue 11), run from the project root.
# Five 1024x1024 1-thread bunny frames, `bench --modes bvh4-packet,bvh8-packet` on the same
# mesh, five more frames; prints each frame's render / camera / trace ms, the bench rows,
# then the summary of frame60_summary.py: each frame's Mrays/s as a share of bench's
# Mrays/s for the frame's ray mix (min/median/max), and camera/trace per frame.
B=${1:-target/release/packet-render}; M=../shared/models/bunny.obj
here=$(cd "$(dirname "$0")" && pwd)
out=$(mktemp -d)
fr() { "$B" render $M --width 1024 --height 1024 --threads 1 --quiet -o "$out/f.png" --stats-json "$out/f.json" >/dev/null; python3 -c "
import json,sys;d=json.load(open(sys.argv[1]));t=d['time_ms'];s=d.get('stages_ms',{})
print(t['render'], s.get('camera',-1), s.get('trace',-1))" "$out/f.json"; }
for i in 1 2 3 4 5; do fr; done > "$out/frames.txt"
"$B" bench --mesh $M --threads 1 --reps 5 --modes bvh4-packet,bvh8-packet 2>&1 | grep -E '^bvh' | grep -v diffuse > "$out/bench.txt"
for i in 1 2 3 4 5; do fr; done >> "$out/frames.txt"
cat "$out/frames.txt" "$out/bench.txt" > "$out/all.txt"
cat "$out/all.txt"
python3 "$here/frame60_summary.py" "$out/all.txt"
rm -rf "$out"
