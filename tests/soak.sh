#!/usr/bin/env bash
# The whole test suite several times in a row on a loaded machine: a test that depends on the
# machine's speed or load (a frame count, a rate, a wait tighter than seconds) fails here sooner
# or later, so a suite that passes every run can be trusted not to fail CI by chance.
#
#   tests/soak.sh [BUILD_DIR] [--runs N] [--jobs J] [--load-cpus C] [-- CTEST_ARGS...]
#
#   BUILD_DIR     an already built tree (default build/ beside tests/)
#   --runs N      how many whole-suite runs, one after the other (default 3)
#   --jobs J      ctest -j J (default 2, as CI on a 2-core machine)
#   --load-cpus C busy processes beside the suite for its whole duration (default: the number
#                 of cores): stress-ng --cpu C when it is installed (Debian stress-ng), else
#                 C shell loops that spin; 0 runs unloaded
#   CTEST_ARGS    passed on to ctest (e.g. -L ui, -LE long)
#
# Writes BUILD_DIR/soak/run-K.log (ctest's output), run-K-times.txt (each test's time, slowest
# first) and summary.txt; prints one line per run and exits 1 if any test failed in any run.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="$here/../build"
runs=3
jobs=2
load_cpus="$(nproc)"
ctest_args=()
while (($#)); do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --load-cpus) load_cpus="$2"; shift 2 ;;
    --) shift; ctest_args=("$@"); break ;;
    -h|--help) sed -n '2,17p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "soak: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) build="$1"; shift ;;
  esac
done
[[ -f "$build/CTestTestfile.cmake" ]] || { echo "soak: $build is not a configured build tree" >&2; exit 2; }
build="$(cd "$build" && pwd)"
out="$build/soak"
mkdir -p "$out"

load_pids=()
stop_load() {
  ((${#load_pids[@]})) && kill "${load_pids[@]}" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap stop_load EXIT
if ((load_cpus > 0)); then
  if command -v stress-ng >/dev/null; then
    stress-ng --cpu "$load_cpus" --quiet &
    load_pids+=($!)
    load_text="stress-ng --cpu $load_cpus"
  else
    for ((i = 0; i < load_cpus; ++i)); do
      bash -c 'while :; do :; done' &
      load_pids+=($!)
    done
    load_text="$load_cpus spinning shell loops (stress-ng not installed)"
  fi
else
  load_text="none"
fi

summary="$out/summary.txt"
{
  echo "soak: $(date -u +%FT%TZ), $(nproc) cores, ctest -j $jobs ${ctest_args[*]:-}, load: $load_text"
} | tee "$summary"
any_failed=0
for ((k = 1; k <= runs; ++k)); do
  log="$out/run-$k.log"
  start=$SECONDS
  rc=0
  (cd "$build" && ctest --output-on-failure -j "$jobs" --timeout 1500 "${ctest_args[@]}") >"$log" 2>&1 || rc=$?
  took=$((SECONDS - start))
  # Each test's time from ctest's progress lines ("  12/900 Test  #34: name ....   Passed    1.23 sec").
  grep -E '^ *[0-9]+/[0-9]+ Test +#[0-9]+: ' "$log" |
    sed -E 's/^ *[0-9]+\/[0-9]+ Test +#[0-9]+: ([^ ]+) .* ([0-9.]+) sec$/\2 \1/' | sort -rn >"$out/run-$k-times.txt" || true
  result="$(grep -E 'tests passed, [0-9]+ tests failed out of' "$log" | tail -1 || true)"
  failed="$(sed -n '/The following tests FAILED:/,$p' "$log" | grep -E '^[[:space:]]+[0-9]+ - ' | sed -E 's/^[[:space:]]+[0-9]+ - //' || true)"
  line="run $k: ${result:-ctest gave no result (exit $rc)} in ${took} s"
  echo "$line" | tee -a "$summary"
  if ((rc != 0)); then
    any_failed=1
    [[ -n "$failed" ]] && sed 's/^/  failed: /' <<<"$failed" | tee -a "$summary"
  fi
done
echo "soak: $([[ $any_failed == 0 ]] && echo "0 failures in $runs runs" || echo "FAILURES (logs in $out)")" | tee -a "$summary"
exit "$any_failed"
