#!/bin/bash
# `volume-haptics --servo-log FILE` in the window (the built-in scene, its simulated device):
# a JSON line a second with each haptic thread's timing, the view's frames and the stolen CPU
# time; checked for its fields and their kinds, never for their values' sizes (the machine's
# speed and load decide those). An unwritable log is refused before anything runs.
#   servo_log_test.sh VOLUME_HAPTICS OUT_DIR
set -euo pipefail
app=$1
out=$2
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
log="$out/servo.jsonl"
rm -f "$log"

"$here/with_xvfb.sh" "$app" --screenshot "$out/servo-log.png" --screenshot-delay-ms 4000 --servo-log "$log"

/usr/bin/python3 - "$log" <<'PY'
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
assert lines, "no line in 4 s of haptics"
with_threads = [l for l in lines if "coupling" in l]
assert with_threads, "no line holds the haptic threads"
for l in lines:
    assert isinstance(l["t_s"], (int, float)) and l["t_s"] >= 0, l
    assert l["steal_ms"] is None or l["steal_ms"] >= 0, l
    assert isinstance(l["frames"], int) and l["frames"] >= 0, l
    assert ("coupling" in l) != (l.get("haptics") is False), l
for l in with_threads:
    for name in ("coupling", "solver"):
        t = l[name]
        assert t["rate_Hz"] >= 0 and t["max_tick_us"] >= 0 and t["jitter_us"] >= 0, l
        assert isinstance(t["misses"], int) and t["misses"] >= 0, l
    assert isinstance(l["realtime"], bool), l
assert any(l["coupling"]["rate_Hz"] > 0 for l in with_threads), "the coupling thread never ticked"
times = [l["t_s"] for l in lines]
assert times == sorted(times), "lines out of order"
print(f"servo log: {len(lines)} lines, {len(with_threads)} with the haptic threads")
PY

# An unwritable log: refused with its reason, exit 1, no window left running.
set +e
message=$("$here/with_xvfb.sh" "$app" --screenshot "$out/never.png" --servo-log /nonexistent-dir/servo.jsonl 2>&1)
rc=$?
set -e
[[ $rc -eq 1 ]] || { echo "an unwritable --servo-log gave rc $rc"; exit 1; }
grep -q "servo-log: cannot write /nonexistent-dir/servo.jsonl" <<< "$message" || { echo "no reason given: $message"; exit 1; }
[[ ! -e "$out/never.png" ]] || { echo "it ran though its log could not be written"; exit 1; }
echo "servo log: an unwritable log is refused"
