#!/bin/bash
# On the device, after the bundle's parts are in /tmp/b and JOBS_TAR (eevee_jobs.py's jobs folder,
# as tar.xz) travelled: unpack both, render the jobs (render_jobs.py) for BUDGET seconds, and
# send the EXRs (ZIP-compressed) back as tar parts of at most 15 MB (the device returns 8 files of 16 MiB).
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
. $HERE/unpack.sh
rm -rf /tmp/jobs && mkdir -p /tmp/jobs
env -u PYTHONHOME -u LD_LIBRARY_PATH python3 -c "import lzma,sys,shutil;shutil.copyfileobj(lzma.open(sys.argv[1]),sys.stdout.buffer)" "$JOBS_TAR" | tar xf - -C /tmp/jobs --strip-components=1
echo "jobs: $(ls /tmp/jobs/*.blend | wc -l) files, $(wc -l < /tmp/jobs/jobs.jsonl) lines"
nvidia-smi --query-gpu=name,utilization.gpu,memory.used,clocks.sm --format=csv,noheader -lms 1000 > /tmp/smi.log 2>&1 &
SMI=$!
env -u PYTHONPATH $PY $HERE/render_jobs.py /tmp/jobs /tmp/exr "${BUDGET:-400}" > /tmp/render.log 2>&1
echo "render rc $?"
kill $SMI
grep -v -E "^EGL Error|Add-on not|Fra:|Read blend|Saved:|^$" /tmp/render.log | tail -60
sort /tmp/smi.log | cut -d, -f1,2 | sort | uniq -c | sort -rn | head -4
cp /tmp/render.log /tmp/exr/times.jsonl $OUT/ 2>/dev/null
(cd /tmp && tar cf - exr | split -b 15000000 -d -a 1 - $OUT/exr.tar.)
ls -la $OUT
