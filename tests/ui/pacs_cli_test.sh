#!/usr/bin/env bash
# `volume-haptics pacs echo|find|get` against the io tests' Orthanc fixture (fixture.env): find
# lists the series with the dataset's file count, get brings that many files, a closed port is
# an error naming the server. Exit 77 (skipped) when the fixture has no PACS.
#   pacs_cli_test.sh VOLUME_HAPTICS FIXTURE_ENV WORK_DIR
set -uo pipefail
exe="$1"; env_file="$2"; work="$3"
[[ -f $env_file ]] || { echo "no fixture file $env_file"; exit 77; }
# shellcheck disable=SC1090
. "$env_file"
[[ ${status:-} == ready ]] || { echo "no test PACS: ${reason:-}"; exit 77; }
server=(--host "$host" --port "$dicom_port" --aet "$aet" --calling-aet "$client_aet")
fail() { echo "FAIL: $*"; exit 1; }

"$exe" pacs echo "${server[@]}" | grep -q "answers" || fail "echo"

out="$("$exe" pacs find "${server[@]}" --patient 'Aus*')" || fail "find: $out"
echo "$out"
series_line="$(echo "$out" | awk -F'\t' '$1 == "series"')"
[[ $(echo "$series_line" | wc -l) == 1 ]] || fail "find: expected one series line"
uid="$(echo "$series_line" | cut -f2)"
files="$(echo "$series_line" | cut -f9)"
[[ $files == "$instances" ]] || fail "find: the series has $files files, the dataset $instances"
[[ $(echo "$out" | awk -F'\t' '$1 == "study"' | wc -l) == 1 ]] || fail "find: expected one study"
[[ -z "$("$exe" pacs find "${server[@]}" --patient 'NOBODY*' | tail -n +2)" ]] || fail "find: NOBODY matched"

rm -rf "$work"; mkdir -p "$work"
"$exe" pacs get "$uid" --out "$work/series" "${server[@]}" || fail "get"
got=$(find "$work/series" -name '*.dcm' | wc -l)
[[ $got == "$instances" ]] || fail "get: $got files, expected $instances"

msg="$("$exe" pacs find --host 127.0.0.1 --port $((http_port + 11)) --aet "$aet" --calling-aet "$client_aet" 2>&1)" \
  && fail "find on a closed port succeeded"
echo "$msg" | grep -q "PACS $aet at 127.0.0.1:$((http_port + 11)): no connection" || fail "closed port: $msg"
rm -rf "$work"
echo "PASS: find listed 1 study, 1 series of $files files; get brought $got files; closed port: $msg"
