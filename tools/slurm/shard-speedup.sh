#!/usr/bin/env bash
# The speed-up of a sharded bake on this machine's cores: for each shard count, every shard runs as its own
# process at once (as array tasks on one node would), each with its share of the cores as --threads, then the
# merge; the wall time of the whole is compared with one shard's, in this one run.
#
#   tools/slurm/shard-speedup.sh SCENE.json [VOXSHADOW] [SHARDS...]   (default shards: 1 2 4)
#
# Environment: VOXSHADOW_BACKEND (cpu, the default, or vulkan), VOXSHADOW_CORES (default: nproc).
set -euo pipefail
scene="${1:?usage: shard-speedup.sh SCENE.json [VOXSHADOW] [SHARDS...]}"
here="$(cd "$(dirname "$(readlink -f "${BASH_SOURCE[0]}")")" && pwd)"
voxshadow="${2:-$here/../../build/tools/voxshadow}"
shift $(($# < 2 ? $# : 2))
counts=("$@")
[ ${#counts[@]} -gt 0 ] || counts=(1 2 4)
backend="${VOXSHADOW_BACKEND:-cpu}"
cores="${VOXSHADOW_CORES:-$(nproc)}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

echo "shard-speedup: $scene, backend $backend, $cores cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
base=""
for n in "${counts[@]}"; do
  threads=$((cores / n))
  [ "$threads" -ge 1 ] || threads=1
  dir="$work/parts$n"
  mkdir -p "$dir"
  start=$(date +%s.%N)
  pids=()
  for ((k = 0; k < n; k++)); do
    "$voxshadow" bake "$scene" --shard "$k/$n" -o "$dir/shard-$k-of-$n.vspart" --backend "$backend" \
      --threads "$threads" > "$dir/log$k" 2>&1 &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || { echo "shard-speedup: a shard of $n failed:" >&2; cat "$dir"/log* >&2; exit 1; }; done
  parts=()
  for ((k = 0; k < n; k++)); do parts+=("$dir/shard-$k-of-$n.vspart"); done
  "$voxshadow" merge "${parts[@]}" -o "$work/merged$n.exr" > /dev/null
  seconds=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.3f", b - a }')
  [ -n "$base" ] || base="$seconds"
  if [ "$n" != "${counts[0]}" ] && ! cmp -s "$work/merged$n.exr" "$work/merged${counts[0]}.exr"; then
    echo "shard-speedup: the merge of $n shards differs from that of ${counts[0]}" >&2
    exit 1
  fi
  printf 'shards %2d (%d at once, --threads %d): %6.2f s, speed-up %.2fx\n' "$n" "$n" "$threads" "$seconds" \
    "$(awk -v a="$base" -v b="$seconds" 'BEGIN { print a / b }')"
done
