#!/usr/bin/env bash
# `volume-haptics report` end to end, without a display: a recording made by `run --record` on
# the block-and-peg scene becomes an HTML report whose pictures a real browser engine (headless
# Chromium) decodes; a truncated copy gives a report with a notice; a reference recorded on
# another scene (the built-in sphere) is refused; a folder becomes a table.
#   report_cli_test.sh VOLUME_HAPTICS SCENE TRAJECTORY OUT_DIR
# Exit 77 (skipped) when no Chromium is installed for the browser part (packaging/setup.sh test
# installs it); everything before it has run by then.
set -euo pipefail
app=$1 scene=$2 trajectory=$3 out=$4
rm -rf "$out"; mkdir -p "$out/cohort/group"
unset DISPLAY WAYLAND_DISPLAY QT_QPA_PLATFORM
fail() { echo "FAIL: $*" >&2; exit 1; }

"$app" run --scene "$scene" --trajectory "$trajectory" --record "$out/cohort/session.vhrec" --verify-step 0 \
  --no-lag-reference >/dev/null
"$app" report "$out/cohort/session.vhrec" --html "$out/session.html" --force-threshold-N 1 \
  || fail "report of a good recording"
grep -q 'Session report: session.vhrec' "$out/session.html" || fail "no title"
images=$(grep -o 'src="data:image/png;base64,' "$out/session.html" | wc -l)
((images >= 5)) || fail "$images inline pictures, expected at least 5"
grep -q -E 'src="(https?:|file:)' "$out/session.html" && fail "the page loads something from outside"
grep -q 'over the felt surface' "$out/session.html" || fail "the contact map is not drawn over the scene's surface"

# A crash's truncated recording: a report of what could be read, with the notice.
size=$(stat -c %s "$out/cohort/session.vhrec")
head -c $((size - 3000)) "$out/cohort/session.vhrec" >"$out/cohort/group/cut.vhrec"
"$app" report "$out/cohort/group/cut.vhrec" --html "$out/cut.html" 2>"$out/cut.err" || fail "report of a truncated recording"
grep -q 'warning:.*truncated' "$out/cut.err" || fail "no warning on stderr: $(cat "$out/cut.err")"
grep -q 'Read with notices' "$out/cut.html" || fail "no notice in the truncated recording's report"

# The same scene as a reference: compared; a folder: a table with a row per recording.
"$app" report "$out/cohort/session.vhrec" --html "$out/compare.html" --reference "$out/cohort/group/cut.vhrec" \
  || fail "comparison with a reference of the same scene"
grep -q 'Against the reference cut.vhrec' "$out/compare.html" || fail "no comparison section"
# A reference recorded on another scene (the built-in sphere) is refused, naming both datasets.
sphere="$(dirname "$scene")/sphere-probe.json"
"$app" make-trajectory --scene "$sphere" --out "$out/sphere.csv" >/dev/null
"$app" run --scene "$sphere" --trajectory "$out/sphere.csv" --record "$out/sphere.vhrec" --verify-step 0 \
  --no-lag-reference >/dev/null
if "$app" report "$out/cohort/session.vhrec" --html "$out/other.html" --reference "$out/sphere.vhrec" 2>"$out/other.err"; then
  fail "a reference of another scene was accepted"
fi
grep -q 'error: the reference was recorded on another scene (dataset [0-9a-f]*, this session dataset [0-9a-f]*)' \
  "$out/other.err" || fail "refusal without its reason: $(cat "$out/other.err")"
"$app" report "$out/cohort" --table "$out/cohort.csv" 2>"$out/table.err" || fail "cohort table"
grep -q '2 of 2 recordings' "$out/table.err" || fail "no progress: $(cat "$out/table.err")"
(($(wc -l <"$out/cohort.csv") == 3)) || fail "cohort table: $(cat "$out/cohort.csv")"

# A real browser engine opens the page and decodes every picture. The page's own time is virtual
# (--virtual-time-budget); the wall-clock limit only stops a browser that hangs, and leaves a cold
# start on a busy machine its time.
browser=$(command -v chromium || command -v chromium-browser || true)
if [[ -z $browser ]]; then echo "SKIP: no Chromium for the browser check"; exit 77; fi
probe="$out/session-probe.html"
sed 's|</body>|<script>window.addEventListener("load", () => { const i = [...document.images]; document.body.insertAdjacentText("beforeend", "DECODED " + i.filter(x => x.complete \&\& x.naturalWidth > 0).length + " OF " + i.length + " SIZES " + i.map(x => x.naturalWidth + "x" + x.naturalHeight).join(",")); });</script></body>|' \
  "$out/session.html" >"$probe"
dom=$(timeout 360 "$browser" --headless --no-sandbox --disable-gpu --virtual-time-budget=5000 --dump-dom \
  "file://$probe" 2>/dev/null)
result=$(grep -o 'DECODED [0-9]* OF [0-9]* SIZES [0-9x,]*' <<<"$dom" || true)
echo "chromium: $result"
[[ $result =~ DECODED\ ([0-9]+)\ OF\ ([0-9]+) ]] || fail "the browser did not run the page"
((BASH_REMATCH[1] == BASH_REMATCH[2] && BASH_REMATCH[2] == images)) || fail "pictures the browser decoded: $result"
[[ $result =~ (SIZES\ |,)0x|x0(,|$) ]] && fail "an empty picture: $result"
echo "PASS"
