#!/usr/bin/env bash
# `volume-haptics pacs echo|find|get` against the io tests' Orthanc fixture (fixture.env): find
# lists the series with the dataset's file count, get brings that many files, a closed port is
# an error naming the server; with the DICOM TLS fixture (TLS_FIXTURE_ENV), echo and find over
# --tls with its CA, and a refusal naming the certificate with another CA. Exit 77 (skipped)
# when the fixture has no PACS.
#   pacs_cli_test.sh VOLUME_HAPTICS FIXTURE_ENV WORK_DIR [TLS_FIXTURE_ENV]
set -uo pipefail
exe="$1"; env_file="$2"; work="$3"; tls_env="${4:-}"
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

[[ -n $tls_env && -f $tls_env ]] || { echo "no DICOM TLS fixture file: TLS not checked"; exit 0; }
tls_values="$(cat "$tls_env")"
get() { echo "$tls_values" | sed -n "s/^$1=//p"; }
[[ $(get status) == ready ]] || { echo "no DICOM TLS test PACS: $(get reason)"; exit 0; }
tls_server=(--host 127.0.0.1 --port "$(get dicom_port)" --aet "$(get aet)" --calling-aet "$(get client_aet)" --tls)
"$exe" pacs echo "${tls_server[@]}" --ca-cert "$(get ca_cert)" | grep -q "answers" || fail "TLS echo"
tls_find="$("$exe" pacs find "${tls_server[@]}" --ca-cert "$(get ca_cert)")" || fail "TLS find: $tls_find"
[[ $(echo "$tls_find" | awk -F'\t' '$1 == "series" {print $9}') == "$(get instances)" ]] || fail "TLS find: $tls_find"
msg="$("$exe" pacs echo "${tls_server[@]}" --ca-cert "$(get other_ca_cert)" 2>&1)" && fail "TLS echo with another CA succeeded"
echo "$msg" | grep -q "the server's certificate was refused: self-signed certificate in certificate chain" ||
  fail "another CA: $msg"
echo "PASS: TLS echo and find with the server's CA; another CA: $msg"
