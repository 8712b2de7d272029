/* api.c - the "modbus" axis backend: a servo/stepper drive behind a register profile
 * (docs/modbus-profile.md), through the Modbus transport's retrying transactions. It does
 * the I/O that the profile's family (proto.h) describes: the writes of a move or a command,
 * the reads of a poll. Runs on the bus worker; caches nothing from the drive: every state
 * comes from it. The unit and the profile come from the backend map, parsed and resolved
 * when the rig file loads; families whose moves carry the speed and acceleration take them
 * from the axis (ax->speed, ax->accel). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/bus/bus.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"

/* Registers read in one request when a poll's spans lie this close. */
#define STATE_BLOCK_MAX 32

/* The backend's state while open. */
struct mbax {
        const struct mbax_conf *conf; /* borrowed from the rig config */
};

static const struct opt_desc mbax_opts[] = {
        {OPT_POSITION, OPT_GET | OPT_SET, .unit = "deg"},
        {OPT_HOME, OPT_SET},
        {OPT_STOP, OPT_SET},
};

/* The settings of an open axis, or NULL before open. */
static const struct mbax_conf *conf(const struct axis *ax)
{
        const struct mbax *m = ax->priv;

        return m ? m->conf : NULL;
}

/* Register accesses that name what failed: "read position (reg 0x0102): cause", or the
 * port alone when it could not be opened. */
static int reg_result(struct axis *ax, int r, const char *what, int reg)
{
        const struct transport *t = bus_transport(ax->bus);

        if (r >= 0)
                return r;
        if (t->open_failed)
                return axis_set_cause(ax, r, "%s", transport_cause(t));
        return axis_set_cause(ax, r, "%s (reg 0x%04x): %s", what, (unsigned)reg,
                              transport_cause(t));
}

static int read_regs(struct axis *ax, const char *what, int reg, int n, uint16_t *dest)
{
        return reg_result(ax, mbus_read_regs(bus_transport(ax->bus), conf(ax)->unit, reg, n, dest),
                          what, reg);
}

/* Writes w[0..n) in order, each in one request; stops at the first failure. */
static int write_all(struct axis *ax, const struct mbax_write *w, int n)
{
        struct transport *t = bus_transport(ax->bus);
        int unit = conf(ax)->unit, r = n;

        for (int i = 0; r >= 0 && i < n; i++)
                r = reg_result(ax,
                               w[i].n == 1 ? mbus_write_reg(t, unit, w[i].addr, w[i].regs[0])
                                           : mbus_write_regs(t, unit, w[i].addr, w[i].n, w[i].regs),
                               w[i].what, w[i].addr);
        return r < 0 ? r : 0;
}

/* Sets the rates of the following moves: the drive's registers when its family has them. */
static int set_rates(struct axis *ax, double speed, double accel)
{
        struct mbax_write w[MBAX_WRITES_MAX];
        struct mbax *m = ax->priv;

        return write_all(ax, w, m->conf->family->rates(m->conf, speed, accel, w));
}

static int mbax_open(struct axis *ax)
{
        const struct mbax_conf *c = ax->conf->backend.conf;
        struct mbax *m;

        if (!c)
                return axis_set_cause(ax, SYNTHETIC_ERRNO(EINVAL),
                                      "no Modbus settings (not loaded from a rig file)");
        if (!ax->priv) {
                m = calloc(1, sizeof(*m));
                if (!m)
                        return -ENOMEM;
                *m = (struct mbax){.conf = c};
                ax->priv = m;
        }
        return set_rates(ax, ax->speed, ax->accel);
}

static int mbax_set_rates(struct axis *ax, double deg_s, double accel)
{
        if (!ax->priv)
                return -ENOTCONN;
        return set_rates(ax, deg_s, accel);
}

static void mbax_close(struct axis *ax)
{
        free(ax->priv);
        ax->priv = NULL;
}

static int command(struct axis *ax, enum mbax_cmd cmd)
{
        struct mbax_write w[MBAX_WRITES_MAX];
        const struct mbax_conf *c = conf(ax);

        if (!c)
                return -ENOTCONN;
        return write_all(ax, w, c->family->command(c, cmd, w));
}

static int mbax_home(struct axis *ax)
{
        return command(ax, MBAX_CMD_HOME);
}

static int mbax_stop(struct axis *ax)
{
        return command(ax, MBAX_CMD_STOP);
}

static int mbax_reset(struct axis *ax)
{
        return command(ax, MBAX_CMD_RESET);
}

/* Reads the spans of a poll into regs (concatenated in span order): in one request when
 * they lie close, else one request each. */
static int read_spans(struct axis *ax, uint16_t regs[MBAX_STATE_REGS])
{
        const struct mbax_conf *c = conf(ax);
        struct mbax_span s[MBAX_SPANS_MAX];
        int n = c->family->spans(c, s), lo = s[0].addr, hi = s[0].addr + s[0].n, at = 0, r;
        uint16_t block[STATE_BLOCK_MAX];

        for (int i = 1; i < n; i++) {
                lo = MIN(lo, s[i].addr);
                hi = MAX(hi, s[i].addr + s[i].n);
        }
        if (n > 1 && hi - lo <= STATE_BLOCK_MAX) {
                r = read_regs(ax, "read status and position", lo, hi - lo, block);
                for (int i = 0; r >= 0 && i < n; at += s[i++].n)
                        memcpy(regs + at, block + (s[i].addr - lo), s[i].n * sizeof(*regs));
                return r < 0 ? r : 0;
        }
        for (int i = 0; i < n; at += s[i++].n)
                if ((r = read_regs(ax, s[i].what, s[i].addr, s[i].n, regs + at)) < 0)
                        return r;
        return 0;
}

/* Reads and decodes the drive's state and raw position count. */
static int read_state(struct axis *ax, struct axis_state *st, int32_t *counts)
{
        uint16_t regs[MBAX_STATE_REGS];
        int r = read_spans(ax, regs);

        if (r < 0)
                return r;
        conf(ax)->family->decode(conf(ax), regs, st, counts);
        return 0;
}

static int mbax_move_abs(struct axis *ax, double deg)
{
        struct mbax_write w[MBAX_WRITES_MAX];
        const struct mbax_conf *c = conf(ax);
        struct axis_state st;
        int32_t cur, target;
        int r;

        if (!c)
                return -ENOTCONN;
        if (ax->conf->continuous) {
                r = read_state(ax, &st, &cur);
                if (r < 0)
                        return r;
                r = mbax_count_target(c->scale, cur, axis_travel(ax->conf, cur / c->scale, deg),
                                      &target);
        } else
                r = mbax_deg_to_counts(c->scale, deg, &target);
        if (r >= 0)
                r = c->family->move(c, target, ax->speed, ax->accel, w);
        return r < 0 ? r : write_all(ax, w, r);
}

static int mbax_poll(struct axis *ax, struct axis_state *st)
{
        int32_t counts;
        int r;

        if (!ax->priv)
                return -ENOTCONN;
        r = read_state(ax, st, &counts);
        if (r < 0)
                return r;
        st->position_deg = mbax_counts_to_deg(conf(ax)->scale, counts, ax->conf->continuous);
        return 0;
}

const struct rig_backend mbax_backend = {
        .name = "modbus",
        .cls = RIG_CLASS_AXIS,
        .bus_types = 1u << RIG_BUS_MODBUS_RTU | 1u << RIG_BUS_MODBUS_TCP,
        .conf_size = sizeof(struct mbax_conf),
        .parse_conf = mbax_parse_conf,
        .ops = &mbax_ops,
};

const struct axis_ops mbax_ops = {
        .name = "modbus",
        .opts = mbax_opts,
        .n_opts = ELEMENTSOF(mbax_opts),
        .open = mbax_open,
        .close = mbax_close,
        .home = mbax_home,
        .move_abs = mbax_move_abs,
        .stop = mbax_stop,
        .reset = mbax_reset,
        .poll = mbax_poll,
        .set_rates = mbax_set_rates,
};
