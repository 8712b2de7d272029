# goniod-lib.sh - sourced by the kernel lane's *-goniod.sh scripts after they set name, sim
# (gonio-sim, when used), goniod and gonioctl: a scratch directory $dir, gonio-sim and goniod
# started in it and stopped on exit, gonioctl on goniod's socket.
#   fail MSG...        prints "$name: MSG" and the logs of gonio-sim and goniod, exits 1
#   wait_for N MSG CMD runs CMD every 0.1 s until it succeeds; fails with MSG after N tries
#   ctl ARGS...        gonioctl on goniod's socket (its stderr shown only when it fails)
#   start_sim RIG ARG  gonio-sim on RIG with --dir $dir and ARGs, returns once it is ready
#   start_goniod RIG   goniod on RIG, its log in $dir/log, returns once it answers
# A script adds the pids of its own background jobs to $pids to have them stopped too.
dir=$(mktemp -d "/tmp/gonio-$name.XXXXXX")
pids=
# goniod and gonio-sim are stopped and waited for before their files go (goniod closes its
# dataset on the way out)
cleanup() {
        for p in $pids; do kill "$p" 2> /dev/null || true; done
        for p in $pids; do wait "$p" 2> /dev/null || true; done
        rm -rf "$dir" || true
}
trap cleanup EXIT
fail() {
        echo "$name: $*" >&2
        cat "$dir/sim.out" "$dir/log" >&2 2> /dev/null || true
        exit 1
}
# gonioctl's stderr to a file: on the guest's console it would draw progress lines
ctl() {
        "$gonioctl" --socket "$dir/sock" --timeout 60 "$@" 2> "$dir/ctl.err" ||
                { cat "$dir/ctl.err" >&2; return 1; }
}
wait_for() {
        local n=$1 what=$2
        shift 2
        until "$@"; do
                n=$((n - 1)); [ $n -gt 0 ] || fail "$what"; sleep 0.1
        done
}
start_sim() {
        local rig=$1
        shift
        "$sim" --rig "$rig" --dir "$dir" "$@" > "$dir/sim.out" 2>&1 &
        pids="$pids $!"
        wait_for 100 "gonio-sim did not come up" grep -q ready "$dir/sim.out"
}
answers() { ctl --quiet status 2> /dev/null; }
start_goniod() {
        "$goniod" --rig "$1" --socket "$dir/sock" --data "$dir/data" 2> "$dir/log" &
        pids="$pids $!"
        wait_for 150 "goniod did not come up" answers
}
