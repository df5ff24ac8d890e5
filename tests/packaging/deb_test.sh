#!/usr/bin/env bash
# The Debian package (packaging/CMakeLists.txt): `cpack -G DEB` from the build tree,
# unpacked with dpkg-deb into a temporary root, must hold the program, its worker, the desktop
# entry, the icon, the .vhrec MIME type, the man page, the udev rules and the copyright; its
# Depends must be computed from the shared libraries; and the unpacked program must run --help,
# a headless run on an installed scene, open every installed scene, and load an NRRD through its
# own (unpacked) worker, without naming the build machine's folders; bench's default output lies
# under the user's data folder; the Description has no stray ';'.
#   usage: [CPACK=/path/to/cpack] deb_test.sh BUILD_DIR SOURCE_DIR
# Exit 77 (skipped, with a message) when a Debian packaging tool is missing.
set -euo pipefail
build="$(cd "$1" && pwd)"
source_dir="$(cd "$2" && pwd)"

cpack="${CPACK:-cpack}"  # ctest passes the cpack of the CMake that configured the build
for tool in "$cpack" dpkg-deb dpkg-shlibdeps help2man perl; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "SKIPPED: the package test needs $tool (Debian: cmake, dpkg-dev, help2man, perl; packaging/setup.sh test installs them)"
    exit 77
  fi
done

tmp="$(mktemp -d "${TMPDIR:-/tmp}/vh-deb-test.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "---- $*"; }

# ---- build the package (outside the build tree, so that parallel tests never see it) ----
step "cpack -G DEB"
t0=$(date +%s)
if ! "$cpack" -G DEB -B "$tmp/cpack" --config "$build/CPackConfig.cmake" >"$tmp/cpack.log" 2>&1; then
  cat "$tmp/cpack.log"; fail "cpack -G DEB failed"
fi
t1=$(date +%s)
debs=("$tmp"/cpack/volume-haptics_*.deb)
[[ ${#debs[@]} -eq 1 && -f ${debs[0]} ]] || { cat "$tmp/cpack.log"; fail "no volume-haptics_*.deb in $tmp/cpack"; }
deb="${debs[0]}"
echo "cpack: $(basename "$deb"), $(du -k "$deb" | cut -f1) KiB, $((t1 - t0)) s"

# ---- control data: computed Depends ----
step "dpkg-deb -I"
dpkg-deb -I "$deb" >"$tmp/info"
sed -n '/^ [A-Z][A-Za-z-]*:/,$p' "$tmp/info"
depends="$(sed -n 's/^ Depends: //p' "$tmp/info")"
[[ -n $depends ]] || fail "the package has no Depends"
for lib in 'libc6 ' 'libqt6' 'libvtk' 'libstdc++6' 'libhidapi-hidraw0' 'libusb-1.0-0' 'libsndfile1'; do
  [[ $depends == *"$lib"* ]] || fail "Depends lacks $lib (dpkg-shlibdeps did not see the shared libraries?): $depends"
done
grep -q '^ Section: science' "$tmp/info" || fail "Section is not science"
grep -q '^ Package: volume-haptics$' "$tmp/info" || fail "the package is not named volume-haptics"
# The Description as dpkg shows it: no stray ';' (a CMake list written as one string).
description="$(sed -n '/^ Description:/,/^ [A-Z][A-Za-z-]*:/p' "$tmp/info")"
[[ -n $description ]] || fail "the package has no Description"
[[ $description != *';'* ]] || fail "the Description carries a ';': $description"

# ---- contents ----
step "dpkg-deb -c"
dpkg-deb -c "$deb" | awk '{print $1, $3, $6}'
root="$tmp/root"
dpkg-deb -x "$deb" "$root"
for f in usr/bin/volume-haptics \
         usr/libexec/volume-haptics/volume-haptics-dicom-worker \
         usr/share/applications/volume-haptics.desktop \
         usr/share/icons/hicolor/scalable/apps/volume-haptics.svg \
         usr/share/mime/packages/volume-haptics.xml \
         usr/share/man/man1/volume-haptics.1.gz \
         usr/lib/udev/rules.d/70-volume-haptics.rules \
         usr/share/doc/volume-haptics/copyright \
         usr/share/volume-haptics/scenes/sphere-probe.json \
         usr/share/volume-haptics/scenes/sphere-drill.json; do
  [[ -f $root/$f ]] || fail "the package lacks /$f"
done
[[ -x $root/usr/bin/volume-haptics && -x $root/usr/libexec/volume-haptics/volume-haptics-dicom-worker ]] ||
  fail "the programs are not executable"
zcat "$root/usr/share/man/man1/volume-haptics.1.gz" | grep -q '^\.TH VOLUME-HAPTICS "1"' || fail "the man page has no .TH header"
zcat "$root/usr/share/man/man1/volume-haptics.1.gz" | grep -q 'run' || fail "the man page does not mention run"
grep -q 'TAG+="uaccess"' "$root/usr/lib/udev/rules.d/70-volume-haptics.rules" || fail "the udev rules give nothing to the seat's user"
# Real-time scheduling for the servo loop: the group's limits, as a conffile, and the group made.
limits="$root/etc/security/limits.d/95-volume-haptics-realtime.conf"
[[ -f $limits ]] || fail "the package lacks the real-time limits file"
grep -Eq '^@volume-haptics +- +rtprio +80$' "$limits" || fail "the limits file does not grant rtprio 80 to the group"
dpkg-deb -e "$deb" "$tmp/control"
grep -qx /etc/security/limits.d/95-volume-haptics-realtime.conf "$tmp/control/conffiles" ||
  fail "the limits file is not a conffile"
grep -q 'groupadd --system volume-haptics' "$tmp/control/postinst" || fail "postinst does not create the group"
if command -v desktop-file-validate >/dev/null 2>&1; then
  desktop-file-validate "$root/usr/share/applications/volume-haptics.desktop" || fail "desktop-file-validate"
else
  echo "note: desktop-file-validate not installed (desktop-file-utils): the desktop entry is not validated"
fi
# The MIME type, compiled as the shared-mime-info trigger would: glob and header magic.
if command -v update-mime-database >/dev/null 2>&1; then
  mkdir -p "$tmp/mime/packages"
  cp "$root/usr/share/mime/packages/volume-haptics.xml" "$tmp/mime/packages/"
  update-mime-database "$tmp/mime" >/dev/null 2>&1
  grep -q 'application/x-volumehaptics-recording:\*\.vhrec' "$tmp/mime/globs" || fail "no *.vhrec glob"
  perl -0777 -ne 'exit(/\[60:application\/x-volumehaptics-recording\]\n>0=\x00\x08VHREC\r\n\x1a/ ? 0 : 1)' \
    "$tmp/mime/magic" || fail "the MIME magic is not the .vhrec header's 8 bytes"
else
  echo "note: update-mime-database not installed (shared-mime-info): the MIME XML is not compiled"
fi

# ---- the unpacked program ----
exe="$root/usr/bin/volume-haptics"
step "no build-tree RPATH, every shared library found"
if readelf -d "$exe" | grep -E 'RPATH|RUNPATH'; then fail "the packaged program carries an RPATH"; fi
if ldd "$exe" | grep 'not found'; then fail "the packaged program misses shared libraries"; fi
# A clean environment: no VH_* variables, a fresh HOME (the generated-data cache goes there).
mkdir -p "$tmp/home" "$tmp/work"
vh() { (cd "$tmp/work" && env -i PATH=/usr/bin:/bin HOME="$tmp/home" QT_QPA_PLATFORM=offscreen "$exe" "$@"); }

step "volume-haptics --help"
vh --help >"$tmp/help.txt" || fail "--help exited with $?"
grep -q 'run' "$tmp/help.txt" || fail "--help does not mention run"

step "headless run on the installed scene (built-in volume)"
scene="$root/usr/share/volume-haptics/scenes/sphere-probe.json"
vh make-trajectory --scene "$scene" --out "$tmp/work/sphere.csv" || fail "make-trajectory on $scene"
t2=$(date +%s)
vh run --scene "$scene" --trajectory "$tmp/work/sphere.csv" --report "$tmp/work/sphere.json" ||
  fail "run on $scene"
grep -q '"scene"' "$tmp/work/sphere.json" || fail "the run wrote no report"
echo "run: $(($(date +%s) - t2)) s"

step "every installed scene opens from the package alone"
# Each scene loads (its volume, tool and device) and runs headless on the sphere's device path.
nscenes=0
for scene in "$root"/usr/share/volume-haptics/scenes/*.json; do
  name="$(basename "$scene" .json)"
  vh run --scene "$scene" --trajectory "$tmp/work/sphere.csv" --report "$tmp/work/$name-report.json" \
    >"$tmp/$name.log" 2>&1 || { cat "$tmp/$name.log"; fail "the installed scene $name does not open"; }
  grep -q '"scene"' "$tmp/work/$name-report.json" || fail "the run of $name wrote no report"
  nscenes=$((nscenes + 1))
done
((nscenes >= 2)) || fail "only $nscenes installed scenes"
echo "scenes: $nscenes open"

step "the Python module imports from the package (system Python) and runs"
if [[ -d $root/usr/lib/python3/dist-packages/volume_haptics ]]; then
  (cd "$tmp/work" && env -i PATH=/usr/bin:/bin HOME="$tmp/home" PYTHONPATH="$root/usr/lib/python3/dist-packages" \
    /usr/bin/python3 -c "import sys, volume_haptics as vh; r = vh.run(sys.argv[1], sys.argv[2]); print('python run:', r.report['ticks'], 'ticks')" \
    "$root/usr/share/volume-haptics/scenes/sphere-probe.json" "$tmp/work/sphere.csv") || fail "import volume_haptics / run from the package"
else
  echo "no Python module in the package (built without pybind11)"
fi

step "bench writes under the user's data folder"
vh bench table1 --help >"$tmp/bench-help.txt" || fail "bench table1 --help exited with $?"
grep -q "$tmp/home/.local/share/volume-haptics/bench/table1" "$tmp/bench-help.txt" ||
  { cat "$tmp/bench-help.txt"; fail "bench's default output folder is not ~/.local/share/volume-haptics/bench"; }
(cd "$tmp/work" && env -i PATH=/usr/bin:/bin HOME="$tmp/home" XDG_DATA_HOME="$tmp/xdg" QT_QPA_PLATFORM=offscreen \
  "$exe" bench table1 --help) | grep -q "$tmp/xdg/volume-haptics/bench/table1" ||
  fail "bench's default output folder does not follow XDG_DATA_HOME"
if grep -q "$build" "$tmp/bench-help.txt"; then fail "bench --help names the build tree $build"; fi

step "an NRRD read through the unpacked worker"
# A 24^3 ball (unsigned char, 1 mm voxels, 128 at radius 8 mm), written here.
perl -e 'for $z (0..23) { for $y (0..23) { for $x (0..23) {
  $r = sqrt(($x-11.5)**2 + ($y-11.5)**2 + ($z-11.5)**2); $v = 128 + 16 * (8 - $r);
  $v = $v < 0 ? 0 : ($v > 255 ? 255 : $v); print pack("C", int($v + 0.5)); } } }' >"$tmp/work/ball.raw"
cat >"$tmp/work/ball.nhdr" <<'EOF'
NRRD0004
type: unsigned char
dimension: 3
sizes: 24 24 24
spacings: 1 1 1
space units: "mm" "mm" "mm"
encoding: raw
data file: ball.raw
EOF
cat >"$tmp/work/ball.json" <<'EOF'
{
  "volume": {"path": "ball.nhdr", "isovalue": 128},
  "tool": {"mesh": "builtin:probe", "point_spacing_m": 0.001},
  "coupling": {"linear_N_per_m": 1000, "angular_Nm_per_rad": 1.0},
  "device": {"kind": "simulated"}
}
EOF
# The unpacked worker, wrapped to log its calls: the program must start this one (found
# relative to ROOT/usr/bin), never the build tree's.
worker="$root/usr/libexec/volume-haptics/volume-haptics-dicom-worker"
mv "$worker" "$worker.real"
printf '#!/bin/sh\necho "$*" >>"%s"\nexec "$0.real" "$@"\n' "$tmp/worker.log" >"$worker"
chmod 755 "$worker"
vh make-trajectory --scene "$tmp/work/ball.json" --out "$tmp/work/ball.csv" || fail "make-trajectory on the NRRD ball"
vh run --scene "$tmp/work/ball.json" --trajectory "$tmp/work/ball.csv" --report "$tmp/work/ball-report.json" ||
  fail "run on the NRRD ball"
grep -q "^volume .*ball.nhdr" "$tmp/worker.log" 2>/dev/null ||
  fail "the unpacked program did not read the NRRD through the unpacked worker (log: $(cat "$tmp/worker.log" 2>/dev/null))"
echo "worker calls: $(wc -l <"$tmp/worker.log")"

step "the installed program names no folder of the build machine"
cat >"$tmp/work/missing.json" <<'EOF'
{
  "volume": {"path": "nowhere/missing.nrrd", "isovalue": 1},
  "tool": {"mesh": "builtin:probe", "point_spacing_m": 0.001},
  "coupling": {"linear_N_per_m": 1000, "angular_Nm_per_rad": 1.0},
  "device": {"kind": "simulated"}
}
EOF
if vh make-trajectory --scene "$tmp/work/missing.json" --out "$tmp/work/missing.csv" >"$tmp/missing.txt" 2>&1; then
  fail "a scene with a missing volume was accepted"
fi
cat "$tmp/missing.txt"
grep -q "$root/usr/share/volume-haptics/datasets" "$tmp/missing.txt" || fail "the shared datasets default is not the installed one"
grep -q "$tmp/home/.cache/volume-haptics" "$tmp/missing.txt" || fail "the generated data default is not the user's cache"
# Every folder looked in lies in the temporary root or home: none of the build machine's.
looked="$(sed -n 's/.*(looked in \([^)]*\)).*/\1/p' "$tmp/missing.txt")"
[[ -n $looked ]] || fail "no 'looked in' list in the error"
while IFS= read -r path; do
  [[ $path == "$tmp"/* ]] || fail "the installed program looked in $path, outside its root (build tree $build, source $source_dir)"
done < <(sed 's/ and /\n/g' <<<"$looked")

echo "PASS: $(basename "$deb") ($(du -k "$deb" | cut -f1) KiB), cpack $((t1 - t0)) s, test $(($(date +%s) - t0)) s"
