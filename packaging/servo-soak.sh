#!/bin/bash
# The haptic servo's timing in the window beside a busy machine, measured side by side with the
# machine's own wake-up latency for a real-time thread, so that a late coupling tick can be put
# down to the program or to the computer.
#
#   packaging/servo-soak.sh [MINUTES] [BUILD_DIR]        (default: 10 minutes, build)
#
# For MINUTES, all at once:
#   - the window (under Xvfb), the head phantom with the probe, a scripted device pressing on the
#     skull and sliding back and forth (the view drawing moving frames all the time), logging its
#     haptic threads' timing every second (`--servo-log`: rate, longest tick, jitter, deadline
#     misses, and the CPU time the hypervisor stole from the VM in that second);
#   - cyclictest (rt-tests): a SCHED_FIFO 80 thread of its own waking every 1 ms, as the coupling
#     thread does, whose latency histogram is what this machine gives any real-time thread;
#   - stress-ng: two CPU hogs and one process faulting in 256 MB (the "busy machine"); not with
#     VH_SOAK_LOAD=0 (the window and cyclictest alone: the quiet machine's figures).
# Then prints the coupling's and the solver's worst seconds beside cyclictest's, and writes
# summary.json, servo.jsonl and cyclictest.txt into $VH_SOAK_OUT (default BUILD_DIR/bench/servo-soak).
# Installs stress-ng and rt-tests (Debian packages) when missing. Needs root (or sudo) for
# SCHED_FIFO, as the application does.
set -euo pipefail

minutes=${1:-10}
build=${2:-build}
here=$(cd "$(dirname "$0")/.." && pwd)
app="$build/app/volume-haptics"
datasets=${VH_SHARED_DATASETS_DIR:-$here/../shared/datasets}
out=${VH_SOAK_OUT:-$build/bench/servo-soak}

if [[ ! -x "$app" ]]; then echo "servo-soak: $app is not built (cmake --build $build)" >&2; exit 2; fi
phantom="$datasets/ct/philips-head-phantom-bone"
if [[ ! -d "$phantom" ]]; then echo "servo-soak: the head phantom is absent ($phantom)" >&2; exit 2; fi
if ! [[ "$minutes" =~ ^[0-9]+$ ]] || (( minutes < 1 )); then echo "servo-soak: MINUTES must be a whole number >= 1" >&2; exit 2; fi

missing=()
command -v stress-ng > /dev/null || missing+=(stress-ng)
command -v cyclictest > /dev/null || missing+=(rt-tests)
command -v xvfb-run > /dev/null || missing+=(xvfb xauth)
if (( ${#missing[@]} )); then
  sudo_=""; [[ $(id -u) -ne 0 ]] && sudo_="sudo"
  echo "servo-soak: installing ${missing[*]}"
  $sudo_ apt-get install -y -q "${missing[@]}" > /dev/null
fi

mkdir -p "$out"
out=$(cd "$out" && pwd)
rm -f "$out/servo.jsonl" "$out/cyclictest.txt" "$out/summary.json"

# The scene, and its device's path: make-trajectory's press-and-slide on the skull, then that
# path back and forth for the whole soak.
cat > "$out/probe.json" <<EOF
{"volume": {"path": "$phantom", "isovalue": 400}, "tool": {"mesh": "builtin:probe"}, "device": {"kind": "simulated"}}
EOF
"$app" make-trajectory --scene "$out/probe.json" --out "$out/press.csv" --slide-m 0.03 > /dev/null
awk -F, -v total_s=$(( minutes * 60 + 60 )) '
  NR == 1 { header = $0; next }
  { n++; t[n] = $1; row[n] = $0; sub(/^[^,]*,/, "", row[n]) }
  END {
    print header
    T = t[n]; cycle = 0
    while (cycle * 2 * T <= total_s) {
      base = cycle * 2 * T
      for (i = (cycle ? 2 : 1); i <= n; i++) printf "%.6f,%s\n", base + t[i], row[i]
      for (i = n - 1; i >= 1; i--) printf "%.6f,%s\n", base + 2 * T - t[i], row[i]
      cycle++
    }
  }' "$out/press.csv" > "$out/soak.csv"
cat > "$out/soak.json" <<EOF
{"volume": {"path": "$phantom", "isovalue": 400}, "tool": {"mesh": "builtin:probe"},
 "device": {"kind": "scripted", "trajectory": "$out/soak.csv"}}
EOF

echo "servo-soak: $minutes min: the window and cyclictest side by side$([[ ${VH_SOAK_LOAD:-1} != 0 ]] && echo ", stress-ng beside them"); output in $out"
stress=""
if [[ ${VH_SOAK_LOAD:-1} != 0 ]]; then
  stress-ng --cpu 2 --vm 1 --vm-bytes 256M --timeout "$(( minutes * 60 + 30 ))s" --quiet &
  stress=$!
fi
cyclictest -m -p 80 -i 1000 -t 1 -q -h 20000 -D "$(( minutes * 60 ))" > "$out/cyclictest.txt" 2>&1 &
cyclic=$!
status=0
xvfb-run -a -s "-screen 0 1600x1000x24" "$app" "$out/soak.json" --servo-log "$out/servo.jsonl" \
  --screenshot "$out/window.png" --screenshot-delay-ms $(( minutes * 60000 )) > "$out/window.log" 2>&1 || status=$?
wait "$cyclic" || true
if [[ -n $stress ]]; then
  kill "$stress" 2> /dev/null || true
  wait "$stress" 2> /dev/null || true
fi
if (( status != 0 )); then echo "servo-soak: the window ended with $status (see $out/window.log)" >&2; exit 1; fi

/usr/bin/python3 - "$out" <<'EOF'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
lines = [json.loads(l) for l in (out / "servo.jsonl").read_text().splitlines() if l.strip()]
seconds = [l for l in lines if "coupling" in l][2:]  # the first two: loading, threads starting
def quantile(v, q):
    v = sorted(v); return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")
def thread(name):
    jit = [s[name]["jitter_us"] for s in seconds]; tick = [s[name]["max_tick_us"] for s in seconds]
    late = [s for s in seconds if s[name]["jitter_us"] > 1000.0]
    return {"seconds": len(seconds), "jitter_us_max": max(jit), "jitter_us_p99": quantile(jit, 0.99),
            "jitter_us_median": quantile(jit, 0.5), "max_tick_us": max(tick),
            "misses": sum(s[name]["misses"] for s in seconds), "seconds_over_1ms": len(late),
            "steal_ms_in_those_seconds": sum(s["steal_ms"] or 0.0 for s in late)}
hist, maxlat, overflow_s = {}, None, []
for l in (out / "cyclictest.txt").read_text().splitlines():
    if l.startswith("# Max Latencies:"): maxlat = int(l.split(":")[1].split()[0])
    elif l.startswith("# Thread 0:"): overflow_s = [int(c) / 1000.0 for c in l.split(":")[1].split()]
    elif l and l[0].isdigit():
        f = l.split()
        if len(f) >= 2: hist[int(f[0])] = int(f[1])
total = sum(hist.values())
def hq(q):
    acc = 0
    for us in sorted(hist):
        acc += hist[us]
        if acc >= q * total: return us
    return None
cyc = {"samples": total, "max_us": maxlat, "p99_us": hq(0.99), "p99_9_us": hq(0.999),
       "over_1ms": sum(c for us, c in hist.items() if us > 1000),
       # When its wake-ups came over 20 ms late [s from its start, about the window's start]:
       # beside the coupling's worst seconds, the same stalls or not.
       "over_20ms_at_s": overflow_s}
worst = sorted(seconds, key=lambda s: -s["coupling"]["jitter_us"])[:8]
summary = {"coupling_worst_seconds": [{"t_s": round(s["t_s"], 1), "jitter_us": s["coupling"]["jitter_us"],
                                       "steal_ms": s["steal_ms"]} for s in sorted(worst, key=lambda s: s["t_s"])],
           "coupling": thread("coupling"), "solver": thread("solver"), "cyclictest": cyc,
           "steal_ms_total": sum(s["steal_ms"] or 0.0 for s in seconds),
           "frames_per_s_mean": sum(s["frames"] for s in seconds) / max(1, len(seconds)),
           "realtime": all(s.get("realtime") for s in seconds)}
(out / "summary.json").write_text(json.dumps(summary, indent=2))
c, s_, k = summary["coupling"], summary["solver"], cyc
print(f"servo-soak: {c['seconds']} s in the window ({summary['frames_per_s_mean']:.1f} frames/s, SCHED_FIFO: {summary['realtime']})")
print(f"  coupling: worst wake-up jitter {c['jitter_us_max']:.0f} us (p99 of seconds {c['jitter_us_p99']:.0f}, median {c['jitter_us_median']:.0f}); "
      f"longest tick {c['max_tick_us']:.0f} us; {c['misses']} misses; {c['seconds_over_1ms']} seconds over 1 ms")
print(f"  solver:   worst wake-up jitter {s_['jitter_us_max']:.0f} us; longest tick {s_['max_tick_us']:.0f} us; {s_['misses']} misses")
print(f"  cyclictest (the machine alone, FIFO 80, 1 ms): max {k['max_us']} us, p99.9 {k['p99_9_us']} us, p99 {k['p99_us']} us, "
      f"{k['over_1ms']} of {k['samples']} wake-ups over 1 ms")
print("  the coupling's worst seconds [s]: " + ", ".join(f"{w['t_s']:.0f} ({w['jitter_us'] / 1000:.1f} ms)" for w in summary["coupling_worst_seconds"]))
print("  cyclictest's wake-ups over 20 ms late at [s]: " + (", ".join(f"{t:.0f}" for t in overflow_s) or "none"))
print(f"  stolen CPU time: {summary['steal_ms_total']:.0f} ms in all, {c['steal_ms_in_those_seconds']:.0f} ms in the coupling's late seconds")
EOF
