# sourced on the device (and locally to test): $R is the unpacked bundle
export PYTHONHOME=$R/py PYTHONNOUSERSITE=1 PYTHONUNBUFFERED=1
export LD_LIBRARY_PATH=$R/py/lib:/usr/local/nvidia/lib64:/usr/local/nvidia/lib:$R/xlibs
[ -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ] && export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
PY=$R/py/bin/python3.11
