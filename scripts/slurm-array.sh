#!/usr/bin/env bash
#SBATCH --job-name=packet-render
#SBATCH --cpus-per-task=1
#
# Renders one frame on a Slurm cluster as a job array: task I of N renders the I-th of
# N balanced bands of rows (`packet-render render --tile I/N`) to a partial image, and a
# merge job, submitted with --dependency=afterok on the whole array, assembles them
# (`packet-render merge`) once every task has succeeded. The merged image is bit for
# bit the image one process renders (docs/distributed.md).
#
# Usage, from a directory every node sees (the partial images go next to OUT):
#   scripts/slurm-array.sh SCENE OUT N [render options, e.g. --width 640 --spp 16]
# Environment:
#   PACKET_RENDER  the binary (default: packet-render on PATH, else target/release/)
#   SBATCH_EXTRA   more sbatch options for both jobs (e.g. "--partition=batch")
#   MERGE=0        submit the array only (an early round of samples, see below)
# Prints the job ids; the merge job's log is OUT.parts/merge.log.
#
# Rounds of samples: with --sample-range a..b among the render options, the parts are
# named tile-I.sa-b.partial, and the merge takes every part in OUT.parts, so a later
# array can add samples to the frame:
#   MERGE=0 scripts/slurm-array.sh scene.toml frame.png 8 --spp 64 --sample-range 0..16
#   scripts/slurm-array.sh scene.toml frame.png 8 --spp 64 --sample-range 16..64
set -euo pipefail

if [ -z "${SLURM_JOB_ID:-}" ]; then
    # Submission (on the login node).
    if [ $# -lt 3 ]; then
        sed -n '/^# Usage/,/^# Prints/p' "$0" >&2
        exit 2
    fi
    scene=$(realpath "$1") out=$(realpath -m "$2") n=$3
    shift 3
    case $n in '' | *[!0-9]* | 0) echo "N must be a positive integer, got '$n'" >&2; exit 2 ;; esac
    bin=${PACKET_RENDER:-$(command -v packet-render || echo "$(dirname "$0")/../target/release/packet-render")}
    bin=$(realpath "$bin")
    work="$out.parts"
    mkdir -p "$work"
    tag=""
    prev=""
    for a in "$@"; do
        [ "$prev" = --sample-range ] && tag=".s${a/../-}"
        case $a in --sample-range=*) r=${a#*=} && tag=".s${r/../-}" ;; esac
        prev=$a
    done
    # shellcheck disable=SC2086 # SBATCH_EXTRA is a list of options
    array=$(sbatch --parsable ${SBATCH_EXTRA:-} --array="0-$((n - 1))" --job-name=pr-tile \
        --output="$work/tile-%a$tag.log" "$0" tile "$bin" "$scene" "$work" "$n" "$tag" "$@")
    array=${array%%;*} # "id;cluster" on multi-cluster setups
    if [ "${MERGE:-1}" = 0 ]; then
        echo "array job $array (${n} tiles), no merge -> $work"
        exit 0
    fi
    # shellcheck disable=SC2086
    merge=$(sbatch --parsable ${SBATCH_EXTRA:-} --dependency="afterok:$array" --kill-on-invalid-dep=yes \
        --job-name=pr-merge --output="$work/merge.log" "$0" merge "$bin" "$out" "$work")
    echo "array job $array (${n} tiles), merge job ${merge%%;*} -> $out"
    exit 0
fi

# Inside a job (sbatch runs a copy of this script, so everything comes as arguments).
mode=$1
shift
case $mode in
tile)
    bin=$1 scene=$2 work=$3 n=$4 tag=$5
    shift 5
    i=$SLURM_ARRAY_TASK_ID
    exec "$bin" render "$scene" -o "$work/tile-$i$tag.partial" --tile "$i/$n" \
        --threads "${SLURM_CPUS_PER_TASK:-1}" "$@"
    ;;
merge)
    bin=$1 out=$2 work=$3
    # Every part of every round; merge refuses overlaps and gaps, naming the files.
    exec "$bin" merge "$work"/tile-*.partial -o "$out"
    ;;
*)
    echo "unknown mode '$mode'" >&2
    exit 2
    ;;
esac
