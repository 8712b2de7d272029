/* wait.h - gonioctl wait [--state STATE]: until goniod reports a rig state (docs/gonioctl.md,
 * "wait"), from its state.changed notifications and a status poll. */
#pragma once

#include <stdbool.h>

#include "client/args.h"
#include "client/conn.h"
#include "client/output.h"

/* True when s names a rig state of docs/protocol.md ("idle", "moving", "fault"...). */
bool wait_state_known(const char *s);

/* Waits on conn (hello done) until the rig state is a->state (default "idle"). Returns EXIT_OK
 * with {state, waited_s} printed; EXIT_INTERRUPTED after --timeout (a->timeout_s; none: no
 * limit), Ctrl-C or SIGTERM; EXIT_DEVICE when the rig latches a fault while waiting for
 * another state; the exit code of a failed status call. The error is printed. */
int wait_command(const struct args *a, struct out *o, struct conn *conn);
