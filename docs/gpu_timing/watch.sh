# watch.sh PID: the GL/EGL libraries that PID (or, when it is `timeout`, its child) maps while it runs
while kill -0 "$1" 2>/dev/null; do
  for p in "$1" $(pgrep -P "$1"); do
    grep -h -o -E "[^/ ]*(nvidia|swrast|gallium|EGL|GLX_)[^/ ]*$" "/proc/$p/maps" 2>/dev/null
  done
  sleep 0.5
done | sort -u | tr '\n' ' '
