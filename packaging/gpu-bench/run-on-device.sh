#!/bin/bash
# On the lent GPU machine, from the repository root, with .gpu-bench/ carried (make-bundle.sh):
#   packaging/gpu-bench/run-on-device.sh STEP...
# Steps: unpack-b (Xvfb, Mesa, the phantom), unpack-a (the program and its libraries), render
# (bench render under VirtualGL's EGL back end), memory (bench memory, likewise), table1 (bench
# table1), lanes (the lane-scaling table with the 20,000-point tools and the 1920 x 1080 frame
# rate, in under 8 minutes). Each archive is nearly the transfer limit alone, so unpack-b runs in one call (carry
# .gpu-bench/b.tar.zst, .gpu-bench/bin, .gpu-bench/gl) and unpack-a with the benchmarks in the
# next, while the machine is still warm (carry .gpu-bench/a.tar.zst, .gpu-bench/bin,
# .gpu-bench/gl, .gpu-bench/vgl). Results go to $OUT. Environment: RENDER_ARGS, MEMORY_ARGS,
# TABLE1_ARGS (extra options), SERIES_DIR (where the generated CT goes; /tmp/vhgen/ct),
# VGL_REFRESHRATE (VirtualGL's emulated display rate; 60 by default).
cd "$(dirname "$0")/../.." || exit 1
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
G=$(pwd)/.gpu-bench
for f in "$G"/gl/*.deb; do [ -f "$f" ] && dpkg -x "$f" /; done
ldconfig 2>/dev/null
NV=$(ls -d /usr/local/nvidia/lib64 /usr/local/nvidia/lib 2>/dev/null | tr '\n' ':')
EGLV=$(ls /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/share/glvnd/egl_vendor.d/10_nvidia.json 2>/dev/null | head -1)
[ -n "$EGLV" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$EGLV
export VGL_DISPLAY=${VGL_DISPLAY:-egl}
export VH_SHARED_DATASETS_DIR=/opt/vh/datasets VH_GENERATED_DATA_DIR=/tmp/vhgen
export QT_PLUGIN_PATH=/opt/vh/plugins QT_QPA_PLATFORM=xcb FONTCONFIG_PATH=/etc/fonts
LIBS=/opt/vh/lib:$NV:$G/vgl
unzst() { LD_LIBRARY_PATH="$G/bin" "$G/bin/zstd" -dc "$1" | tar xf - -C /; }
# Runs a command with VirtualGL's fakers: its GLX calls rendered on the GPU through EGL.
under_vgl() { env LD_LIBRARY_PATH="$LIBS" LD_PRELOAD="$G/vgl/libdlfaker.so:$G/vgl/libvglfaker.so" "$@"; }
start_x() {
  [ -n "${DISPLAY:-}" ] && return
  mkdir -p /var/lib/xkb /tmp/.X11-unix
  LD_LIBRARY_PATH=/opt/vh/lib:/opt/vh/libx LIBGL_DRIVERS_PATH=/opt/vh/dri GALLIUM_DRIVER=softpipe DRAW_USE_LLVM=0 \
    /opt/vh/bin/Xvfb :99 -screen 0 1920x1080x24 -nolisten tcp > "$OUT/xvfb.log" 2>&1 &
  sleep 3
  export DISPLAY=:99
}
for step in "$@"; do
  echo "=== $step $(date +%T)"
  case $step in
    unpack-a) unzst "$G/a.tar.zst" && LD_LIBRARY_PATH=$LIBS ldd /opt/vh/bin/volume-haptics | grep "not found" ;;
    unpack-b) unzst "$G/b.tar.zst" ;;
    render)
      start_x
      under_vgl "$G/vgl/glxinfo" 2>&1 |
        grep -E "renderer string|core profile version"
      # shellcheck disable=SC2086
      under_vgl /opt/vh/bin/volume-haptics bench render --no-plots --series-dir ${SERIES_DIR:-/tmp/vhgen/ct} ${RENDER_ARGS:-} \
        --out "$OUT/render" 2>&1 | grep -v '^\[VGL\]' ;;
    memory)
      start_x
      # shellcheck disable=SC2086
      under_vgl /opt/vh/bin/volume-haptics bench memory --series-dir ${SERIES_DIR:-/tmp/vhgen/ct} ${MEMORY_ARGS:-} \
        --out "$OUT/memory" 2>&1 | grep -v '^\[VGL\]' ;;
    table1)
      # shellcheck disable=SC2086
      env LD_LIBRARY_PATH="$LIBS" /opt/vh/bin/volume-haptics bench table1 --no-plots --verify-step 0 \
        ${TABLE1_ARGS:-} --out "$OUT/table1" ;;
    lanes)
      # The many-core table in one step, under 8 minutes on 16 cores: the four scenes and the
      # 20,000-point tools (the edge test on, as the application runs it), each on 1, 2, 4 and 8
      # lanes without budget or deadline beside the budgeted run; then the frame rate at 1920 x
      # 1080. Each part is bounded, so that a slow machine still leaves time to fetch $OUT.
      env LD_LIBRARY_PATH="$LIBS" timeout 330 /opt/vh/bin/volume-haptics bench table1 --no-plots --verify-step 0 \
        --mode accelerated --ticks 2000 --lanes-sweep 1,2,4,8 ${TABLE1_ARGS:-} --out "$OUT/lanes"
      start_x
      # shellcheck disable=SC2086
      under_vgl timeout 120 /opt/vh/bin/volume-haptics bench render --no-plots --sizes 1920x1080 --seconds 3 \
        --series-dir ${SERIES_DIR:-/tmp/vhgen/ct} ${RENDER_ARGS:-} --out "$OUT/render-1080" 2>&1 | grep -v '^\[VGL\]' ;;
    *) echo "unknown step $step"; exit 2 ;;
  esac
done
