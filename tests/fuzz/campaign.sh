#!/usr/bin/env bash
# The long fuzz campaign (not in CI): each target in turn, one process on one core (libFuzzer
# in-process, no -jobs / -workers), for N runs
# (default 10^6), from the committed corpus; new inputs into BUILD/fuzz-corpus/TARGET (kept
# between campaigns), a crash's input into BUILD/fuzz-artifacts/TARGET/. Prints a Markdown table
# (target, runs, crashes, runs/s, corpus) and writes it to BUILD/fuzz-campaign.md.
#   tests/fuzz/campaign.sh [--build DIR] [--runs N] [--max-time S] [--keep-going] [TARGET...]
# --keep-going: libFuzzer's fork mode with one worker (-fork=1, still one core), going on after a
# crash, timeout or out-of-memory (counted; each input kept) instead of stopping at the first:
# for targets whose system library (VTK, vtk-dicom) has known crashes.
# Build first: cmake -S . -B build-fuzz -G Ninja -DVH_FUZZ=ON -DCMAKE_C_COMPILER=clang
#   -DCMAKE_CXX_COMPILER=clang++ && cmake --build build-fuzz --target vh_fuzz_targets
# Also `ctest -L fuzz_campaign` in that build (one test per target).
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="$root/build-fuzz"
runs=1000000
max_time=0
keep_going=()
targets=()
while (($#)); do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --runs) runs="$2"; shift 2 ;;
    --max-time) max_time="$2"; shift 2 ;;
    --keep-going) keep_going=(-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1); shift ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done
((${#targets[@]})) || targets=(dicom nrrd metaimage nifti mesh seg rtstruct pacs_response igtl scene trajectory recording spacemouse falcon)

table="$build/fuzz-campaign.md"
rows=()
status=0
for name in "${targets[@]}"; do
  bin="$build/tests/fuzz/fuzz_$name"
  [[ -x "$bin" ]] || { echo "campaign: $bin missing (build vh_fuzz_targets with VH_FUZZ=ON)" >&2; exit 2; }
  out="$build/fuzz-corpus/$name"
  artifacts="$build/fuzz-artifacts/$name/"
  log="$build/fuzz-logs/$name.log"
  mkdir -p "$out" "$artifacts" "$(dirname "$log")"
  dict=(); [[ -f "$here/dict/$name.dict" ]] && dict=(-dict="$here/dict/$name.dict")
  before=$(find "$artifacts" -type f | wc -l)
  echo "campaign: $name: $runs runs (log $log)"
  "$bin" -runs="$runs" -max_total_time="$max_time" -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$artifacts" "${keep_going[@]}" "${dict[@]}" "$out" "$here/corpus/$name" >"$log" 2>&1
  rc=$?
  crashes=$(( $(find "$artifacts" -type f | wc -l) - before ))
  ((rc == 0)) || status=1
  execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
  rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)"
  if ((${#keep_going[@]})); then  # fork mode: "#RUNS: cov: ... oom/timeout/crash: A/B/C time: Ss ..."
    last="$(grep -E '^#[0-9]+: cov:' "$log" | tail -1)"
    execs="$(sed -E 's/^#([0-9]+):.*/\1/' <<<"$last")"
    secs="$(sed -E 's/.* time: ([0-9]+)s.*/\1/' <<<"$last")"
    rate=$(( ${execs:-0} / (${secs:-1} > 0 ? ${secs:-1} : 1) ))
    crashes="$(sed -E 's#.*oom/timeout/crash: ([0-9]+)/([0-9]+)/([0-9]+).*#\1 oom, \2 timeouts, \3 crashes#' <<<"$last")"
  fi
  files=$(find "$out" -type f | wc -l)
  kib=$(( $(du -sk "$out" | cut -f1) ))
  row="| $name | ${execs:-?} | $crashes | ${rate:-?} | $files inputs, $kib KiB |"
  echo "campaign: $row (exit $rc)"
  rows+=("$row")
done
{
  echo "| target | executions | crashes | exec/s | corpus after |"
  echo "|---|---|---|---|---|"
  printf '%s\n' "${rows[@]}"
} | tee "$table"
exit $status
