#!/bin/bash
# On the device, after every chunk is in /tmp/b: unpack the bundle, time EEVEE, then Cycles.
set -u
B=/tmp/b; W=/tmp/w; HERE=$(cd "$(dirname "$0")" && pwd)
. $HERE/unpack.sh
mkdir -p $W/gpu && cp $B/*.blend $W/gpu/ && cp $HERE/*.py $HERE/watch.sh $W/
echo "EGL vendor json: ${__EGL_VENDOR_LIBRARY_FILENAMES:-none}"
(cd $W && env -u PYTHONPATH $PY egl_check.py 2>&1 | tail -2)
nvidia-smi --query-gpu=name,utilization.gpu,memory.used,clocks.sm --format=csv,noheader -lms 1000 > $OUT/smi.log 2>&1 &
SMI=$!
cd $W
SIZES="${SIZES:-320x180 1920x1080}" REPS=${REPS:-3} env -u PYTHONPATH timeout ${ETIME:-400} $PY gpu_time.py -- ${SPECS:-sp256:novpl sp256 sp800 sp256:rt} > $OUT/eevee.log 2>&1 &
P=$!; bash watch.sh $P > $OUT/libs.txt; wait $P; echo "eevee rc $?"
echo "libs: $(cat $OUT/libs.txt)"
grep -v -E "^EGL Error|Add-on not|Fra:|Read blend|Saved:" $OUT/eevee.log | tail -40
if [ "${CYC:-1}" = 1 ]; then
  env -u PYTHONPATH timeout ${CTIME:-150} $PY cycles_time.py -- OPTIX 1 4 16 > $OUT/cycles.log 2>&1; echo "cycles rc $?"
  grep -E "ROW|devices|Error|error|no OPTIX" $OUT/cycles.log | tail -12
fi
kill $SMI; sort $OUT/smi.log | uniq -c | sort -rn | head -5; tail -3 $OUT/smi.log
