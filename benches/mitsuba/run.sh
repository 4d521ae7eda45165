#!/usr/bin/env bash
# Render phase against Mitsuba 3's JIT-vectorised wavefront variant (llvm_ad_rgb: Dr.Jit
# compiles the whole frame to LLVM kernels, Embree traces), on the same frames, back to back.
#   benches/mitsuba/run.sh PACKET_RENDER_BINARY [THREADS] [REPS]
# Needs: python3 -m venv /tmp/mi-venv && /tmp/mi-venv/bin/pip install mitsuba   (3.9.1 here)
#        apt-get install -y libllvm19   (LLVM 15 fails to select fmaximum for dof_area)
# Mitsuba's figure is the median of REPS renders after one untimed first render (which
# JIT-compiles its kernels: 0.3-0.7 s, printed as first_s); ours is `render`'s phase from
# --stats-json, the median of REPS runs taken alternately with Mitsuba's batch.
set -euo pipefail
PR=${1:?usage: run.sh PACKET_RENDER_BINARY [THREADS] [REPS]}
T=${2:-1}; REPS=${3:-3}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
PY=${MITSUBA_PYTHON:-/tmp/mi-venv/bin/python}
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM-19.so}
"$PY" -c "import mitsuba" 2>/dev/null || { echo "mitsuba not importable by $PY (see the header)" >&2; exit 2; }
out=$(mktemp -d)
ours() { # args -> render seconds
  "$PR" render "$@" -o "$out/o.png" --threads "$T" --quiet --stats-json "$out/s.json" >/dev/null
  python3 -c "import json,sys;print(json.load(open(sys.argv[1]))['time_ms']['render']/1000)" "$out/s.json"
}
mits() { # script args -> warm median seconds (of REPS) and first render
  "$PY" "$here/$1" "${@:2}" | python3 -c "import json,sys;d=json.loads(sys.stdin.read().strip().splitlines()[-1]);print(d['warm_median_s'],d['first_s'])"
}
median() { python3 -c "import sys,statistics;print(round(statistics.median(float(x) for x in sys.argv[1:]),4))" "$@"; }
echo "threads $T, median of $REPS, load: $(cut -d' ' -f1-3 /proc/loadavg)"
row() { # name, mitsuba script args..., --, ours args...
  local name=$1; shift
  local -a ma=() oa=(); while [ "$1" != -- ]; do ma+=("$1"); shift; done; shift; oa=("$@")
  local o=() m first
  for _ in $(seq "$REPS"); do o+=("$(ours "${oa[@]}")"); done
  read -r m first < <(mits "${ma[@]}")
  for _ in $(seq "$REPS"); do o+=("$(ours "${oa[@]}")"); done
  local om; om=$(median "${o[@]}")
  printf '%-10s mitsuba %8.3f s (first %6.3f s)   packet-render %8.3f s   ratio %6.2fx\n' \
    "$name" "$m" "$first" "$om" "$(python3 -c "print($m/$om)")"
}
row bunny    bunny.py "$root/../shared/models/bunny.obj" 1024 1024 "$T" "$REPS" -- \
             "$root/../shared/models/bunny.obj" --width 1024 --height 1024
row dof_area dof_area.py 320 240 "$T" "$REPS" -- "$root/scenes/dof_area.toml"
row dof_area_640 dof_area.py 640 480 "$T" "$REPS" -- "$root/scenes/dof_area.toml" --width 640 --height 480
rm -rf "$out"
