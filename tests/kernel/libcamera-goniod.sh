#!/bin/sh
# libcamera-goniod.sh GONIO_SIM GONIOD GONIOCTL - kernel lane: goniod's continuous scan with a
# libcamera camera on vimc (gonio-sim's Modbus turntable on a pty, the laser on gpio-sim's line
# "laser"), and frames dropped by vimc's fault injector (tests/kernel/vimc-faults.patch) in
# the middle of it: the scan ends with an error naming the camera and the frames lost, the
# rig in its safe state (laser off, turntable stopped, no stream), no fault latched; once the
# drops stop, the next scan runs to its end.
set -eu
name=libcamera-goniod sim=$1 goniod=$2 gonioctl=$3
. "$(dirname "$0")/goniod-lib.sh"
laser_line() { set -- $(gpiofind laser); cat "/sys/bus/gpio/devices/$1/sim_gpio$2/value"; }

cat > "$dir/rig.yaml" << EOF
rig: libcamera-goniod
buses:
  - { name: drives, type: modbus-rtu, port: $dir/drives, baud: 115200, timeout_ms: 200,
      retries: 2 }
  - { name: gpio, type: local }
  - { name: cams, type: local }
axes:
  - { name: turntable, continuous: true, max_speed: 90, accel: 180, settle_ms: 50,
      modbus: { bus: drives, unit: 1 } }
laser: { name: laser, azimuth: 0, origin: [600, 0, 150],
         gpio: { bus: gpio, chip: gonio-gpio, line: laser } }
cameras:
  - { name: cam0, libcamera: { bus: cams, id: "platform/vimc.0 Sensor B" }, elevation: 20,
      distance: 500, target: [0, 0, 0], width: 240, height: 180, fx: 250, fy: 250,
      frame_rate: 30 }
EOF
start_sim "$dir/rig.yaml" --time-scale 2
start_goniod "$dir/rig.yaml"
ctl --quiet home || fail "home"

# 2 frames dropped once the scan stores frames (drops before the stream's first frame would go
# unseen: libcamera counts from the first frame it gets)
"$gonioctl" --socket "$dir/sock" --timeout 60 --json scan lc --start 0 --end 180 --step 1 \
        --no-mesh > "$dir/scan1.json" 2> "$dir/scan1.err" &
scan=$!
pids="$pids $scan"
stored() {
        kill -0 $scan || fail "the scan ended early: $(cat "$dir/scan1.err")"
        [ -n "$(ls "$dir/data/lc/images" 2> /dev/null)" ]
}
wait_for 100 "the scan stored nothing" stored
echo 2 > /sys/module/vimc/parameters/drop_frames
rc=0
wait "$scan" || rc=$?
cat "$dir/scan1.err" >&2
[ $rc != 0 ] || fail "the scan went on past 2 dropped frames"
grep -q "camera 'cam0' \[libcamera@cams\]: Failed to dequeue a frame: 2 frames dropped" \
        "$dir/scan1.err" || fail "the scan's error does not name the camera and the 2 frames"

# the safe state, and nothing latched
[ "$(laser_line)" = 0 ] || fail "laser line high after the failed scan"
st=$(ctl --json status)
echo "$st" | grep -q '"state": *"idle"' || fail "not idle after the failed scan: $st"

out=$(ctl --json scan lc --start 0 --end 15 --step 1 --no-mesh) || fail "second scan"
echo "$out"
echo "$out" | grep -Eq '"stored": *[1-9]' || fail "the second scan stored nothing"
echo "libcamera-goniod: a scan ended by 2 dropped frames, the rig safe, the next scan whole"
