#!/usr/bin/env bash
# benches/tools/imgcheck.sh BASE_BIN NEW_BIN OUTDIR : renders the same images with both binaries, cmp's them.
# Exit 0 only when every PNG is byte-identical. Run from a project root (scenes/, ../shared).
set -u
B=$1; N=$2; O=$3; mkdir -p "$O/b" "$O/n"
root=$(pwd); sh=$root/../shared
fail=0; count=0
r() { # name args...
  local name=$1; shift
  "$B" render "$@" -o "$O/b/$name.png" --quiet >/dev/null 2>"$O/b/$name.err" || echo "base failed: $name"
  "$N" render "$@" -o "$O/n/$name.png" --quiet >/dev/null 2>"$O/n/$name.err" || echo "new failed: $name"
  count=$((count+1))
  if ! cmp -s "$O/b/$name.png" "$O/n/$name.png"; then echo "DIFFERS: $name ($*)"; fail=1; fi
}
for s in scenes/*.toml; do n=$(basename "$s" .toml); r "$n" "$s" --width 320 --height 240 --threads 2; done
for t in 1 2; do
  for k in 1 3 4 9; do r "dof_area_t${t}_k$k" scenes/dof_area.toml --threads $t --shadow-samples $k; done
  r "area64_t$t" "$sh/anchors/povray/scenes/whitted_area64.toml" --threads $t --width 320 --height 240
  r "blur16_t$t" "$sh/anchors/povray/scenes/whitted_blur16.toml" --threads $t --width 320 --height 240
  r "bunny_t$t" "$sh/models/bunny.obj" --threads $t --width 512 --height 512
done
r whitted_base "$sh/anchors/povray/scenes/whitted_base.toml" --threads 2 --width 320 --height 240
r area_lights_bvh2 scenes/area_lights.toml --accel bvh2 --width 160 --height 100
r dof_area_recursive scenes/dof_area.toml --integrator whitted --width 160 --height 120
echo "imgcheck: $count images compared, $([ $fail = 0 ] && echo all identical || echo SOME DIFFER)"
exit $fail
