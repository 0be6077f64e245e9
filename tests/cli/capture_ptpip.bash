# The PTP/IP emulator for the capture CLI tests (sourced after lib.bash and
# capture_lib.bash by capture.sh and capture_faults.sh): skips when it is not
# built; start_cam/stop_cam, the bounded `cap`, gp_leaks.
if [ -z "${PTPIP_CAMERA:-}" ] || [ ! -x "$PTPIP_CAMERA" ]; then
  skip "PTPIP_CAMERA not built"
  finish
  exit $?
fi

CAM_PID=
# start_cam [emulator flags]: starts the emulator, sets $PORT; at most 10 s.
start_cam() {
  stop_cam
  rm -f "$T/cam.port"
  "$PTPIP_CAMERA" --lifetime 120 "$@" >"$T/cam.port" 2>"$T/cam.log" &
  CAM_PID=$!
  PORT=
  for _ in $(seq 1 100); do
    PORT=$(awk '/^PORT/{print $2}' "$T/cam.port" 2>/dev/null)
    [ -n "$PORT" ] && return 0
    sleep 0.1
  done
  bad "emulator did not start: $(cat "$T/cam.log")"
  return 1
}
stop_cam() {
  if [ -n "$CAM_PID" ]; then
    kill "$CAM_PID" 2>/dev/null
    wait "$CAM_PID" 2>/dev/null
    CAM_PID=
  fi
}
trap stop_cam EXIT
# Every capture is bounded: a hung camera must never hang the suite.
cap() {
  local t0=$SECONDS rc
  timeout 60 "$SETLIGHT" capture "$@"
  rc=$?
  [ $((SECONDS - t0)) -gt 3 ] && echo "slow ($((SECONDS - t0)) s): capture $*" >&3
  return $rc
}
exec 3>&1

# gp_leaks CMD...: runs CMD with LeakSanitizer still on, but blind to the
# leaks inside libgphoto2 listed in lsan_libgphoto2.supp (detection, a failed
# PTP/IP init); a leak of setlight's own is still reported.
gp_leaks() {
  ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}fast_unwind_on_malloc=0" \
    LSAN_OPTIONS="${LSAN_OPTIONS:+$LSAN_OPTIONS:}suppressions=$(dirname "$0")/lsan_libgphoto2.supp" "$@"
}

