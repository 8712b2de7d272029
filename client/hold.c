/* hold.c - gonioctl's hold mode: after `laser on` (or `lamp on` of a lamp with
 * off_on_disconnect) gonioctl keeps its connection, which keeps the switch on, listening to
 * notifications until a signal, --for or the switch going off elsewhere; then it switches the
 * switch off itself. A gonioctl killed outright closes the connection: goniod switches it off. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "client/cmd.h"
#include "client/hold.h"

#define OFF_TIMEOUT_MS 30000

struct holder {
        const char *names; /* comma-separated, as the result gave them */
        char off[64];      /* the first of them that went off, "" while all are on */
};

/* True when name is one of the comma-separated list. */
static bool listed(const char *list, const char *name)
{
        size_t n = strlen(name);

        for (const char *p = list; p && *p; p = strchr(p, ',') ? strchr(p, ',') + 1 : NULL)
                if (strncmp(p, name, n) == 0 && (p[n] == ',' || p[n] == '\0'))
                        return true;
        return false;
}

static void on_notification(const char *method, json_t *params, void *userdata)
{
        struct holder *h = userdata;
        const char *dev = json_string_value(json_object_get(params, "name"));

        if (strcmp(method, "switch.changed") == 0 && dev && !h->off[0] &&
            json_is_false(json_object_get(params, "on")) && listed(h->names, dev))
                snprintf(h->off, sizeof(h->off), "%s", dev);
}

/* Waits until a signal (-EINTR), the deadline (-ETIMEDOUT), or one of h's switches went off
 * (0); else the failure's exit code (> 0, printed). */
static int wait_hold(struct out *o, struct conn *conn, int64_t deadline, int intr_fd,
                     struct holder *h)
{
        struct conn_error e;
        int r;

        while (!h->off[0]) {
                r = conn_wait_notification(conn, deadline, intr_fd, on_notification, h, &e);
                if (r == -EINTR || r == -ETIMEDOUT)
                        return r;
                if (r < 0)
                        return cmd_call_failed(o, "hold", r, &e);
        }
        return 0;
}

int hold_switch(const struct args *a, struct out *o, struct conn *conn, const char *method,
                json_t *params, json_t *res, int intr_fd)
{
        struct holder h = {.names = json_string_value(json_object_get(res, "laser"))
                                            ?: json_string_value(json_object_get(res, "lamp"))};
        int64_t deadline =
                a->given & ARG_FOR ? conn_now_ms() + (int64_t)(a->for_s * 1000) : CONN_NO_DEADLINE;
        json_t *off = NULL;
        struct conn_error e;
        int r;

        if (!json_is_true(json_object_get(res, "on")) ||
            (!json_is_true(json_object_get(res, "off_on_disconnect")) && !(a->given & ARG_FOR)))
                return EXIT_OK;
        if (intr_fd < 0) {
                out_error(o, method, "catching signals: %s", strerror(-intr_fd));
                return EXIT_PROTOCOL;
        }
        if (!o->quiet && !o->json)
                fprintf(stderr, "gonioctl: %s on, held until %s\n", h.names ?: "?",
                        a->given & ARG_FOR ? "--for ends" : "Ctrl-C or SIGTERM");
        r = wait_hold(o, conn, deadline, intr_fd, &h);
        if (r > 0)
                return r;
        if (h.off[0]) {
                out_error(o, method,
                          "%s went off while held (switched off elsewhere, its "
                          "max_on_s, or a fault)",
                          h.off);
                return EXIT_INTERRUPTED;
        }
        json_object_set_new(params, "on", json_false());
        r = conn_call(conn, method, json_incref(params), conn_now_ms() + OFF_TIMEOUT_MS, -1, NULL,
                      NULL, &off, &e);
        json_decref(off);
        return r < 0 ? cmd_call_failed(o, method, r, &e) : EXIT_OK;
}
