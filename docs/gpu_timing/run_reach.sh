#!/bin/bash
# On the device, after the bundle's parts and the gpu/*.blend files are in /tmp/b: unpack, check
# EGL, and run reach_time.py (NAME and VARIANTS as its arguments) for at most RTIME seconds.
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
. $HERE/unpack.sh
W=/tmp/w; mkdir -p $W/gpu && cp /tmp/b/*.blend $W/gpu/
(cd $W && env -u PYTHONPATH $PY $HERE/egl_check.py 2>&1 | tail -1)
nvidia-smi --query-gpu=name,utilization.gpu,memory.used,clocks.sm --format=csv,noheader -lms 1000 > $OUT/smi.log 2>&1 &
SMI=$!
(cd $W && env -u PYTHONPATH timeout ${RTIME:-300} $PY $HERE/reach_time.py -- "$@" > $OUT/reach.log 2>&1); echo "reach rc $?"
kill $SMI
grep -E "^ROW|VPLs|Error|error" $OUT/reach.log | tail -40
sort $OUT/smi.log | cut -d, -f1,2 | uniq -c | sort -rn | head -3
