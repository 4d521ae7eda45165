#!/usr/bin/env bash
# Wavefront vs recursive end-to-end render time (docs/wavefront.md).
# Usage: scripts/bench_wavefront.sh [BUNNY_OBJ] [RUNS]
# Writes the Stanford Bunny scene (the model is not ours to ship) to a temp dir, then
# renders scenes/whitted.toml and the bunny at 1024x1024 with both integrators at
# --threads 1 and --threads 0, pairs back to back, and prints the median render time.
set -euo pipefail
cd "$(dirname "$0")/.."
BUNNY=${1:-/work/shared/models/bunny.obj}
RUNS=${2:-3}
BIN=target/release/packet-render
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
cat > "$TMP/bunny_mirror_glass.toml" <<TOML
# The Stanford Bunny (69,451 triangles) on a mirror floor next to a glass sphere.
background = [0.35, 0.4, 0.5]
ambient = [0.04, 0.04, 0.04]

[render]
width = 1024
height = 1024
spp = 1
max_depth = 8

[camera]
eye = [0, 1.6, 4.2]
target = [0, 0.8, 0]
fov = 45

[materials.clay]
diffuse = [0.75, 0.55, 0.4]
specular = [0.25, 0.25, 0.25]
shininess = 40

[materials.floor_mirror]
preset = "mirror"
mirror = [0.8, 0.8, 0.85]

[materials.glass]
preset = "glass"
ior = 1.5

[[mesh]]
file = "$BUNNY"
material = "clay"
scale = 10
translate = [-0.2, -0.33, 0]

[[sphere]]
center = [0.95, 0.45, 0.6]
radius = 0.45
material = "glass"

[[quad]]
corner = [-6, 0, -6]
edge1 = [0, 0, 12]
edge2 = [12, 0, 0]
material = "floor_mirror"

[[light]]
type = "point"
position = [3, 5, 4]
intensity = [45, 45, 45]
TOML
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
for scene in scenes/whitted.toml "$TMP/bunny_mirror_glass.toml"; do
  for threads in 1 0; do
    rm -f "$TMP"/t_*
    for _ in $(seq "$RUNS"); do
      for integ in whitted wavefront; do
        "$BIN" render "$scene" -o "$TMP/out.png" --width 1024 --height 1024 \
          --integrator $integ --threads $threads --quiet --stats-json "$TMP/s.json"
        python3 -c "import json,sys; s=json.load(open(sys.argv[1])); print(s['time_ms']['render'], s['rays']['total'], s['mrays_per_s'])" "$TMP/s.json" >> "$TMP/t_$integ"
      done
    done
    w=$(cut -d' ' -f1 "$TMP/t_whitted" | median)
    v=$(cut -d' ' -f1 "$TMP/t_wavefront" | median)
    rays=$(head -1 "$TMP/t_wavefront" | cut -d' ' -f2)
    python3 -c "import sys; w,v,r=map(float,sys.argv[1:4]); print(f'{sys.argv[4]:<28} threads {sys.argv[5]}: whitted {w:8.1f} ms ({r/w/1e3:6.2f} Mrays/s)  wavefront {v:8.1f} ms ({r/v/1e3:6.2f} Mrays/s)  speedup {w/v:.2f}x  ({int(r)} rays)')" "$w" "$v" "$rays" "$(basename "$scene")" "$threads"
  done
done
