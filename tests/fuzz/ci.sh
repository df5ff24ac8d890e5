#!/usr/bin/env bash
# CI step of packaging/setup.sh test: builds the fuzz targets with clang (ASan, UBSan, libFuzzer)
# in their own build folder, only them and the libraries they need, and runs each briefly on the
# committed corpus (libFuzzer fork mode with one worker, going on past a crash).
# Each crash, timeout (> 10 s on one input) or out-of-memory (> 2 GB) is replayed and judged by
# its stack: in the project's code (a vh:: frame, the target, or a UBSan report) it fails the
# step; inside a system library (VTK 9.1, vtk-dicom 0.8.14, DCMTK 3.6.7, libOpenIGTLink 1.11: its
# first named frame there; known ones in docs/developing.md "Fuzzing") it is
# listed as a warning, as is an out-of-memory over the RSS limit that names no allocation. The inputs are kept under BUILD/fuzz-artifacts/TARGET/.
#   tests/fuzz/ci.sh [BUILD_DIR]      (default build-fuzz beside build/)
# Environment: VH_FUZZ_SECONDS per target (default 15, at most 30), VH_JOBS (default nproc: the
# build's jobs, and how many targets fuzz at once),
# VH_FUZZ_TARGETS (names, e.g. "seg igtl": build and run only those; default every target with
# a folder in corpus/).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="${1:-$root/build-fuzz}"
seconds="${VH_FUZZ_SECONDS:-15}"
((seconds <= 30)) || seconds=30
jobs="${VH_JOBS:-$(nproc)}"

# "project" or "system": where the first named frame of a replayed crash lies.
where() {
  awk '/runtime error:/ { print "project"; exit }
       /out-of-memory \(used:/ { print "unclassified (RSS limit)"; exit }
       /^ *#[0-9]+ / { if ($0 ~ /libvtk|vtkmetaio| in vtk|libdcm|libOpenIGTLink/) { print "system"; exit }
                       if ($0 ~ / in vh::|LLVMFuzzerTestOneInput|\/app\/|\/haptics\/|\/datasets\//) { print "project"; exit } }
       END { }'
}

start=$SECONDS
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DVH_WITH_APP=ON \
  -DVH_FUZZ=ON -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ >/dev/null
names=()
if [[ -n "${VH_FUZZ_TARGETS:-}" ]]; then
  read -r -a names <<<"$VH_FUZZ_TARGETS"
  build_targets=("${names[@]/#/fuzz_}")
else
  for corpus in "$here"/corpus/*/; do names+=("$(basename "$corpus")"); done
  build_targets=(vh_fuzz_targets)
fi
cmake --build "$build" --target "${build_targets[@]}" -j "$jobs"
echo "fuzz: targets built in $((SECONDS - start)) s"

# One target: its run, then each input it kept replayed alone and judged. Prints its report
# and exits 1 when the project's code failed (or the fuzzer did not run).
fuzz_one() {
  local name="$1"
  local corpus="$here/corpus/$name"
  local bin="$build/tests/fuzz/fuzz_$name"
  local work="$build/fuzz-ci/$name"          # new inputs go here, never into the source tree
  local artifacts="$build/fuzz-artifacts/ci-$name/"
  rm -rf "$work" "$artifacts"; mkdir -p "$work" "$artifacts"
  local dict=(); [[ -f "$here/dict/$name.dict" ]] && dict=(-dict="$here/dict/$name.dict")
  local log="$build/fuzz-ci/$name.log"
  "$bin" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 -max_total_time="$seconds" \
    -timeout=10 -rss_limit_mb=2048 -artifact_prefix="$artifacts" "${dict[@]}" "$work" "$corpus" \
    >"$log" 2>&1 || true
  local last; last="$(grep -E '^#[0-9]+: cov:' "$log" | tail -1 || true)"
  if [[ -z "$last" ]]; then
    echo "fuzz: $name: FAILED to run (log $log)"; tail -20 "$log"; return 1
  fi
  local runs; runs="$(sed -E 's/^#([0-9]+):.*/\1/' <<<"$last")"
  local project=0 system=0 input rc out w
  for input in "$artifacts"*; do
    [[ -f "$input" ]] || continue
    rc=0; out="$(timeout 60 "$bin" -timeout=10 -rss_limit_mb=2048 "$input" 2>&1)" || rc=$?
    w="$(where <<<"$out")"
    ((rc != 0)) || w="unclassified (does not fail when replayed alone)"
    if [[ "$w" == system || "$w" == unclassified* ]]; then
      system=$((system + 1))
      echo "fuzz: $name: warning: $(basename "$input") fails inside a system library ($w):"
    else
      project=$((project + 1))
      echo "fuzz: $name: FAILED: $(basename "$input") (kept in $artifacts):"
    fi
    grep -E "ERROR:|SUMMARY:|runtime error:|terminate called|what\(\)" <<<"$out" | head -3 | sed 's/^/    /' || true
    grep -E "^ +#[0-9]+ .*( in vtk| in vh::|libvtk|libdcm|libOpenIGTLink|LLVMFuzzerTestOneInput)" <<<"$out" | head -4 | cut -c1-200 | sed 's/^/    /' || true
  done
  echo "fuzz: $name: $runs runs; $project failures in the project's code, $system inside system libraries"
  ((project == 0))
}

# The targets run VH_JOBS at a time (each fuzzer is one process on one core); each one's report
# is printed whole, in the targets' order.
mkdir -p "$build/fuzz-ci"
for name in "${names[@]}"; do
  while (($(jobs -rp | wc -l) >= jobs)); do wait -n || true; done
  ( if fuzz_one "$name" >"$build/fuzz-ci/$name.report" 2>&1; then echo 0; else echo 1; fi \
      >"$build/fuzz-ci/$name.status" ) &
done
wait
failed=()
for name in "${names[@]}"; do
  cat "$build/fuzz-ci/$name.report"
  [[ "$(cat "$build/fuzz-ci/$name.status" 2>/dev/null)" == 0 ]] || failed+=("$name")
done
echo "fuzz: done in $((SECONDS - start)) s"
if ((${#failed[@]})); then
  echo "fuzz: failures in: ${failed[*]}" >&2
  exit 1
fi
