/* api.c - the "modbus" axis backend: a servo/stepper drive behind a register profile
 * (docs/modbus-profile.md), through the Modbus transport's retrying transactions.
 * Runs on the bus worker; caches nothing: every state comes from the drive, the unit and
 * the register profile from the backend map, parsed and resolved when the rig file loads. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/bus/bus.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"

/* Registers read in one request when status, fault and position lie this close. */
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

/* The profile of an open axis, or NULL before open. */
static const struct rig_modbus_profile *prof(const struct axis *ax)
{
        const struct mbax *m = ax->priv;

        return m ? m->conf->profile : NULL;
}

/* The unit of an open axis. */
static int unit(const struct axis *ax)
{
        const struct mbax *m = ax->priv;

        return m->conf->unit;
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
        return reg_result(ax, mbus_read_regs(bus_transport(ax->bus), unit(ax), reg, n, dest), what,
                          reg);
}

static int write_reg(struct axis *ax, const char *what, int reg, uint16_t v)
{
        return reg_result(ax, mbus_write_reg(bus_transport(ax->bus), unit(ax), reg, v), what, reg);
}

static int write_regs(struct axis *ax, const char *what, int reg, int n, const uint16_t *src)
{
        return reg_result(ax, mbus_write_regs(bus_transport(ax->bus), unit(ax), reg, n, src), what,
                          reg);
}

static int command(struct axis *ax, uint16_t cmd)
{
        if (!ax->priv)
                return -ENOTCONN;
        return write_reg(ax, "write command", prof(ax)->reg_command, cmd);
}

/* Writes a rate register unless the rig file leaves it to the drive (value 0). */
static int write_rate(struct axis *ax, const char *what, uint16_t reg, double value)
{
        if (!(value > 0))
                return 0;
        return write_reg(ax, what, reg, mbax_rate_reg(value));
}

static int mbax_open(struct axis *ax)
{
        const struct mbax_conf *c = ax->conf->backend.conf;
        struct mbax *m;
        int r;

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
        r = write_rate(ax, "write max speed", c->profile->reg_speed, ax->conf->max_speed);
        if (r < 0)
                return r;
        return write_rate(ax, "write acceleration", c->profile->reg_accel, ax->conf->accel);
}

static int mbax_set_speed(struct axis *ax, double deg_s)
{
        if (!ax->priv)
                return -ENOTCONN;
        return write_rate(ax, "write max speed", prof(ax)->reg_speed, deg_s);
}

static void mbax_close(struct axis *ax)
{
        free(ax->priv);
        ax->priv = NULL;
}

static int mbax_home(struct axis *ax)
{
        return command(ax, prof(ax)->cmd_home);
}

static int mbax_stop(struct axis *ax)
{
        return command(ax, prof(ax)->cmd_stop);
}

static int mbax_reset(struct axis *ax)
{
        return command(ax, prof(ax)->cmd_reset);
}

static int read_position(struct axis *ax, int32_t *ret)
{
        uint16_t regs[2];
        int r;

        r = read_regs(ax, "read position", prof(ax)->reg_position, 2, regs);
        if (r < 0)
                return r;
        *ret = mbax_get_i32(prof(ax), regs);
        return 0;
}

static int mbax_move_abs(struct axis *ax, double deg)
{
        const struct rig_modbus_profile *p = prof(ax);
        uint16_t regs[2];
        int32_t cur, target;
        int r;

        if (!p)
                return -ENOTCONN;
        if (ax->conf->continuous) {
                r = read_position(ax, &cur);
                if (r < 0)
                        return r;
                r = mbax_count_target(p, cur, axis_travel(ax->conf, cur / p->scale, deg), &target);
        } else
                r = mbax_deg_to_counts(p, deg, &target);
        if (r < 0)
                return r;
        mbax_put_i32(p, target, regs);
        r = write_regs(ax, "write target", p->reg_target, 2, regs);
        if (r < 0)
                return r;
        return command(ax, p->cmd_move);
}

/* Reads status, fault and both position registers, in one request when they are close. */
static int read_state_regs(struct axis *ax, uint16_t *status, uint16_t *fault, uint16_t pos[2])
{
        const struct rig_modbus_profile *p = prof(ax);
        int lo = MIN(MIN(p->reg_status, p->reg_fault), p->reg_position);
        int hi = MAX(MAX(p->reg_status, p->reg_fault), p->reg_position + 1);
        uint16_t block[STATE_BLOCK_MAX];
        int r;

        if (hi - lo >= STATE_BLOCK_MAX) {
                r = read_regs(ax, "read status", p->reg_status, 1, status);
                if (r >= 0)
                        r = read_regs(ax, "read fault code", p->reg_fault, 1, fault);
                return r < 0 ? r : read_regs(ax, "read position", p->reg_position, 2, pos);
        }
        r = read_regs(ax, "read status and position", lo, hi - lo + 1, block);
        if (r < 0)
                return r;
        *status = block[p->reg_status - lo];
        *fault = block[p->reg_fault - lo];
        pos[0] = block[p->reg_position - lo];
        pos[1] = block[p->reg_position + 1 - lo];
        return 0;
}

static int mbax_poll(struct axis *ax, struct axis_state *st)
{
        uint16_t status, fault, pos[2];
        int r;

        if (!ax->priv)
                return -ENOTCONN;
        r = read_state_regs(ax, &status, &fault, pos);
        if (r < 0)
                return r;
        mbax_decode_status(status, fault, st);
        st->position_deg =
                mbax_counts_to_deg(prof(ax), mbax_get_i32(prof(ax), pos), ax->conf->continuous);
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
        .set_speed = mbax_set_speed,
};
