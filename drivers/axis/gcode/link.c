/* link.c - the session with one G-code controller on a serial line (see link.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "drivers/axis/gcode/link.h"
#include "drivers/transport/transport.h"

static struct transport *tp(const struct gclink *l)
{
        return bus_transport(l->bus);
}

static int timeout_ms(const struct gclink *l)
{
        int ms = bus_conf(l->bus)->timeout_ms;

        return ms > 0 ? ms : 200;
}

int gclink_attach(struct bus *b, enum gc_flavor flavor, struct gclink **ret)
{
        struct transport *t = bus_transport(b);
        struct gclink *l = t->priv;

        if (t->ops->type != RIG_BUS_SERIAL)
                return transport_set_cause(t, SYNTHETIC_ERRNO(EINVAL), "bus '%s' is no serial line",
                                           bus_conf(b)->name);
        if (l && l->flavor != flavor)
                return transport_set_cause(t, SYNTHETIC_ERRNO(EINVAL),
                                           "the controller on %s is %s, not %s", bus_conf(b)->port,
                                           gc_flavor_name(l->flavor), gc_flavor_name(flavor));
        if (!l) {
                l = calloc(1, sizeof(*l));
                if (!l)
                        return -ENOMEM;
                *l = (struct gclink){.bus = b, .flavor = flavor};
                t->priv = l;
                t->priv_free = free;
        }
        *ret = l;
        return 0;
}

const char *gclink_cause(const struct gclink *l)
{
        return transport_cause(tp(l));
}

/* A failure that leaves the session in an unknown state: the next use resets. */
static int desync(struct gclink *l, int r)
{
        l->synced = false;
        return r;
}

/* The reply to an asynchronous line. */
static void owed_reply(struct gclink *l, const struct gc_line *p, const char *line)
{
        l->owed--;
        if (p->kind == GC_LINE_ERROR && !l->async_error) {
                l->async_error = -EPROTO;
                snprintf(l->async_cause, sizeof(l->async_cause), "%s", line);
        } else if (p->kind == GC_LINE_OK && l->owed_home)
                l->homed = true;
        if (l->owed == 0)
                l->owed_home = false;
}

/* Updates the controller's state from one line. Returns true when the line is the reply
 * to a synchronous command (an ok or error not owed to an asynchronous line). */
static bool handle(struct gclink *l, const char *line, const struct gc_line *p)
{
        switch (p->kind) {
        case GC_LINE_GREETING:
                l->resets++;
                l->owed = 0;
                l->owed_home = false;
                l->homed = false;
                l->motor_on = false;
                return false;
        case GC_LINE_ALARM:
                l->alarm = true;
                l->alarm_code = p->code ? p->code : -1;
                return false;
        case GC_LINE_MSG:
                l->alarm = p->unlocked ? false : l->alarm || p->alarm_lock;
                return false;
        case GC_LINE_STATUS:
                l->alarm = p->status.state == GC_ST_ALARM;
                return false;
        case GC_LINE_OK:
        case GC_LINE_ERROR:
                if (l->owed > 0) {
                        owed_reply(l, p, line);
                        return false;
                }
                return true;
        case GC_LINE_OTHER:
                snprintf(l->value, sizeof(l->value), "%s", line);
                return false;
        default:
                return false;
        }
}

/* Reads one line before deadline into buf (GC_LINE_MAX) and handles it. Returns 1 for the
 * reply to a synchronous command, 0 for another line, -errno. */
static int read_one(struct gclink *l, int64_t deadline, char *buf, struct gc_line *p)
{
        ssize_t n = transport_read_line(tp(l), buf, GC_LINE_MAX, deadline);

        if (n < 0)
                return (int)n;
        if (gc_parse_line(buf, p) < 0)
                return transport_set_cause(tp(l), SYNTHETIC_ERRNO(EPROTO),
                                           "unreadable status report '%s'", buf);
        return handle(l, buf, p);
}

int gclink_drain(struct gclink *l)
{
        char buf[GC_LINE_MAX];
        struct gc_line p;

        for (;;) {
                int r = read_one(l, transport_deadline(0), buf, &p);
                if (r == -ETIMEDOUT)
                        return 0;
                if (r < 0)
                        return desync(l, r);
                if (r == 1)
                        return desync(l, transport_set_cause(tp(l), SYNTHETIC_ERRNO(EPROTO),
                                                             "unexpected reply '%s'", buf));
        }
}

static int write_bytes(struct gclink *l, const char *s, size_t n)
{
        int r = transport_write_all(tp(l), s, n, transport_deadline(timeout_ms(l)));

        return r < 0 ? desync(l, r) : 0;
}

int gclink_realtime(struct gclink *l, char c)
{
        return write_bytes(l, &c, 1);
}

/* Reads lines until one of kind want comes, before deadline. what names the request in the
 * cause of a timeout. Returns 0 or -errno. */
static int wait_kind(struct gclink *l, enum gc_line_kind want, int64_t deadline, int ms,
                     const char *what, struct gc_line *p)
{
        char buf[GC_LINE_MAX];

        for (;;) {
                int r = read_one(l, deadline, buf, p);
                if (r == -ETIMEDOUT)
                        return desync(
                                l, transport_set_cause(tp(l), r, "no %s within %d ms", what, ms));
                if (r < 0)
                        return desync(l, r);
                if (p->kind == want)
                        return 0;
        }
}

int gclink_status(struct gclink *l, struct gc_status *st)
{
        struct gc_line p;
        int r = gclink_realtime(l, GC_RT_STATUS);

        if (r >= 0)
                r = wait_kind(l, GC_LINE_STATUS, transport_deadline(timeout_ms(l)), timeout_ms(l),
                              "status report", &p);
        if (r >= 0)
                *st = p.status;
        return r;
}

int gclink_reset(struct gclink *l)
{
        struct gc_status st;
        struct gc_line p;
        char c = GC_RT_RESET;
        bool homed = l->homed;
        int r = write_bytes(l, &c, 1);

        if (r < 0)
                return r;
        r = wait_kind(l, GC_LINE_GREETING, transport_deadline(GCLINK_GREETING_MS),
                      GCLINK_GREETING_MS, "greeting after reset (Ctrl-X)", &p);
        if (r < 0)
                return r;
        if (p.flavor != l->flavor)
                return desync(l, transport_set_cause(tp(l), SYNTHETIC_ERRNO(EPROTO),
                                                     "the controller greets as %s, not %s",
                                                     gc_flavor_name(p.flavor),
                                                     gc_flavor_name(l->flavor)));
        l->alarm_code = 0;
        l->async_error = 0;
        l->synced = true;
        r = gclink_status(l, &st); /* the alarm lock message comes before it */
        /* Both firmwares keep their step count over a soft reset; GRBL says the position is
         * lost (alarm) when the reset stopped motion, Horus does not (docs/gcode.md). */
        l->homed = r >= 0 && homed && !(l->flavor == GC_FLAVOR_GRBL && l->alarm);
        return r;
}

int gclink_sync(struct gclink *l)
{
        struct transport *t = tp(l);
        int r;

        if (l->synced && t->is_open)
                return 0;
        r = transport_open(t);
        if (r < 0)
                return r;
        transport_flush(t);
        l->alarm = false;
        l->homed = false; /* a new session: whatever happened before is unknown */
        return gclink_reset(l);
}

/* Syncs and drains; -EBUSY while a reply is owed. */
static int ready(struct gclink *l, const char *line)
{
        int r = gclink_sync(l);

        if (r >= 0)
                r = gclink_drain(l);
        if (r >= 0 && l->owed > 0)
                return transport_set_cause(tp(l), SYNTHETIC_ERRNO(EBUSY),
                                           "cannot send '%s': the controller answers only when "
                                           "its motion has ended",
                                           line);
        return r;
}

static int write_line(struct gclink *l, const char *line)
{
        char buf[GC_LINE_MAX + 2];
        int n = snprintf(buf, sizeof(buf), "%s\n", line);

        if (n < 0 || (size_t)n >= sizeof(buf))
                return -ENOBUFS;
        return write_bytes(l, buf, (size_t)n);
}

int gclink_command(struct gclink *l, const char *line)
{
        char buf[GC_LINE_MAX];
        struct gc_line p;
        int64_t deadline;
        int r = ready(l, line);

        if (r >= 0)
                r = write_line(l, line);
        if (r < 0)
                return r;
        deadline = transport_deadline(timeout_ms(l));
        for (;;) {
                r = read_one(l, deadline, buf, &p);
                if (r == -ETIMEDOUT)
                        return desync(l,
                                      transport_set_cause(tp(l), r, "no reply to '%s' within %d ms",
                                                          line, timeout_ms(l)));
                if (r < 0)
                        return desync(l, r);
                if (p.kind == GC_LINE_GREETING)
                        return transport_set_cause(tp(l), SYNTHETIC_ERRNO(ECONNRESET),
                                                   "the controller reset before answering '%s'",
                                                   line);
                if (r == 1 && p.kind == GC_LINE_OK)
                        return 0;
                if (r == 1)
                        return transport_set_cause(tp(l), SYNTHETIC_ERRNO(EPROTO), "'%s': %s", line,
                                                   buf);
        }
}

int gclink_command_async(struct gclink *l, const char *line, bool home)
{
        int r = ready(l, line);

        if (r >= 0)
                r = write_line(l, line);
        if (r < 0)
                return r;
        l->owed++;
        l->owed_home = home;
        l->async_error = 0;
        return 0;
}
