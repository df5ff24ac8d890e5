#!/bin/bash
# Packs what `bench render` and `bench table1` need on a lent GPU machine that has none of this
# project's libraries (an Ubuntu image with the NVIDIA driver, no network), in two archives that
# each travel under the device tool's 64 MiB limit with the working tree:
#   .gpu-bench/a.tar.zst  the program and its DICOM reader process, their Debian 12 libraries and Qt's xcb plugin, small datasets
#   .gpu-bench/b.tar.zst  Xvfb, xkbcomp and Mesa's software driver, the Philips head phantom
# and, unpacked beside them, a zstd binary, VirtualGL's fakers and the GL loader packages.
# Usage (from the repository root, after a release build in build/):
#   VGL_BUILD=/path/to/virtualgl/build packaging/gpu-bench/make-bundle.sh
# VirtualGL 3 (not in Debian): cmake -G Ninja -DVGL_FAKEOPENCL=OFF -DVGL_USEXV=OFF
#   -DTJPEG_INCLUDE_DIR=/usr/include -DTJPEG_LIBRARY=/usr/lib/x86_64-linux-gnu/libturbojpeg.so
#   (apt: libturbojpeg0-dev libxtst-dev libx11-xcb-dev libxcb-keysyms1-dev libegl-dev libglu1-mesa-dev).
# Then on the machine: packaging/gpu-bench/run-on-device.sh (see there).
set -euo pipefail
: "${VGL_BUILD:?set VGL_BUILD to a VirtualGL 3 build folder}"
OUTDIR=.gpu-bench
D=${VH_SHARED_DATASETS_DIR:-../shared/datasets}
QP=/usr/lib/x86_64-linux-gnu/qt6/plugins
DRI=/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so
mkdir -p $OUTDIR/bin $OUTDIR/vgl $OUTDIR/gl
# The machine brings its own C library, C++ runtime and (through glvnd) its own GL.
skip() { case $1 in */libc.so*|*/libm.so*|*/libpthread*|*/libdl.so*|*/librt.so*|*/libGL.so*|*/libGLX.so*|*/libEGL.so*|*/libOpenGL.so*|*/libGLdispatch*|*/libstdc++*|*/libgcc_s*|*/libLLVM*|*/libz3*) return 0;; esac; return 1; }
A=$(mktemp -d); B=$(mktemp -d); STUB=$(mktemp -d)
trap 'rm -rf $A $B $STUB' EXIT
mkdir -p $A/opt/vh/{lib,bin,plugins/platforms,plugins/xcbglintegrations,datasets/ct,datasets/classic,datasets/meshes}
mkdir -p $B/opt/vh/{libx,bin,dri,datasets/ct} $B/usr/share/X11 $B/usr/bin $B/usr/share/fonts/truetype/dejavu $B/etc
cp build/app/volume-haptics build/app/volume-haptics-dicom-worker $A/opt/vh/bin/
cp -L $QP/platforms/libqxcb.so $A/opt/vh/plugins/platforms/
cp -L $QP/xcbglintegrations/libqxcb-glx-integration.so $A/opt/vh/plugins/xcbglintegrations/
for f in build/app/volume-haptics build/app/volume-haptics-dicom-worker $QP/platforms/libqxcb.so $QP/xcbglintegrations/libqxcb-glx-integration.so; do
  ldd $f | awk '/=>/{print $3}'
done | sort -u > $A/libs.txt
while read -r l; do skip "$l" || cp -L "$l" $A/opt/vh/lib/; done < $A/libs.txt
# Xvfb's GLX extension loads Mesa's swrast driver only to list frame buffer configurations (the
# rendering happens on the GPU through VirtualGL). Its 117 MB LLVM is replaced by a stub that
# defines the symbols the driver links against; GALLIUM_DRIVER=softpipe never calls them.
objdump -T $DRI | awk '$0 ~ /\(LLVM_15\)/ {print $NF}' | sort -u > $STUB/syms.txt
{ echo 'static long stub(void) { return 0; }'; i=0
  while read -r sym; do echo "__attribute__((alias(\"stub\"))) long s$i(void) __asm__(\"$sym\");"; i=$((i + 1)); done < $STUB/syms.txt
} > $STUB/stub.c
echo 'LLVM_15 { global: *; };' > $STUB/ver.map
gcc -shared -fPIC -o $B/opt/vh/libx/libLLVM-15.so.1 -Wl,-soname,libLLVM-15.so.1 -Wl,--version-script=$STUB/ver.map $STUB/stub.c
cp -L $DRI $B/opt/vh/dri/
cp -L /usr/bin/Xvfb /usr/bin/xdpyinfo $B/opt/vh/bin/
cp -L /usr/bin/xkbcomp $B/usr/bin/
cp -r /usr/share/X11/xkb $B/usr/share/X11/
cp /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf /usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf $B/usr/share/fonts/truetype/dejavu/
cp -rL /etc/fonts $B/etc/
for f in $DRI /usr/bin/Xvfb /usr/bin/xkbcomp /usr/bin/xdpyinfo; do ldd $f | awk '/=>/{print $3}'; done | sort -u | while read -r l; do
  skip "$l" && continue
  grep -qx "$l" $A/libs.txt && continue
  cp -L "$l" $B/opt/vh/libx/
done
cp -r $D/ct/ct-head-small $A/opt/vh/datasets/ct/
cp -r $D/classic/engine $A/opt/vh/datasets/classic/
cp -r $D/meshes/* $A/opt/vh/datasets/meshes/
cp -r $D/ct/philips-head-phantom-bone $B/opt/vh/datasets/ct/
tar cf - -C $A ./opt | zstd -19 --long=27 -T0 -q -f -o $OUTDIR/a.tar.zst
tar cf - -C $B . | zstd -19 --long=27 -T0 -q -f -o $OUTDIR/b.tar.zst
# zstd itself, VirtualGL's fakers and the glvnd loaders (Debian 12's: the machine has none).
cp -L /usr/bin/zstd $OUTDIR/bin/
for l in $(ldd /usr/bin/zstd | awk '/=>/{print $3}'); do skip "$l" || cp -L "$l" $OUTDIR/bin/; done
cp $VGL_BUILD/lib/libvglfaker.so $VGL_BUILD/lib/libdlfaker.so $VGL_BUILD/bin/glxinfo $OUTDIR/vgl/
for l in $(ldd $VGL_BUILD/lib/libvglfaker.so | awk '/=>/{print $3}'); do
  skip "$l" || grep -qx "$l" $A/libs.txt || cp -L "$l" $OUTDIR/vgl/  # the rest travels in a.tar.zst
done
(cd $OUTDIR/gl && apt-get download libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2 2>/dev/null)
ls -la $OUTDIR/*.tar.zst
