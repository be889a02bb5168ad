#!/bin/bash
# Builds what the GPU timing carries to a device machine that has no Blender and no network:
# a relocatable CPython 3.11 with bpy 5.0.1 (trimmed: no other add-ons than Cycles, no USD Python
# module, no Cycles GPU kernels but the three below), the X11/GL/EGL client libraries bpy links
# (glvnd's libEGL finds the driver's libEGL_nvidia), split into chunks that fit one device call.
# Usage: build_bundle.sh OUTDIR  (run from the repository root, with .venv made by `make`)
set -euo pipefail
OUT=$1; B=$OUT/bundle; rm -rf "$B"; mkdir -p "$B/py/bin" "$B/py/lib" "$B/xlibs"
P=$(readlink -f .venv/bin/python); P=${P%/bin/*}
cp -a "$P/bin/python3.11" "$B/py/bin/"; cp -a "$P"/lib/libpython3.11.so* "$B/py/lib/"
(cd "$P/lib" && tar cf - --exclude='python3.11/test' --exclude='python3.11/site-packages' \
  --exclude='*/__pycache__' --exclude='python3.11/idlelib' --exclude='python3.11/tkinter' \
  --exclude='python3.11/turtledemo' --exclude='python3.11/ensurepip' --exclude='python3.11/lib2to3' \
  --exclude='python3.11/config-3.11-x86_64-linux-gnu' --exclude='*/tests' python3.11) | (cd "$B/py/lib" && tar xf -)
SP=.venv/lib/python3.11/site-packages; D=$B/py/lib/python3.11/site-packages; mkdir -p "$D"
(cd "$SP" && tar cf - --exclude='*/__pycache__' --exclude='*/tests' zstandard requests urllib3 idna certifi charset_normalizer) | (cd "$D" && tar xf -)
(cd "$SP" && tar cf - --exclude='*/__pycache__' --exclude='bpy/5.0/scripts/addons_core/cycles/lib' \
  --exclude='bpy/5.0/python/lib/python3.11/site-packages/pxr' --exclude='bpy/5.0/datafiles/assets' \
  --exclude='bpy/lib/libOpenImageDenoise_device_hip*' --exclude='bpy/lib/libOpenImageDenoise_device_sycl*' bpy) | (cd "$D" && tar xf -)
(cd "$D/bpy/5.0/scripts/addons_core" && ls | grep -v -x cycles | xargs rm -rf)
for f in "$D"/bpy/__init__.so "$D"/bpy/lib/*.so*; do strip --strip-unneeded "$f"; done
for l in libX11.so.6 libXrender.so.1 libXfixes.so.3 libXi.so.6 libxkbcommon.so.0 libxcb.so.1 libXext.so.6 \
  libSM.so.6 libICE.so.6 libGL.so.1 libGLX.so.0 libGLdispatch.so.0 libXau.so.6 libXdmcp.so.6 libuuid.so.1 \
  libbsd.so.0 libmd.so.0 libEGL.so.1 libOpenGL.so.0 libXxf86vm.so.1 libffi.so.8 libssl.so.3 libcrypto.so.3 \
  liblzma.so.5 libbz2.so.1.0 libz.so.1 libsqlite3.so.0 libreadline.so.8 libncursesw.so.6 libtinfo.so.6; do
  cp -L "/lib/x86_64-linux-gnu/$l" "$B/xlibs/"
done
tar cf - -C "$B" py xlibs | xz --x86 --lzma2=preset=9,dict=64MiB -T0 > "$OUT/bundle.tar.xz"
(cd "$SP/bpy/5.0/scripts/addons_core/cycles" && tar cf "$OUT/cyc.tar" lib/kernel_optix.ptx.zst \
  lib/kernel_optix_shader_raytrace.ptx.zst lib/kernel_compute_75.ptx.zst)
# 55 MB parts: with the 8 MB working tree each fits one call's 64 MiB.
(cd "$OUT" && split -b 55000000 -d -a 1 bundle.tar.xz part_ && md5sum part_* > parts.md5)
ls -la "$OUT"
