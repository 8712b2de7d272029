/* wait.c - gonioctl wait: asks status, then listens to state.changed notifications and asks
 * status again every POLL_MS (a notification missed or a state that never changes still
 * ends the wait), until the rig is in the wanted state, a fault latches, or the deadline. */
#include <errno.h>
#include <string.h>

#include "client/cmd.h"
#include "client/wait.h"
#include "common/cleanup.h"

#define POLL_MS   250
#define STATUS_MS 30000 /* for one status reply */

static const char *const states[] = {"idle",      "homing",  "moving", "stopping",
                                     "capturing", "storing", "fault"};

struct waiter {
        const char *want;
        bool reached; /* a notification said the rig is in the state */
};

bool wait_state_known(const char *s)
{
        for (size_t i = 0; i < ELEMENTSOF(states); i++)
                if (strcmp(states[i], s) == 0)
                        return true;
        return false;
}

static void on_notification(const char *method, json_t *params, void *userdata)
{
        struct waiter *w = userdata;
        const char *s = json_string_value(json_object_get(params, "state"));

        if (strcmp(method, "state.changed") == 0 && s && strcmp(s, w->want) == 0)
                w->reached = true;
}

/* Asks status: 1 when the rig is in w->want, 0 when not, or an exit code after printing
 * why (< 0 as -exit code): a latched fault while waiting for another state, a failed call. */
static int poll_status(struct out *o, struct conn *conn, struct waiter *w, int64_t deadline,
                       int intr_fd)
{
        _cleanup_(json_decrefp) json_t *st = NULL;
        struct conn_error e;
        int64_t until = MIN(deadline, conn_now_ms() + STATUS_MS);
        int r = conn_call(conn, "status", json_object(), until, intr_fd, on_notification, w, &st,
                          &e);
        const char *state;
        json_t *fault;

        if (r == -EINTR || (r == -ETIMEDOUT && until == deadline))
                return r;
        if (r < 0)
                return -cmd_call_failed(o, "wait", r, &e);
        state = json_string_value(json_object_get(st, "state")) ?: "";
        fault = json_object_get(st, "fault");
        if (w->reached || strcmp(state, w->want) == 0)
                return 1;
        if (strcmp(state, "fault") == 0) {
                out_error(o, "wait", "the rig is in fault (%s: %s), not %s",
                          json_string_value(json_object_get(fault, "device")) ?: "?",
                          json_string_value(json_object_get(fault, "message")) ?: "?", w->want);
                return -EXIT_DEVICE;
        }
        return 0;
}

/* Says why the wait ended early (r: -EINTR or -ETIMEDOUT) and returns EXIT_INTERRUPTED. */
static int interrupted(struct out *o, const struct args *a, const char *want, int r)
{
        if (r == -ETIMEDOUT)
                out_error(o, "wait", "timed out after %g s waiting for state %s", a->timeout_s,
                          want);
        else
                out_error(o, "wait", "interrupted waiting for state %s", want);
        json_decref(o->error_detail);
        o->error_detail = json_pack("{s:s}", "cause", r == -ETIMEDOUT ? "timeout" : "signal");
        return EXIT_INTERRUPTED;
}

int wait_command(const struct args *a, struct out *o, struct conn *conn)
{
        struct waiter w = {.want = a->state ?: "idle"};
        int64_t start = conn_now_ms();
        int64_t deadline =
                a->timeout_s > 0 ? start + (int64_t)(a->timeout_s * 1000) : CONN_NO_DEADLINE;
        _cleanup_close_ int intr_fd = cmd_intr_fd();
        struct conn_error e;
        json_t *res;
        int r;

        while ((r = poll_status(o, conn, &w, deadline, intr_fd)) == 0) {
                r = conn_wait_notification(conn, MIN(deadline, conn_now_ms() + POLL_MS), intr_fd,
                                           on_notification, &w, &e);
                if (r == -EINTR || (r == -ETIMEDOUT && conn_now_ms() >= deadline))
                        break;
                if (r < 0 && r != -ETIMEDOUT)
                        return cmd_call_failed(o, "wait", r, &e);
        }
        if (r == -EINTR || r == -ETIMEDOUT)
                return interrupted(o, a, w.want, r);
        if (r < 0)
                return -r;
        res = json_pack("{s:s,s:f}", "state", w.want, "waited_s",
                        (double)(conn_now_ms() - start) / 1000);
        out_result(o, NULL, w.want, res);
        json_decref(res);
        return EXIT_OK;
}
