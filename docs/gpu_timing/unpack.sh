# sourced on the device by run_gpu.sh, run_jobs.sh and run_reach.sh: checks the bundle's parts in
# /tmp/b and unpacks them into $R (once per machine: a warm machine keeps /tmp), then sets the
# bundle's Python up (devenv.sh).
B=/tmp/b; R=/tmp/r
(cd $B && md5sum -c parts.md5 | tail -5)
if [ ! -x $R/py/bin/python3.11 ]; then
  mkdir -p $R && s0=$SECONDS
  if command -v xz >/dev/null; then cat $B/part_* | xz -dc -T0 | tar xf - -C $R
  else cat $B/part_* | python3 -c "import lzma,sys,shutil;shutil.copyfileobj(lzma.open(sys.stdin.buffer),sys.stdout.buffer)" | tar xf - -C $R; fi
  echo "unpacked in $((SECONDS-s0)) s"
  [ -f $B/cyc.tar ] && tar xf $B/cyc.tar -C $R/py/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/cycles/
fi
. "$(dirname "${BASH_SOURCE[0]}")/devenv.sh"
