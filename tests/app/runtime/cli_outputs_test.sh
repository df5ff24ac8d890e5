#!/usr/bin/env bash
# The command line's outputs, checked with the kernel's own view (stat, test -p / -L):
#  - folders it creates for --record / --report are owner-only (0700) under the usual umask 022;
#  - a trace that cannot be written whole (the file-size limit standing in for a full disk) is an
#    error (exit status non-zero, the reason named) and leaves no partial trace;
#  - only a regular file is ever replaced: `export --csv -` prints to the standard output (no
#    file named "-"), a FIFO of the test's own is written in place and stays a FIFO, a symbolic
#    link is refused with the reason and left (it and its target) as it was;
#  - an HDF5 export (which HDF5 writes by seeking in a file) to "-" or a FIFO is refused with the
#    reason, the FIFO left a FIFO; one cut by the file-size limit is an error and leaves no file.
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
if "$vh" export new/deeper/s.vhrec --hdf5 - >/dev/null 2>h5-err.txt; then fail "export --hdf5 - exited 0"; fi
grep -q "regular file" h5-err.txt || fail "the refused --hdf5 - does not say why: $(cat h5-err.txt)"
[[ ! -e ./- ]] || fail "export --hdf5 - wrote a file named -"
if "$vh" export new/deeper/s.vhrec --hdf5 ticks.fifo 2>h5-err.txt; then fail "export --hdf5 to a FIFO exited 0"; fi
[[ -p ticks.fifo ]] || fail "export --hdf5 replaced the FIFO"
if (trap '' XFSZ; ulimit -f 8; exec "$vh" export new/deeper/s.vhrec --hdf5 cut.h5) >/dev/null 2>h5-err.txt; then
  fail "an HDF5 export cut by the file-size limit exited 0"
fi
grep -q "cannot write" h5-err.txt || fail "the failed HDF5 export is not named: $(cat h5-err.txt)"
[[ ! -e cut.h5 ]] || fail "a partial HDF5 file was left"
if ls -A | grep -q '^\.cut\.'; then fail "a temporary HDF5 file was left"; fi
"$vh" export new/deeper/s.vhrec --hdf5 whole.h5 >/dev/null
[[ $(stat -c %a whole.h5) == 600 ]] || fail "the HDF5 export is not 0600"
if (trap '' XFSZ; ulimit -f 8; exec "$vh" run --scene "$scene" --trajectory "$trajectory" --trace trace.csv) \
  >/dev/null 2>trace-err.txt; then
  fail "a trace cut by the file-size limit exited 0"
fi
grep -q "cannot write" trace-err.txt || fail "the failed trace is not named: $(cat trace-err.txt)"
[[ ! -e trace.csv ]] || fail "a partial trace was left ($(wc -l <trace.csv) lines)"
if ls -A | grep -q '^\.trace\.'; then fail "a temporary trace file was left"; fi
echo "cli outputs: folders 0700, '-' to stdout, FIFO in place, link refused, a cut trace an error, HDF5 only to a file"
