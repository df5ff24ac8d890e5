#!/usr/bin/env bash
# CI step of packaging/setup.sh test: builds the fuzz targets with clang (ASan, UBSan, libFuzzer)
# in their own build folder, only them and the libraries they need, and runs each briefly on the
# committed corpus. Fails when a target crashes, leaks, times out (> 10 s on one input) or
# reports undefined behaviour; the input is kept under BUILD/fuzz-artifacts/TARGET/.
#   tests/fuzz/ci.sh [BUILD_DIR]      (default build-fuzz beside build/)
# Environment: VH_FUZZ_SECONDS per target (default 15, at most 30), VH_JOBS (default nproc).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="${1:-$root/build-fuzz}"
seconds="${VH_FUZZ_SECONDS:-15}"
((seconds <= 30)) || seconds=30
jobs="${VH_JOBS:-$(nproc)}"

start=$SECONDS
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DVH_WITH_APP=ON \
  -DVH_FUZZ=ON -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ >/dev/null
cmake --build "$build" --target vh_fuzz_targets -j "$jobs"
echo "fuzz: targets built in $((SECONDS - start)) s"

failed=()
for corpus in "$here"/corpus/*/; do
  name="$(basename "$corpus")"
  bin="$build/tests/fuzz/fuzz_$name"
  work="$build/fuzz-ci/$name"          # new inputs go here, never into the source tree
  artifacts="$build/fuzz-artifacts/$name/"
  rm -rf "$work"; mkdir -p "$work" "$artifacts"
  dict=(); [[ -f "$here/dict/$name.dict" ]] && dict=(-dict="$here/dict/$name.dict")
  log="$build/fuzz-ci/$name.log"
  if "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
      -artifact_prefix="$artifacts" "${dict[@]}" "$work" "$corpus" >"$log" 2>&1; then
    execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")"
    echo "fuzz: $name: ${execs:-?} runs, no crash"
  else
    echo "fuzz: $name: FAILED (log $log; input under $artifacts)"
    grep -E "ERROR:|SUMMARY:|^ +#[0-9]+ " "$log" | head -25 || true
    failed+=("$name")
  fi
done
echo "fuzz: done in $((SECONDS - start)) s"
if ((${#failed[@]})); then
  echo "fuzz: crashes in: ${failed[*]}" >&2
  exit 1
fi
