#!/usr/bin/env bash
# One-command set-up for a fresh Debian 12 machine.
#   packaging/setup.sh run [ARGS...]  install missing Debian packages, build the application (not
#                                     the tests), open it
#   packaging/setup.sh test           install missing Debian packages, build, run ctest, leave
#                                     the Debian package in the build folder
# Environment: VH_BUILD_DIR (default build), VH_FUZZ_BUILD_DIR (default build-fuzz), VH_JOBS
# (default nproc).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mode="${1:-test}"; shift || true
build_dir="${VH_BUILD_DIR:-$here/build}"
jobs="${VH_JOBS:-$(nproc)}"
# Each step's wall time, printed as it ends and summed up at the end ("setup: times: ...").
step_start=$SECONDS; step_times=()
step_done() {
  local took=$((SECONDS - step_start))
  step_times+=("$1 $((took / 60)) min $((took % 60)) s")
  echo "setup: $1 took $((took / 60)) min $((took % 60)) s"
  step_start=$SECONDS
}

# Debian 12 package names; each is installed only when missing.
packages=(cmake ninja-build g++ mold pkg-config libeigen3-dev libgtest-dev libgmock-dev
  libbenchmark-dev nlohmann-json3-dev libcli11-dev libvtk9-dev libvtk-dicom-dev libdcmtk-dev
  qt6-base-dev libqt6opengl6-dev qt6-charts-dev libhidapi-dev libusb-1.0-0-dev
  zlib1g-dev libssl-dev zstd xvfb xauth libgl1-mesa-dri umockdev libumockdev-dev libopenigtlink-dev
  libsndfile1-dev qt6-multimedia-dev libvorbis-dev libogg-dev)
# Recordings as HDF5 files (export --hdf5): the HDF5 library, serial build.
packages+=(libhdf5-dev)
# Soft tissue (app/tissue): Spectra's eigensolvers for the modal model, header-only.
packages+=(libspectra-dev)
# The Python module volume_haptics (app/python): pybind11, the system Python's headers, NumPy.
packages+=(pybind11-dev python3-dev python3-numpy)
# test also builds the fuzz targets (tests/fuzz/ci.sh): clang and its libFuzzer / sanitizer runtimes.
# test also builds and checks the Debian package (tests/packaging/deb_test.sh): dpkg-shlibdeps
# (dpkg-dev) and file for cpack's Depends, help2man for the man page, desktop-file-utils and
# shared-mime-info to validate the desktop entry and compile the MIME type.
# test also starts a real PACS for the PACS client's tests (tests/app/io/pacs_orthanc_fixture.sh):
# Orthanc, run from the build tree with its own configuration (the package's service is not
# used), DCMTK's command-line tools (dcmtk: storescu stores the test series in it), curl (asks
# Orthanc's REST API whether it is up and holds the series) and the openssl command (makes the
# throwaway CA and certificates of the second, DICOM TLS, Orthanc).
# test also opens a session report in a real browser engine (headless Chromium:
# tests/ui/report_cli_test.sh) to check that its inline pictures decode.
# test also runs the Python module's pytest suite and checks NIfTI placement against nibabel.
# test also decodes the exported videos' Theora stream (libtheora's decoder, tests/ui/recording_test.cpp).
if [[ $mode == test ]]; then
  packages+=(python3-pytest python3-nibabel libtheora-dev)
  # The HDF5 recordings read by h5py and pandas alone (tests/app/python/test_hdf5.py).
  packages+=(python3-h5py python3-pandas)
  # Scene.volume of a DICOM series against nibabel's DICOM wrapper (tests/app/python/test_dicom_volume.py).
  packages+=(python3-pydicom)
  # Studies on a Dask cluster (tests/app/python/test_study.py: a LocalCluster of two workers).
  packages+=(python3-dask python3-distributed)
  # The tissue model's static solve against CalculiX, an independent FEM program with the same
  # 8-node brick (tests/tissue/calculix_reference_test.cpp): 2 packages, 2 MB (SfePy pulls 100).
  packages+=(calculix-ccx)
  packages+=(clang libclang-rt-14-dev dpkg-dev file help2man desktop-file-utils shared-mime-info orthanc dcmtk curl
    openssl chromium)
fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  sudo_cmd=(); [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -q
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
step_done "Debian packages"

cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DVH_WITH_APP=ON
step_done "configure"
# run builds only what the application needs (the program, its DICOM reader process, the
# synthetic volumes of the built-in scenes): under half of the build; test builds everything.
targets=()
[[ $mode == run ]] && targets=(--target volume-haptics volume-haptics-dicom-worker vh_synthetic_data)
cmake --build "$build_dir" -j "$jobs" "${targets[@]}"
step_done "build"

case "$mode" in
  test)
    cd "$build_dir"
    ctest --output-on-failure -j "$jobs" --timeout 1500
    step_done "ctest"
    # The Debian package, left in the build tree (the package test builds its own and removes it).
    cpack -G DEB >/dev/null && echo "setup: the Debian package: $(ls "$build_dir"/volume-haptics_*.deb)"
    step_done "cpack"
    # Fuzz targets (clang, their own build folder), each briefly on the committed corpus.
    VH_JOBS="$jobs" bash "$here/tests/fuzz/ci.sh" "${VH_FUZZ_BUILD_DIR:-$here/build-fuzz}"
    step_done "fuzz (build and runs)"
    echo "setup: times: $(printf '%s; ' "${step_times[@]}")total $((SECONDS / 60)) min $((SECONDS % 60)) s"
    ;;
  run)
    app="$build_dir/app/volume-haptics"
    if [[ -z "${DISPLAY:-}" && -z "${WAYLAND_DISPLAY:-}" ]]; then
      echo "setup: no display found; running under xvfb-run (pass a screenshot path with --screenshot to see it)"
      exec xvfb-run -a -s "-screen 0 1280x1024x24" "$app" "$@"
    fi
    exec "$app" "$@"
    ;;
  *) echo "usage: $0 run [ARGS...] | test" >&2; exit 2 ;;
esac
