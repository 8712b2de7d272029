/* switch.c - the switch class (lamps, laser, spare outputs): backend lookup, logging
 * wrappers, confirmed cached state and the lamp warm-up time. */
#include <stdarg.h>
#include <stdlib.h>
#include <time.h>

#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/registry.h"
#include "drivers/switch/switch.h"

int sw_log_full(struct sw *s, int level, int err, const char *fmt, ...)
{
        const struct bus_dev_ref ref = {"switch",      s->conf->name,
                                        s->ops->name,  &s->conf->backend.addr,
                                        s->last_error, sizeof(s->last_error)};
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_log_dev(s->bus, &ref, level, err, fmt, ap);
        va_end(ap);
        return r;
}

int sw_set_cause(struct sw *s, int err, const char *fmt, ...)
{
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_dev_cause(s->cause, sizeof(s->cause), err, fmt, ap);
        va_end(ap);
        return r;
}

/* Logs the failure of the op WHAT with the backend's cause, or strerror(r). */
static int fail(struct sw *s, int r, const char *what)
{
        if (s->cause[0])
                return sw_log_full(s, GN_LOG_ERR, r, "Failed to %s: %s", what, s->cause);
        return sw_log_full(s, GN_LOG_ERR, r, "Failed to %s: %m", what);
}

int sw_new(const struct rig_switch_conf *conf, struct bus *bus, struct sw **ret)
{
        const struct sw_ops *ops;
        struct sw *s;

        if (!conf || !bus || !ret)
                return -EINVAL;
        ops = registry_switch(conf->backend.name);
        if (!ops)
                return log_error_errno(SYNTHETIC_ERRNO(ENOENT), "switch '%s': Unknown backend '%s'",
                                       conf->name, conf->backend.name);
        s = calloc(1, sizeof(*s));
        if (!s)
                return -ENOMEM;
        *s = (struct sw){.ops = ops, .conf = conf, .bus = bus};
        *ret = s;
        return 0;
}

struct sw *sw_free(struct sw *s)
{
        if (!s)
                return NULL;
        if (s->ops->close)
                s->ops->close(s);
        free(s);
        return NULL;
}

int sw_get(struct sw *s, bool *on)
{
        bool v;
        int r;

        s->cause[0] = '\0';
        r = s->ops->get(s, &v);
        if (r < 0)
                return fail(s, r, "read the state");
        s->on = v;
        if (on)
                *on = v;
        return 0;
}

int sw_open(struct sw *s)
{
        int r;

        s->cause[0] = '\0';
        if (s->ops->open) {
                r = s->ops->open(s);
                if (r < 0)
                        return fail(s, r, "open");
        }
        return sw_get(s, NULL);
}

/* Sleeps on the calling (worker) thread; restarts after signals. */
static void sleep_ms(int ms)
{
        struct timespec ts = {.tv_sec = ms / 1000, .tv_nsec = (long)(ms % 1000) * 1000000L};

        while (clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, &ts) == EINTR)
                ;
}

int sw_set(struct sw *s, bool on)
{
        int r;

        s->cause[0] = '\0';
        r = s->ops->set(s, on);
        if (r < 0)
                return fail(s, r, on ? "switch on" : "switch off");
        s->on = on;
        if (on && s->conf->warmup_ms > 0)
                sleep_ms(s->conf->warmup_ms); /* lamp warm-up: part of the device */
        log_debug("switch '%s': %s", s->conf->name, on ? "on" : "off");
        return 0;
}
