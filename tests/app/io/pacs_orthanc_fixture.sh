#!/usr/bin/env bash
# A real PACS for the PACS client's tests: Orthanc (Debian package `orthanc`) run from the build
# tree on free ports, holding the shared small CT head. ctest runs `start` as a FIXTURES_SETUP
# test and `stop` as its FIXTURES_CLEANUP test, so Orthanc is killed even when a test fails.
#
#   pacs_orthanc_fixture.sh start STATE_DIR DATASET_DIR [ORTHANC] [STORESCU] [tls]
#   pacs_orthanc_fixture.sh stop STATE_DIR
#
# With `tls`, Orthanc's DICOM port speaks DICOM TLS only ("DicomTlsEnabled", Orthanc >= 1.9.0):
# the openssl command makes a throwaway CA, a server certificate it signs for localhost and
# 127.0.0.1, a client certificate, and a second, unrelated CA, in STATE_DIR/tls; the dataset is
# then stored through Orthanc's REST API (curl), as storescu would need TLS itself: its first
# four files, enough for a study to find.
#
# STATE_DIR receives orthanc.json (its own configuration: storage in STATE_DIR/db, HTTP on the
# loopback only, no authentication, the tests' AE titles as known modalities), orthanc.log, and
# fixture.env, which the tests read:
#   status=ready|unavailable  reason=...  (unavailable: Orthanc or the dataset is absent; the
#   tests then skip, saying why) host=127.0.0.1 dicom_port=N http_port=N aet=VHPACS
#   client_aet=VHTEST instances=93 dataset=DATASET_DIR pid=N; with tls also ca_cert=,
#   other_ca_cert=, client_cert=, client_key= (PEM files).
# The dataset is stored with DCMTK's storescu (C-STORE), independently of the code under test.
set -uo pipefail

readonly kPacsAet=VHPACS        # the server's AE title (Orthanc's DicomAet)
readonly kClientAet=VHTEST      # the AE title the tests call from (a known modality: C-FIND, C-GET)
readonly kStoreAet=VHSTORE      # storescu's AE title (stores are allowed from any AE)

mode="${1:-}"
state="${2:-}"
[[ -n $mode && -n $state ]] || { echo "usage: $0 start STATE_DIR DATASET_DIR [ORTHANC] [STORESCU] | stop STATE_DIR" >&2; exit 2; }
state="$(realpath -m "$state")"  # one spelling, so that stop finds the Orthanc that start began
env_file="$state/fixture.env"
pid_file="$state/orthanc.pid"

# True when something listens on 127.0.0.1:$1 (bash's /dev/tcp; no other tool needed).
port_in_use() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

# Kills the Orthanc this fixture started (its pid file, checked to be Orthanc on our config).
stop_orthanc() {
  [[ -f $pid_file ]] || return 0
  local pid; pid="$(cat "$pid_file")"
  if [[ -n $pid && -r /proc/$pid/cmdline ]] && tr '\0' ' ' <"/proc/$pid/cmdline" | grep -q -- "$state/orthanc.json"; then
    kill "$pid" 2>/dev/null
    for _ in $(seq 1 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null && echo "orthanc fixture: Orthanc $pid did not stop in 10 s; killed"
  fi
  rm -f "$pid_file"
}

unavailable() {
  printf 'status=unavailable\nreason=%s\n' "$1" >"$env_file"
  echo "orthanc fixture: $1; the PACS tests will be skipped"
  exit 0
}

case "$mode" in
  stop)
    stop_orthanc
    rm -rf "$state/db" "$state/tls"
    [[ -d $state ]] && printf 'status=unavailable\nreason=the test PACS was stopped (run the tests through ctest)\n' >"$env_file"
    echo "orthanc fixture: stopped"
    exit 0
    ;;
  start) ;;
  *) echo "$0: unknown mode '$mode'" >&2; exit 2 ;;
esac

dataset="${3:-}"
orthanc="${4:-}"; [[ -n $orthanc ]] || orthanc="$(command -v Orthanc || echo /usr/sbin/Orthanc)"
storescu="${5:-}"; [[ -n $storescu ]] || storescu="$(command -v storescu || true)"
tls="${6:-}"
mkdir -p "$state"
stop_orthanc  # a previous run's server, if its cleanup never ran
rm -rf "$state/db" "$state/tls" "$env_file"

[[ -x $orthanc ]] || unavailable "Orthanc is not installed (Debian package orthanc; packaging/setup.sh test installs it)"
[[ -x $storescu ]] || unavailable "storescu is not installed (Debian package dcmtk; packaging/setup.sh test installs it)"
command -v curl >/dev/null || unavailable "curl is not installed (packaging/setup.sh test installs it)"
[[ -d $dataset ]] || unavailable "shared dataset missing: $dataset"
mapfile -t files < <(find "$dataset" -maxdepth 1 -type f -name '*.dcm' | sort)
((${#files[@]} > 0)) || unavailable "no .dcm files in $dataset"
[[ ${6:-} == tls ]] && files=("${files[@]:0:4}")
instances=${#files[@]}

tls_config=""
if [[ $tls == tls ]]; then
  command -v openssl >/dev/null || unavailable "the openssl command is not installed (Debian package openssl)"
  version="$("$orthanc" --version 2>/dev/null | sed -n '1s/^[^ ]* \([0-9.]*\).*/\1/p')"  # "PATH 1.10.1"
  [[ -n $version && $(printf '%s\n1.9.0\n' "$version" | sort -V | head -n 1) == 1.9.0 ]] ||
    unavailable "Orthanc ${version:-?} has no DICOM TLS (it needs 1.9.0 or later)"
  t="$state/tls"; mkdir -p "$t"
  # A CA, a server certificate it signs (for the names the tests connect to), a client one, and
  # a second CA that signed nothing here. Throwaway keys: two days, no passphrase.
  make_ca() {
    openssl req -x509 -newkey rsa:2048 -nodes -days 2 -keyout "$t/$1.key" -out "$t/$1.crt" -subj "/CN=$2" \
      -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign
  }
  sign() {  # name, common name, extensions
    openssl req -newkey rsa:2048 -nodes -keyout "$t/$1.key" -out "$t/$1.csr" -subj "/CN=$2" &&
      printf '%s\n' "$3" >"$t/$1.ext" &&
      openssl x509 -req -in "$t/$1.csr" -CA "$t/ca.crt" -CAkey "$t/ca.key" -CAcreateserial -days 2 \
        -extfile "$t/$1.ext" -out "$t/$1.crt"
  }
  if ! { make_ca ca "VolumeHaptics test CA" && make_ca other-ca "Another test CA" &&
         sign server localhost $'subjectAltName=DNS:localhost,IP:127.0.0.1\nextendedKeyUsage=serverAuth' &&
         sign client "$kClientAet" "extendedKeyUsage=clientAuth"; } >"$t/openssl.log" 2>&1; then
    echo "orthanc fixture: openssl failed:" >&2; cat "$t/openssl.log" >&2; exit 1
  fi
  tls_config="
  \"DicomTlsEnabled\" : true,
  \"DicomTlsCertificate\" : \"$t/server.crt\",
  \"DicomTlsPrivateKey\" : \"$t/server.key\",
  \"DicomTlsTrustedCertificates\" : \"$t/ca.crt\",
  \"DicomTlsRemoteCertificateRequired\" : false,"
fi

started=""
for attempt in 1 2 3 4 5 6 7 8; do
  # Two free ports in the dynamic range, different on each try.
  dicom_port=$((20000 + (RANDOM * 32768 + RANDOM) % 40000))
  http_port=$((dicom_port + 1))
  if port_in_use "$dicom_port" || port_in_use "$http_port"; then continue; fi
  cat >"$state/orthanc.json" <<EOF
{
  "Name" : "VolumeHaptics test PACS",
  "StorageDirectory" : "$state/db",
  "IndexDirectory" : "$state/db",
  "StorageCompression" : false,
  "Plugins" : [],
  "HttpServerEnabled" : true,
  "HttpPort" : $http_port,
  "RemoteAccessAllowed" : false,
  "AuthenticationEnabled" : false,
  "SslEnabled" : false,
  "HttpThreadsCount" : 4,
  "DicomServerEnabled" : true,$tls_config
  "DicomAet" : "$kPacsAet",
  "DicomPort" : $dicom_port,
  "DicomCheckCalledAet" : true,
  "DicomCheckModalityHost" : false,
  "DicomAlwaysAllowEcho" : true,
  "DicomAlwaysAllowStore" : true,
  "DicomAlwaysAllowFind" : false,
  "DicomAlwaysAllowGet" : false,
  "DicomAlwaysAllowMove" : false,
  "DicomThreadsCount" : 2,
  "DicomModalities" : {
    "volume-haptics-tests" : {
      "AET" : "$kClientAet", "Host" : "127.0.0.1", "Port" : 104,
      "AllowEcho" : true, "AllowFind" : true, "AllowGet" : true, "AllowMove" : false, "AllowStore" : true
    }
  },
  "SaveJobs" : false,
  "LuaScripts" : [],
  "StableAge" : 1
}
EOF
  setsid "$orthanc" --no-jobs --logfile="$state/orthanc.log" "$state/orthanc.json" </dev/null >/dev/null 2>&1 &
  echo $! >"$pid_file"
  # Up to 60 s: an Orthanc that lost its port exits at once (kill -0 ends the wait), so the
  # wait is only long for one that is alive but slow to start on a loaded machine.
  for _ in $(seq 1 600); do
    kill -0 "$(cat "$pid_file")" 2>/dev/null || break
    # Our server (its name), not another one that took the port meanwhile.
    if curl -s --max-time 5 "http://127.0.0.1:$http_port/system" 2>/dev/null | grep -q '"DicomAet" : "'"$kPacsAet"'"' \
       && port_in_use "$dicom_port"; then
      started=yes; break
    fi
    sleep 0.1
  done
  [[ -n $started ]] && break
  echo "orthanc fixture: Orthanc did not come up on ports $dicom_port/$http_port (try $attempt); log tail:"
  tail -n 5 "$state/orthanc.log" 2>/dev/null
  stop_orthanc
done
[[ -n $started ]] || { echo "orthanc fixture: Orthanc would not start; see $state/orthanc.log" >&2; exit 1; }

t0_us=${EPOCHREALTIME/./}
if [[ $tls == tls ]]; then
  for f in "${files[@]}"; do
    curl -s --fail --max-time 30 -X POST --data-binary "@$f" "http://127.0.0.1:$http_port/instances" \
      >>"$state/store.log" 2>&1 || { echo "orthanc fixture: storing $f over HTTP failed" >&2; stop_orthanc; exit 1; }
  done
elif ! "$storescu" -aet "$kStoreAet" -aec "$kPacsAet" --no-halt 127.0.0.1 "$dicom_port" "$dataset"/*.dcm \
     >"$state/storescu.log" 2>&1; then
  echo "orthanc fixture: storescu failed:" >&2; tail -n 20 "$state/storescu.log" >&2
  stop_orthanc; exit 1
fi
stored=$(curl -s --max-time 30 "http://127.0.0.1:$http_port/statistics" | sed -n 's/.*"CountInstances" : \([0-9]*\).*/\1/p')
if [[ $stored != "$instances" ]]; then
  echo "orthanc fixture: $instances files sent, Orthanc holds ${stored:-?} instances" >&2
  stop_orthanc; exit 1
fi
store_ms=$(( (${EPOCHREALTIME/./} - t0_us) / 1000 ))
echo "orthanc fixture: Orthanc $(cat "$pid_file") on DICOM${tls:+ TLS} port $dicom_port, HTTP port $http_port;" \
  "stored $stored instances in $store_ms ms"
cat >"$env_file" <<EOF
status=ready
host=127.0.0.1
dicom_port=$dicom_port
http_port=$http_port
aet=$kPacsAet
client_aet=$kClientAet
instances=$stored
dataset=$dataset
pid=$(cat "$pid_file")
EOF
if [[ $tls == tls ]]; then
  printf 'ca_cert=%s\nother_ca_cert=%s\nclient_cert=%s\nclient_key=%s\n' \
    "$state/tls/ca.crt" "$state/tls/other-ca.crt" "$state/tls/client.crt" "$state/tls/client.key" >>"$env_file"
fi
