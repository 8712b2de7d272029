#!/bin/sh
# parallel.sh N TEST ARGS... - runs N copies of an end-to-end test at once (each with its own
# simulator and daemon) and fails unless every copy passes: the machine loaded this way
# widens the races between a drive's answers and goniod's commands (e2e-daemon-parallel
# found a poll queued before a move taken for the move's arrival).
n=$1
shift
i=0
pids=
while [ "$i" -lt "$n" ]; do
        "$@" > "${TMPDIR:-/tmp}/e2e-parallel.$$.$i.log" 2>&1 &
        pids="$pids $!"
        i=$((i + 1))
done
failed=0
i=0
for pid in $pids; do
        if ! wait "$pid"; then
                echo "copy $i failed:"
                cat "${TMPDIR:-/tmp}/e2e-parallel.$$.$i.log"
                failed=$((failed + 1))
        fi
        rm -f "${TMPDIR:-/tmp}/e2e-parallel.$$.$i.log"
        i=$((i + 1))
done
echo "$failed of $n copies failed"
[ "$failed" -eq 0 ]
