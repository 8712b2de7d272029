#!/bin/sh
# gpio-goniod.sh GONIOD GONIOCTL [unplug] - kernel lane: goniod drives the gpio-stepper axis and
# a gpio lamp on gpio-sim's chip "gonio-gpio" through gonioctl: homing that ends when the home
# switch is made (its simulated pull written to gpio-sim's sysfs meanwhile), a move, a stop
# mid-move, the lamp on and off; levels and positions checked in gpio-sim's sysfs and in
# goniod's replies. With "unplug" (a test of its own, so each has the lane's per-test time):
# the chip unplugged mid-move (gpio-sim's configfs `live` set to 0): a fault naming the chip,
# `fault clear` refused while it is gone and accepted once it is back, the axis unhomed, its
# enable line and the lamp driven again.
set -eu
goniod=$1 gonioctl=$2 mode=${3:-motion}
case $mode in motion | unplug) ;; *) echo "gpio-goniod: unknown mode $mode" >&2; exit 2 ;; esac
dir=$(mktemp -d /tmp/gonio-gpio-goniod.XXXXXX)
pid=
live=/sys/kernel/config/gpio-sim/gonio/live
# goniod is stopped and waited for before its files go (it closes its dataset on the way out);
# gpio-sim's chip is plugged back in for the lane's next test, even after a failure
cleanup() {
        [ -z "$pid" ] || { kill "$pid" 2> /dev/null || true; wait "$pid" 2> /dev/null || true; }
        echo 1 > "$live" 2> /dev/null || true
        rm -rf "$dir" || true
}
trap cleanup EXIT
fail() { echo "gpio-goniod: $*" >&2; exit 1; }

# gpio-sim's sysfs attribute of a named line: /sys/bus/gpio/devices/gpiochipN/sim_gpioK/ATTR
sim() { set -- $(gpiofind "$1") "$2"; echo "/sys/bus/gpio/devices/$1/sim_gpio$2/$3"; }
echo pull-down > "$(sim home pull)"

cat > "$dir/rig.yaml" << EOF
rig: gpio-goniod
buses:
  - { name: io, type: local }
axes:
  - { name: arm, limits: [-90, 90], max_speed: 4, accel: 20,
      gpio-stepper: { bus: io, chip: gonio-gpio, step: step, dir: dir, enable: enable,
                      home: home, steps_per_deg: 10, home_speed: 3 } }
lamps:
  - { name: lamp0, elevation: 10, gpio: { bus: io, chip: gonio-gpio, line: lamp } }
EOF
"$goniod" --rig "$dir/rig.yaml" --socket "$dir/sock" --data "$dir/data" 2> "$dir/log" &
pid=$!
# gonioctl's stderr to a file: on the guest's console it would draw progress lines
ctl() {
        "$gonioctl" --socket "$dir/sock" --timeout 20 "$@" 2> "$dir/ctl.err" ||
                { cat "$dir/ctl.err" >&2; return 1; }
}
i=0
until ctl --quiet status 2> /dev/null; do
        i=$((i + 1))
        [ $i -lt 100 ] || { cat "$dir/log" >&2; fail "goniod did not come up"; }
        sleep 0.1
done

motion() {
        # homing: the switch is made a second into it; goniod answers once the axis is homed
        (sleep 1; echo pull-up > "$(sim home pull)") &
        out=$(ctl home arm) || { cat "$dir/log" >&2; fail "home failed"; }
        echo "$out"
        echo "$out" | grep -Eq '^arm +0\.000' || fail "home: $out"
        echo pull-down > "$(sim home pull)"

        out=$(ctl move arm 3)
        echo "$out"
        echo "$out" | grep -Eq '^arm +3\.000' || fail "move: $out"
        [ "$(cat "$(sim dir value)")" = 1 ] || fail "dir line not high after a move up"

        ctl move arm 60 --no-wait
        sleep 1
        ctl stop
        sleep 0.5
        pos=$(ctl --json status | grep -o '"position": *[0-9.-]*' | head -1 | grep -o '[0-9.-]*$')
        echo "stopped at $pos deg"
        awk "BEGIN { exit !($pos > 3.5 && $pos < 20) }" || fail "stop: at $pos deg"

        ctl lamp lamp0 on
        [ "$(cat "$(sim lamp value)")" = 1 ] || fail "lamp on: line low"
        ctl lamp lamp0 off
        [ "$(cat "$(sim lamp value)")" = 0 ] || fail "lamp off: line high"
        echo "gpio-goniod: home, move, stop and lamp through goniod"
}

# unplugged mid-move: the fault names the axis and the chip within a second or two; homed
# first (at once: the home switch is made when homing starts), the lamp on
unplug() {
        echo pull-up > "$(sim home pull)"
        ctl home arm > /dev/null
        echo pull-down > "$(sim home pull)"
        ctl lamp lamp0 on
        ctl move arm 60 --no-wait
        sleep 0.5
        echo 0 > "$live"
        i=0
        until ctl --json status > "$dir/status" && grep -q '"state": *"fault"' "$dir/status"; do
                i=$((i + 1))
                [ $i -lt 30 ] ||
                        { cat "$dir/status" "$dir/log" >&2; fail "no fault after the unplug"; }
                sleep 0.1
        done
        grep -q '"device": *"arm"' "$dir/status" || fail "fault not on arm: $(cat "$dir/status")"
        grep -q "GPIO chip 'gonio-gpio' (gpiochip[0-9]*) is gone (unplugged?) while stepping" \
                "$dir/status" || fail "fault message: $(cat "$dir/status")"
        echo "unplugged: fault on arm after $i polls of the status"
        # refused while the chip is gone, naming it
        if "$gonioctl" --socket "$dir/sock" --timeout 20 fault clear 2> "$dir/ctl.err"; then
                fail "fault clear accepted while the chip is gone"
        fi
        grep -q "GPIO chip 'gonio-gpio' is still gone" "$dir/ctl.err" ||
                fail "fault clear refused, but: $(cat "$dir/ctl.err")"
        # plugged back (perhaps as another gpiochipN): clear reopens; the axis must be homed again
        echo 1 > "$live"
        ctl fault clear || { cat "$dir/log" >&2; fail "fault clear refused after the replug"; }
        ctl --json status | grep -q '"homed": *false' || fail "arm still homed after the replug"
        if "$gonioctl" --socket "$dir/sock" --timeout 20 move arm 3 2> "$dir/ctl.err"; then
                fail "an absolute move accepted on an unhomed axis"
        fi
        grep -q "not homed" "$dir/ctl.err" || fail "move refused, but: $(cat "$dir/ctl.err")"
        [ "$(cat "$(sim enable value)")" = 1 ] || fail "enable line low after the replug"
        ctl lamp lamp0 on
        [ "$(cat "$(sim lamp value)")" = 1 ] || fail "lamp on after the replug: line low"
        echo "gpio-goniod: unplug mid-move, fault clear refused while gone, reopened once back"
}

"$mode"
