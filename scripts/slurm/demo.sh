#!/usr/bin/env bash
# The run recorded in docs/distributed.md: a 4-task Slurm job array renders a frame in
# bands, a dependent job merges them, and the result is compared byte for byte with a
# single-process render. Needs a running cluster (scripts/slurm/single-node.sh start)
# and a release build (cargo build --release). Usage: scripts/slurm/demo.sh [WORKDIR]
set -uo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
work=$(realpath -m "${1:-/tmp/slurm-demo}")
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
export PACKET_RENDER=${PACKET_RENDER:-$repo/target/release/packet-render}
scene=$repo/scenes/dof_area.toml
opts=(--width 320 --height 240 --spp 16 --seed 1)
say() { echo "\$ $*"; }
say sinfo; sinfo
say scripts/slurm-array.sh scenes/dof_area.toml frame.png 4 "${opts[@]}"
submitted=$("$repo/scripts/slurm-array.sh" "$scene" "$work/frame.png" 4 "${opts[@]}")
echo "$submitted"
array=$(echo "$submitted" | awk '{print $3}') merge=$(echo "$submitted" | awk '{print $8}')
say squeue; squeue
while [ -n "$(squeue -h)" ]; do sleep 1; done
say "scontrol show job ... (once the queue is empty)"
scontrol show job -o | tr ' ' '\n' |
    grep -E '^(JobId|ArrayJobId|ArrayTaskId|JobName|JobState|ExitCode|StartTime|EndTime)=' |
    paste -sd' ' | sed 's/ JobId=/\nJobId=/g' |
    awk -v a="$array" -v m="$merge" '$0 ~ "ArrayJobId=" a " " || $0 ~ "^JobId=" m " "'
say ls -l frame.png frame.png.parts; (cd "$work" && ls -l frame.png frame.png.parts | awk 'NF > 5 {print $5, $9}')
say tail -n 3 frame.png.parts/tile-0.log; tail -n 3 frame.png.parts/tile-0.log
say packet-render render scenes/dof_area.toml -o single.png "${opts[@]}" --quiet
"$PACKET_RENDER" render "$scene" -o single.png "${opts[@]}" --quiet
say cmp frame.png single.png; cmp frame.png single.png && echo identical
say packet-render render scenes/dof_area.toml -o single.partial "${opts[@]}" --quiet
"$PACKET_RENDER" render "$scene" -o single.partial "${opts[@]}" --quiet
say packet-render merge frame.png.parts/tile-{0..3}.partial -o merged.partial
"$PACKET_RENDER" merge frame.png.parts/tile-{0..3}.partial -o merged.partial
say cmp merged.partial single.partial; cmp merged.partial single.partial && echo identical
say packet-render merge frame.png.parts/tile-{0,1,3}.partial -o bad.png
"$PACKET_RENDER" merge frame.png.parts/tile-{0,1,3}.partial -o bad.png; echo "exit status $?"
# Two rounds of samples: a first array without a merge, a second that merges both.
wait_queue() { while [ -n "$(squeue -h)" ]; do sleep 1; done; }
say MERGE=0 scripts/slurm-array.sh scenes/dof_area.toml rounds.png 3 "${opts[@]}" --sample-range 0..6
MERGE=0 "$repo/scripts/slurm-array.sh" "$scene" "$work/rounds.png" 3 "${opts[@]}" --sample-range 0..6
wait_queue
say scripts/slurm-array.sh scenes/dof_area.toml rounds.png 3 "${opts[@]}" --sample-range 6..16
"$repo/scripts/slurm-array.sh" "$scene" "$work/rounds.png" 3 "${opts[@]}" --sample-range 6..16
wait_queue
say ls rounds.png.parts; (cd "$work/rounds.png.parts" && ls -- *.partial)
say cmp rounds.png single.png; cmp rounds.png single.png && echo identical
