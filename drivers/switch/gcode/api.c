/* api.c - the "gcode-laser" switch backend: a laser output of the Horus/Ciclop board, on
 * the G-code line it shares with the board's turntable axis (drivers/axis/gcode/link.h).
 * The firmware has no command to read a laser back: the state is the last one the board
 * confirmed with "ok", dropped by a reset of the board (its lasers start off) and by the
 * firmware's own 255 s limit. */
#include <errno.h>
#include <stdlib.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/axis/gcode/link.h"
#include "drivers/switch/gcode/proto.h"
#include "drivers/transport/transport.h"

struct gcsw {
        const struct gcsw_conf *conf; /* borrowed from the rig config */
        struct gclink *link;
        bool on;         /* confirmed by the board */
        unsigned resets; /* the link's reset count when it was confirmed */
        uint64_t on_ns;  /* CLOCK_MONOTONIC when switched on */
};

static const struct opt_desc gcsw_opts[] = {
        {OPT_STATE, OPT_GET | OPT_SET},
};

static int link_result(struct sw *s, int r)
{
        struct gcsw *m = s->priv;

        if (r >= 0)
                return r;
        return sw_set_cause(s, r, "%s",
                            m ? gclink_cause(m->link) : transport_cause(bus_transport(s->bus)));
}

static int gcsw_open(struct sw *s)
{
        const struct gcsw_conf *c = s->conf->backend.conf;
        struct gcsw *m;
        int r;

        if (!c)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EINVAL),
                                    "no G-code laser settings (not loaded from a rig file)");
        if (!s->priv) {
                m = calloc(1, sizeof(*m));
                if (!m)
                        return -ENOMEM;
                *m = (struct gcsw){.conf = c};
                r = gclink_attach(s->bus, GC_FLAVOR_HORUS, &m->link);
                if (r < 0) {
                        free(m);
                        return link_result(s, r);
                }
                s->priv = m;
        }
        return link_result(s, gclink_sync(((struct gcsw *)s->priv)->link));
}

static void gcsw_close(struct sw *s)
{
        struct gcsw *m = s->priv;

        if (!m)
                return;
        free(m);
        s->priv = NULL;
}

static int gcsw_set(struct sw *s, bool on)
{
        struct gcsw *m = s->priv;
        char line[16];
        int r;

        if (!m)
                return -ENOTCONN;
        r = gcsw_format(line, sizeof(line), m->conf->tool, on);
        if (r >= 0)
                r = link_result(s, gclink_command(m->link, line));
        if (r < 0)
                return r;
        m->on = on;
        m->resets = m->link->resets;
        m->on_ns = gn_monotonic_ns();
        return 0;
}

static int gcsw_get(struct sw *s, bool *on)
{
        struct gcsw *m = s->priv;
        int r;

        if (!m)
                return -ENOTCONN;
        r = link_result(s, gclink_sync(m->link));
        if (r >= 0)
                r = link_result(s, gclink_drain(m->link));
        if (r < 0)
                return r;
        *on = m->on && m->resets == m->link->resets &&
              gn_monotonic_ns() - m->on_ns < (uint64_t)GCSW_AUTO_OFF_S * 1000000000u;
        return 0;
}

const struct rig_backend gcsw_backend = {
        .name = "gcode-laser",
        .cls = RIG_CLASS_SWITCH,
        .bus_types = 1u << RIG_BUS_SERIAL,
        .conf_size = sizeof(struct gcsw_conf),
        .parse_conf = gcsw_parse_conf,
        .ops = &gcsw_ops,
};

const struct sw_ops gcsw_ops = {
        .name = "gcode-laser",
        .opts = gcsw_opts,
        .n_opts = ELEMENTSOF(gcsw_opts),
        .open = gcsw_open,
        .close = gcsw_close,
        .set = gcsw_set,
        .get = gcsw_get,
};
