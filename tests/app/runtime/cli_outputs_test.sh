#!/usr/bin/env bash
# The command line's outputs, checked with the kernel's own view (stat, test -p / -L):
#  - folders it creates for --record / --report are owner-only (0700) under the usual umask 022;
#  - a trace that cannot be written whole (the file-size limit standing in for a full disk) is an
#    error (exit status non-zero, the reason named) and leaves no partial trace;
#  - only a regular file is ever replaced: `export --csv -` prints to the standard output (no
#    file named "-"), a FIFO of the test's own is written in place and stays a FIFO, a symbolic
#    link is refused with the reason and left (it and its target) as it was.
# Usage: cli_outputs_test.sh VOLUME_HAPTICS SCENE TRAJECTORY OUT_DIR
set -euo pipefail
vh="$1" scene="$2" trajectory="$3" out="$4"
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$out"
mkdir -p "$out"
cd "$out"
umask 022
"$vh" run --scene "$scene" --trajectory "$trajectory" --record new/deeper/s.vhrec --report new/deeper/r.json >/dev/null
for d in new new/deeper; do
  mode=$(stat -c %a "$d")
  [[ $mode == 700 ]] || fail "the folder $d was created $mode, not 700"
done
[[ $(stat -c %a new/deeper/r.json) == 600 ]] || fail "the report is not 0600"

"$vh" export new/deeper/s.vhrec --csv - >stdout.csv
head -1 stdout.csv | grep -q '^t_s,tick,' || fail "export --csv - printed no CSV header"
(( $(wc -l <stdout.csv) > 10 )) || fail "export --csv - printed too few rows"
[[ ! -e ./- ]] || fail "export --csv - wrote a file named -"

mkfifo ticks.fifo
cat ticks.fifo >from-fifo.csv &
reader=$!
"$vh" export new/deeper/s.vhrec --csv ticks.fifo
wait "$reader"
[[ -p ticks.fifo ]] || fail "the FIFO was replaced by a regular file"
cmp -s from-fifo.csv stdout.csv || fail "the FIFO's reader did not receive the CSV"

echo keep >real.csv
ln -s real.csv link.csv
if "$vh" export new/deeper/s.vhrec --csv link.csv 2>err.txt; then fail "a symbolic link was written through"; fi
grep -q "symbolic link" err.txt || fail "the refusal does not say why: $(cat err.txt)"
[[ -L link.csv ]] || fail "the link was replaced"
[[ $(cat real.csv) == keep ]] || fail "the link's target was written"
if (trap '' XFSZ; ulimit -f 8; exec "$vh" run --scene "$scene" --trajectory "$trajectory" --trace trace.csv) \
  >/dev/null 2>trace-err.txt; then
  fail "a trace cut by the file-size limit exited 0"
fi
grep -q "cannot write" trace-err.txt || fail "the failed trace is not named: $(cat trace-err.txt)"
[[ ! -e trace.csv ]] || fail "a partial trace was left ($(wc -l <trace.csv) lines)"
if ls -A | grep -q '^\.trace\.'; then fail "a temporary trace file was left"; fi
echo "cli outputs: folders 0700, '-' to stdout, FIFO in place, link refused, a cut trace an error"
