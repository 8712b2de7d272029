#!/bin/sh
# lab-goniod.sh GONIO_SIM GONIOD GONIOCTL RELAY_EMU LAB_RIG - kernel lane: goniod on a variant
# of examples/rigs/lab.yaml, the rig a lab wires, with every backend family at once: the
# Modbus drives emulated by gonio-sim on a pty, the lamps on the emulated USB relay board,
# the laser on gpio-sim's line "laser", the cameras on vivid's two nodes. Home, move, lamp and
# laser through gonioctl, their effect read back where the "hardware" shows it (the board's
# state file, gpio-sim's sysfs), and a capture whose rows match their files and the commands.
set -eu
name=lab-goniod sim=$1 goniod=$2 gonioctl=$3 emu=$4 rig=$5
. "$(dirname "$0")/goniod-lib.sh"
sim_line() { set -- $(gpiofind "$1") "$2"; cat "/sys/bus/gpio/devices/$1/sim_gpio$2/$3"; }
relays() { echo $((0x$(cat "$dir/relays.state"))); }

(cd "$dir" && "$emu" -n lab -s LAB01 4 relays.state) || fail "relay board emulator"
export GONIO_SIM_DIR="$dir" GONIO_LAB_DRIVES="$dir/drives" GONIO_LAB_RELAYS=LAB01 \
        GONIO_LAB_GPIOCHIP=gonio-gpio GONIO_LAB_LASER=laser \
        GONIO_LAB_CAM0=platform:vivid-000 GONIO_LAB_CAM1=platform:vivid-001
start_sim "$rig" --time-scale 5
start_goniod "$rig"
st=$(ctl --json status)
echo "$st" | grep -q '"state": *"idle"' || fail "not idle at start: $st"

ctl --quiet home || fail "home"
ctl --quiet move turntable 30 || fail "move"
ctl --quiet lamp lamp1 on || fail "lamp on"
[ "$(relays)" = 2 ] || fail "relay board state $(relays), expected relay 2 on"
# gonioctl holds the laser on while it runs (the rig's laser goes off when its client goes)
"$gonioctl" --socket "$dir/sock" --quiet laser on --for 300 2> "$dir/hold.err" &
holder=$!
pids="$pids $holder"
i=0
until [ "$(sim_line laser value)" = 1 ]; do
        i=$((i + 1)); [ $i -lt 100 ] || fail "laser line low after laser on: $(cat "$dir/hold.err")"
        sleep 0.1
done
ctl --quiet dataset create lab || fail "dataset create"
cap=$(ctl --json capture) || fail "capture"
echo "$cap" > "$dir/cap.json"
/usr/bin/python3 - "$dir" << 'PY' || fail "captured rows do not match"
import hashlib, json, sys
d = sys.argv[1]
caps = json.load(open(f"{d}/cap.json"))["captures"]
assert sorted(c["camera"] for c in caps) == ["cam0", "cam1"], caps
for c in caps:
    data = open(f"{d}/data/lab/{c['file']}", "rb").read()
    assert hashlib.sha256(data).hexdigest() == c["sha256"], c["file"]
    assert abs(c["turntable"] - 30) < 0.01 and c["lamps"] == "lamp1" and c["laser"], c
    assert (c["width"], c["height"]) == (640, 480), c
print(f"lab-goniod: {len(caps)} captures, files and labels match")
PY
kill -TERM "$holder" && wait "$holder" && [ "$(sim_line laser value)" = 0 ] ||
        fail "laser off when its gonioctl ends: $(cat "$dir/hold.err")"
ctl --quiet lamp lamp1 off && [ "$(relays)" = 0 ] || fail "lamp off"
echo "lab-goniod: Modbus drives, USB relay lamps, GPIO laser and V4L2 cameras in one goniod"
