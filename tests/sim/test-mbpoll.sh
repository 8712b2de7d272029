#!/bin/sh
# test-mbpoll.sh GONIO_SIM - gonio-sim's Modbus drive emulator driven by Debian's mbpoll,
# a Modbus master nobody here wrote: home the drive, write a target (int32, high word
# first, 1/1000 degree) and the move command, and read the position until it is there
# (registers of docs/modbus-profile.md). Skips (77) without mbpoll.
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
YAML
GONIO_SIM_DIR=$DIR "$SIM" --rig "$DIR/rig.yaml" --dir "$DIR" --time-scale 10 > "$DIR/out" 2>&1 &
PID=$!
for _ in $(seq 100); do grep -q ready "$DIR/out" && break; sleep 0.1; done
MB="mbpoll -m rtu -b 115200 -P none -a 1 -0 -1"
reg() { $MB -t 4:hex -r "$1" -c 1 "$DIR/drives" | sed -n 's/^\[[0-9]*\]:[[:space:]]*//p'; }
put() { R=$1; shift; $MB -r "$R" "$DIR/drives" "$@" > /dev/null; }
put 32 2                                   # command: home
for _ in $(seq 100); do [ $(( $(reg 0) & 2 )) -ne 0 ] && break; sleep 0.1; done
[ $(( $(reg 0) & 2 )) -ne 0 ] || { echo "not homed: status $(reg 0)"; exit 1; }
put 16 0 45000                             # target 45.000 deg: high word 0, low 45000
put 32 1                                   # command: move
for _ in $(seq 100); do
        pos=$(( $(reg 2) * 65536 + $(reg 3) ))
        st=$(reg 0)
        [ "$pos" -eq 45000 ] && [ $(( st & 8 )) -ne 0 ] && { echo "at $pos, status $st"; exit 0; }
        sleep 0.1
done
echo "never reached 45000: position $pos, status $st"
exit 1
