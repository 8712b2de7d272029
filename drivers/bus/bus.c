/* bus.c - a physical bus (RS-485 line, TCP link, gonio-sim socket, serial line) with its
 * worker thread and its transport, and the one log format of device messages.
 *
 * DESIGN
 * Threads: a bus made by bus_new() owns one workq (common/workq.h): the worker runs the
 * jobs queued by bus_submit() one at a time, and owns the transport; no other thread
 * touches it. Results come back to the loop thread through the workq's eventfd. A bus
 * made by bus_new_sync() has no worker: its owner's thread does all of that and
 * bus_submit() runs job and done inline.
 *
 * Queue: BUS_QUEUE_MAX jobs in flight; a full queue gives -EAGAIN to the caller. Urgent
 * jobs (stop) run before any queued job and have reserved slots, but never interrupt
 * the running one: transports bound every transaction (see drivers/transport/modbus.c).
 *
 * The bus runs jobs and holds a transport, nothing more: opening, retries and protocol
 * errors belong to the transport (drivers/transport/). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/workq.h"
#include "drivers/bus/bus.h"
#include "drivers/transport/transport.h"

struct bus {
        struct rig_bus_conf conf;
        struct workq *q; /* NULL for a sync bus */
        struct transport *t;
};

struct bus_job {
        struct bus *bus;
        bus_job_fn fn;
        bus_done_fn done;
        void *userdata;
};

static int new_common(const struct rig_bus_conf *conf, struct bus **ret)
{
        struct bus *b;
        int r;

        if (!conf || !ret)
                return -EINVAL;
        b = calloc(1, sizeof(*b));
        if (!b)
                return -ENOMEM;
        b->conf = *conf;
        r = transport_new(&b->conf, &b->t);
        if (r < 0) {
                free(b);
                return log_error_errno(r, "bus '%s': No transport for this bus type: %m",
                                       conf->name);
        }
        *ret = b;
        return 0;
}

int bus_new_sync(const struct rig_bus_conf *conf, struct bus **ret)
{
        return new_common(conf, ret);
}

int bus_new(sd_event *event, const struct rig_bus_conf *conf, struct bus **ret)
{
        struct bus *b;
        int r;

        r = new_common(conf, &b);
        if (r < 0)
                return r;
        r = workq_new(event, conf->name, BUS_QUEUE_MAX, &b->q);
        if (r < 0) {
                bus_free(b);
                return log_error_errno(r, "bus '%s': Failed to start worker: %m", conf->name);
        }
        *ret = b;
        return 0;
}

struct bus *bus_free(struct bus *b)
{
        if (!b)
                return NULL;
        b->q = workq_free(b->q);
        b->t = transport_free(b->t);
        free(b);
        return NULL;
}

static int run_job(void *userdata)
{
        struct bus_job *j = userdata;

        return j->fn(j->bus, j->userdata);
}

static void job_done(int result, void *userdata)
{
        struct bus_job *j = userdata;

        if (j->done)
                j->done(j->bus, result, j->userdata);
        free(j);
}

int bus_submit(struct bus *b, bus_job_fn job, bus_done_fn done, void *userdata, bool urgent)
{
        struct bus_job *j;
        int r;

        if (!b || !job)
                return -EINVAL;
        if (!b->q) {
                r = job(b, userdata);
                if (done)
                        done(b, r, userdata);
                return 0;
        }
        j = malloc(sizeof(*j));
        if (!j)
                return -ENOMEM;
        *j = (struct bus_job){.bus = b, .fn = job, .done = done, .userdata = userdata};
        r = workq_push(b->q, run_job, job_done, j, urgent);
        if (r < 0)
                free(j);
        return r;
}

const struct rig_bus_conf *bus_conf(const struct bus *b)
{
        return &b->conf;
}

struct transport *bus_transport(const struct bus *b)
{
        return b->t;
}

/* "PORT#ADDR": the port's last path component (host:port for TCP), the address's value left
 * out when it has none. */
static void where(const struct bus *b, const struct rig_addr *addr, char *buf, size_t len)
{
        const struct rig_bus_conf *c = &b->conf;
        const char *slash = strrchr(c->port, '/');
        int k;

        if (c->type == RIG_BUS_MODBUS_TCP)
                k = snprintf(buf, len, "%s:%d", c->host, c->tcp_port);
        else if (c->type == RIG_BUS_LOCAL) /* no port: its name */
                k = snprintf(buf, len, "%s", c->name);
        else
                k = snprintf(buf, len, "%s", slash ? slash + 1 : c->port);
        if (addr && addr->key && k >= 0 && (size_t)k < len)
                snprintf(buf + k, len - k, "#%d", addr->value);
}

int bus_log_dev(const struct bus *b, const struct bus_dev_ref *dev, int level, int err,
                const char *fmt, va_list ap)
{
        char loc[RIG_PATH_MAX + 16], msg[1024];
        int saved = errno;

        where(b, dev->addr, loc, sizeof(loc));
        errno = err < 0 ? -err : err;
        vsnprintf(msg, sizeof(msg), fmt, ap);
        errno = saved;
        if (dev->last_error && level <= GN_LOG_WARNING)
                snprintf(dev->last_error, dev->last_error_len, "%s '%s' [%s@%s]: %s", dev->kind,
                         dev->name, dev->backend, loc, msg);
        return gn_log_full_errno(level, err, "%s '%s' [%s@%s]: %s", dev->kind, dev->name,
                                 dev->backend, loc, msg);
}

int bus_dev_cause(char *buf, size_t len, int err, const char *fmt, va_list ap)
{
        int saved = errno;

        errno = err < 0 ? -err : err;
        vsnprintf(buf, len, fmt, ap);
        errno = saved;
        return err < 0 ? err : -err;
}
