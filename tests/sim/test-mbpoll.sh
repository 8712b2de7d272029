#!/bin/sh
# test-mbpoll.sh GONIO_SIM - gonio-sim's Modbus drive emulators driven by Debian's mbpoll, a
# Modbus master nobody here wrote, with the register numbers of docs/modbus-profile.md:
# - unit 1, gonio-default: home, write a target (int32, high word first, 1/1000 degree) and
#   the move command, read the position until it is there;
# - unit 2, azd (Oriental Motor AZ): a ZHOME edge on the driver input command, then one
#   direct data operation (16 registers at 0x0058, trigger 1), reading the feedback position
#   (0x00CC) and the driver output status (0x007F: HOME-END, IN-POS) until it is there.
# Skips (77) without mbpoll.
set -eu
SIM=$1
command -v mbpoll > /dev/null || { echo "mbpoll is not installed: skipped"; exit 77; }
DIR=$(mktemp -d /tmp/gonio-mbpoll-XXXXXX)
trap 'kill $PID 2> /dev/null || true; wait 2> /dev/null || true; rm -rf "$DIR"' EXIT
cat > "$DIR/rig.yaml" << 'YAML'
rig: mbpoll
buses:
  - { name: drives, type: modbus-rtu, port: "${GONIO_SIM_DIR}/drives" }
axes:
  - { name: turntable, continuous: true, max_speed: 90, accel: 180,
      modbus: { bus: drives, unit: 1 } }
  - { name: camera_arm, limits: [-170, 170], max_speed: 90, accel: 180,
      modbus: { bus: drives, unit: 2, profile: azd } }
YAML
GONIO_SIM_DIR=$DIR "$SIM" --rig "$DIR/rig.yaml" --dir "$DIR" --time-scale 10 > "$DIR/out" 2>&1 &
PID=$!
for _ in $(seq 100); do grep -q ready "$DIR/out" && break; sleep 0.1; done
MB="mbpoll -m rtu -b 115200 -P none -0 -1"
UNIT=1
reg() { $MB -a $UNIT -t 4:hex -r "$1" -c 1 "$DIR/drives" | sed -n 's/^\[[0-9]*\]:[[:space:]]*//p'; }
put() { R=$1; shift; $MB -a $UNIT -r "$R" "$DIR/drives" "$@" > /dev/null; }
# wait_for EXPR: up to 10 s until the shell arithmetic EXPR (reading registers) holds
wait_for() {
        for _ in $(seq 100); do
                eval "v=\$(( $1 ))"
                [ "$v" -ne 0 ] && return 0
                sleep 0.1
        done
        return 1
}

put 32 2                                   # command: home
wait_for '$(reg 0) & 2' || { echo "not homed: status $(reg 0)"; exit 1; }
put 16 0 45000                             # target 45.000 deg: high word 0, low 45000
put 32 1                                   # command: move
wait_for '$(reg 2) * 65536 + $(reg 3) == 45000 && ($(reg 0) & 8)' ||
        { echo "gonio-default: never reached 45000: status $(reg 0)"; exit 1; }
echo "gonio-default: at 45000, status $(reg 0)"

UNIT=2
put 124 0 16                               # driver input command: ZHOME on
put 124 0 0                                #   and off (the edge starts it)
wait_for '$(reg 127) & 16' || { echo "azd: no HOME-END: output $(reg 127)"; exit 1; }
# direct data operation: data No. 0, type 1 (absolute), position 4500 steps (45 deg at the
# default 100 steps/deg), 9000 Hz, rates 18000 Hz/s, current 100.0 %, trigger 1
put 88 0 0 0 1 0 4500 0 9000 0 18000 0 18000 0 1000 0 1
wait_for '$(reg 204) * 65536 + $(reg 205) == 4500 && ($(reg 127) & 16384)' ||
        { echo "azd: never reached 4500: output $(reg 127)"; exit 1; }
[ $(( $(reg 103) )) -eq 0 ] || { echo "azd: trigger not back at 0"; exit 1; }
echo "azd: at 4500, output $(reg 127), alarm $(reg 129)"
