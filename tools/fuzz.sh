#!/usr/bin/env bash
# Runs every libFuzzer target of ./build-asan (built by tools/run-sanitized.sh) in turn.
#   tools/fuzz.sh           short mode: VOXSHADOW_FUZZ_SECONDS (default 45) seconds per target
#   tools/fuzz.sh --long    1,000,000 executions per target (VOXSHADOW_FUZZ_RUNS overrides), shared out
#                           among VOXSHADOW_FUZZ_JOBS (default 1) libFuzzer jobs on one corpus
#   tools/fuzz.sh ... NAME  only the targets named (scene_file, vdb, ...)
# Each target fuzzes a working corpus in <build>/fuzz/<name>/corpus, seeded (read-only) from
# tests/fuzz/seeds/<name>/, tests/fuzz/regressions/<name>/ and ../shared/assets/<name>/ where they exist.
# A crash, leak, timeout or sanitizer report fails the script; the input is kept in
# <build>/fuzz/<name>/artifacts/ (to be added to tests/fuzz/regressions/<name>/ once understood).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${VOXSHADOW_ASAN_BUILD_DIR:-$root/build-asan}"
assets="${VOXSHADOW_ASSETS:-$root/../shared/assets}"

mode=short
names=()
for arg in "$@"; do
  case "$arg" in
    --long) mode=long ;;
    -*) echo "fuzz: unknown option $arg" >&2; exit 2 ;;
    *) names+=("$arg") ;;
  esac
done
if [ ${#names[@]} -eq 0 ]; then
  for exe in "$build"/tests/fuzz/fuzz_*; do
    case "$(basename "$exe")" in fuzz_replay_*) continue ;; esac
    [ -x "$exe" ] && names+=("$(basename "$exe" | sed 's/^fuzz_//')")
  done
fi
if [ ${#names[@]} -eq 0 ]; then
  echo "fuzz: no fuzz targets in $build/tests/fuzz (build with tools/run-sanitized.sh)" >&2
  exit 2
fi
if [ ! -d "$assets/vdb" ]; then
  echo "fuzz: third-party assets not found at $assets (expected ../shared/assets, or set VOXSHADOW_ASSETS)" >&2
  exit 2
fi

source "$root/tests/sanitizers/options.sh"
export LSAN_OPTIONS="${LSAN_OPTIONS/lsan.supp/lsan-fuzz.supp}"
# A small quarantine keeps the fuzzing process's memory small (the default 256 MB quarantine doubled the cost of
# an execution when the .vdb target forked itself for its checks; it now forks one small checking process
# before fuzzing, vs::setPersistentCheckingProcess).
export ASAN_OPTIONS="$ASAN_OPTIONS:quarantine_size_mb=16"
jobs=1
if [ "$mode" = long ]; then
  jobs="${VOXSHADOW_FUZZ_JOBS:-1}"
  case "$jobs" in '' | *[!0-9]* | 0) echo "fuzz: VOXSHADOW_FUZZ_JOBS must be a positive integer, not '$jobs'" >&2; exit 2 ;; esac
  total_runs="${VOXSHADOW_FUZZ_RUNS:-1000000}"
  # Jobs fuzz the one corpus side by side (libFuzzer -jobs), each with its share of the executions, rounded up.
  budget=(-runs="$(((total_runs + jobs - 1) / jobs))")
else
  # A fixed seed makes the short pass replay the same mutations run after run, so that CI does not turn red by
  # chance on a known finding (tests/fuzz/findings/); the long mode explores with fresh seeds.
  budget=(-max_total_time="${VOXSHADOW_FUZZ_SECONDS:-45}" -seed="${VOXSHADOW_FUZZ_SEED:-1}")
fi

status=0
summary=()
for name in "${names[@]}"; do
  exe="$build/tests/fuzz/fuzz_$name"
  [ -x "$exe" ] || { echo "fuzz: no target $exe" >&2; exit 2; }
  work="$build/fuzz/$name"
  mkdir -p "$work/corpus" "$work/artifacts"
  # OpenVDB and the targets write temporary files into TMPDIR: keep them in the build tree, away from
  # the shared assets and other processes.
  rm -rf "$work/tmp"
  mkdir -p "$work/tmp"
  seeds=()
  for dir in "$root/tests/fuzz/seeds/$name" "$root/tests/fuzz/regressions/$name" "$assets/$name"; do
    [ -d "$dir" ] && seeds+=("$dir")
  done
  flags=(-timeout=20 -rss_limit_mb=4096 -print_final_stats=1 -artifact_prefix="$work/artifacts/")
  [ -f "$root/tests/fuzz/$name.dict" ] && flags+=(-dict="$root/tests/fuzz/$name.dict")
  # Megabyte .vdb and .vox files would make each execution slow; inputs up to 64 KiB reach the header,
  # metadata, transforms, topology and chunks, where hostile files do their damage. Longer seeds are left
  # out, not cut to length (libFuzzer would cut them): the generated seeds (tests/fuzz/seeds/, written by
  # make_fuzz_seeds) and the small assets cover the same code paths; ctest replays the large assets.
  max_len=""
  case "$name" in vdb | vox) max_len=65536 ;; esac
  if [ -n "$max_len" ]; then
    rm -rf "$work/seeds"
    mkdir -p "$work/seeds"
    for dir in "${seeds[@]}"; do
      find "$dir" -type f -size -$((max_len + 1))c -exec cp --backup=numbered -t "$work/seeds" {} +
    done
    seeds=("$work/seeds")
    flags+=(-max_len="$max_len")
  fi
  # A damaged length field makes OpenVDB size a string from it and fill it before the read fails: a cap of
  # 64 MiB per request (instead of tests/fuzz/allocation_cap.cpp's 1 GiB) keeps such inputs fast, refused
  # with std::bad_alloc as the larger ones are.
  cap=""
  [ "$name" = vdb ] && cap="${VOXSHADOW_FUZZ_ALLOCATION_CAP_MB:-64}"
  echo "fuzz: $name ($mode): ${budget[*]}, corpus $work/corpus, seeds ${seeds[*]}"
  rc=0
  runs=()
  # How far 45 s gets the vdb target varies from machine to machine (about 250 executions a second under
  # ASan on a 2-core Intel Xeon, 8 when every input forked the fuzzing process): a fixed count makes its short pass
  # replay the same mutations every time, so that a finding is the same finding on every machine.
  if [ "$mode" = short ] && [ "$name" = vdb ]; then runs=(-runs="${VOXSHADOW_FUZZ_VDB_RUNS:-2000}"); fi
  job_logs=("$work/log.txt")
  if [ "$jobs" -gt 1 ]; then
    # libFuzzer writes job J's output to fuzz-J.log in the working directory.
    rm -f "$work"/fuzz-*.log
    flags+=(-jobs="$jobs" -workers="$jobs")
    job_logs=()
    for ((j = 0; j < jobs; j++)); do job_logs+=("$work/fuzz-$j.log"); done
  fi
  (cd "$work" && VOXSHADOW_FUZZ_ALLOCATION_CAP_MB="$cap" TMPDIR="$work/tmp" "$exe" "${flags[@]}" "${budget[@]}" "${runs[@]}" "$work/corpus" "${seeds[@]}") >"$work/log.txt" 2>&1 || rc=$?
  rm -rf "$work/tmp"
  runs=0
  secs=0
  for log in "${job_logs[@]}"; do
    n=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" 2>/dev/null | tail -1)
    t=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" 2>/dev/null | tail -1)
    runs=$((runs + ${n:-0}))
    [ "${t:-0}" -gt "$secs" ] && secs="$t"
  done
  if [ "$jobs" -gt 1 ] && [ "$rc" -ne 0 ]; then cat "${job_logs[@]}" >>"$work/log.txt" 2>/dev/null || true; fi
  if [ "$rc" -ne 0 ]; then
    tail -n 60 "$work/log.txt" >&2
    echo "fuzz: $name FAILED (status $rc); log $work/log.txt, input in $work/artifacts/" >&2
    summary+=("$name: FAILED")
    status=1
  else
    summary+=("$name: $runs executions in $secs s ($jobs job(s)), corpus $(ls "$work/corpus" | wc -l) inputs")
  fi
done
printf 'fuzz: %s\n' "${summary[@]}"
exit "$status"
