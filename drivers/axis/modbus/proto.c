/* proto.c - pure encoding and decoding of the Modbus axis register profiles: the shared
 * helpers, the generic family (a rig-file register profile) and the parsing of the
 * backend map. The built-in "azd" family is in azd.c. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "common/cleanup.h"
#include "drivers/axis/modbus/proto.h"

void mbax_put_i32(bool word_swap, int32_t v, uint16_t regs[2])
{
        uint32_t u = (uint32_t)v;
        uint16_t hi = (uint16_t)(u >> 16), lo = (uint16_t)(u & 0xffffu);

        regs[0] = word_swap ? lo : hi;
        regs[1] = word_swap ? hi : lo;
}

int32_t mbax_get_i32(bool word_swap, const uint16_t regs[2])
{
        uint32_t hi = word_swap ? regs[1] : regs[0];
        uint32_t lo = word_swap ? regs[0] : regs[1];

        return (int32_t)((hi << 16) | lo);
}

static int to_i32(double v, int32_t *ret)
{
        double r = round(v);

        if (!isfinite(r) || r < (double)INT32_MIN || r > (double)INT32_MAX)
                return -ERANGE;
        *ret = (int32_t)r;
        return 0;
}

int mbax_deg_to_counts(double scale, double deg, int32_t *ret)
{
        if (!(scale > 0))
                return -ERANGE;
        return to_i32(deg * scale, ret);
}

double mbax_counts_to_deg(double scale, int32_t counts, bool continuous)
{
        double deg = (double)counts / scale;

        if (!continuous)
                return deg;
        deg = fmod(deg, 360.0);
        if (deg < 0)
                deg += 360.0;
        return deg >= 360.0 ? 0.0 : deg; /* -tiny + 360 rounds to 360 */
}

int mbax_count_target(double scale, int32_t cur, double delta_deg, int32_t *ret)
{
        if (!(scale > 0) || !isfinite(delta_deg))
                return -ERANGE;
        return to_i32((double)cur + delta_deg * scale, ret);
}

uint16_t mbax_rate_reg(double value)
{
        double r = round(value * 10.0);

        if (!(r >= 1.0)) /* also NaN */
                return 1;
        return r > 65535.0 ? 65535 : (uint16_t)r;
}

void mbax_decode_status(uint16_t status, uint16_t fault, struct axis_state *st)
{
        st->enabled = status & AXIS_ST_ENABLED;
        st->homed = status & AXIS_ST_HOMED;
        st->moving = status & AXIS_ST_MOVING;
        st->in_position = status & AXIS_ST_IN_POSITION;
        st->fault = status & AXIS_ST_FAULT;
        st->fault_code = st->fault ? fault : 0;
}

/* ---- the generic family: the registers of a rig_modbus_profile ---- */

static int generic_spans(const struct mbax_conf *c, struct mbax_span s[MBAX_SPANS_MAX])
{
        const struct rig_modbus_profile *p = c->profile;

        s[0] = (struct mbax_span){"read status", p->reg_status, 1};
        s[1] = (struct mbax_span){"read fault code", p->reg_fault, 1};
        s[2] = (struct mbax_span){"read position", p->reg_position, 2};
        return 3;
}

static void generic_decode(const struct mbax_conf *c, const uint16_t *regs, struct axis_state *st,
                           int32_t *counts)
{
        mbax_decode_status(regs[0], regs[1], st);
        *counts = mbax_get_i32(c->word_swap, regs + 2);
}

/* A one-register write of v at reg, or none when the rig file leaves a rate to the drive. */
static int rate_write(const char *what, uint16_t reg, double v, struct mbax_write *w)
{
        if (!(v > 0))
                return 0;
        *w = (struct mbax_write){.what = what, .addr = reg, .n = 1, .regs = {mbax_rate_reg(v)}};
        return 1;
}

static int generic_rates(const struct mbax_conf *c, double speed, double accel,
                         struct mbax_write w[MBAX_WRITES_MAX])
{
        int n = rate_write("write max speed", c->profile->reg_speed, speed, &w[0]);

        return n + rate_write("write acceleration", c->profile->reg_accel, accel, &w[n]);
}

static void command_write(const struct rig_modbus_profile *p, uint16_t cmd, struct mbax_write *w)
{
        *w = (struct mbax_write){
                .what = "write command", .addr = p->reg_command, .n = 1, .regs = {cmd}};
}

static int generic_move(const struct mbax_conf *c, int32_t target, double speed, double accel,
                        struct mbax_write w[MBAX_WRITES_MAX])
{
        (void)speed, (void)accel; /* written by generic_rates */
        w[0] = (struct mbax_write){.what = "write target", .addr = c->profile->reg_target, .n = 2};
        mbax_put_i32(c->word_swap, target, w[0].regs);
        command_write(c->profile, c->profile->cmd_move, &w[1]);
        return 2;
}

static int generic_command(const struct mbax_conf *c, enum mbax_cmd cmd,
                           struct mbax_write w[MBAX_WRITES_MAX])
{
        const struct rig_modbus_profile *p = c->profile;

        command_write(p,
                      cmd == MBAX_CMD_HOME   ? p->cmd_home
                      : cmd == MBAX_CMD_STOP ? p->cmd_stop
                                             : p->cmd_reset,
                      &w[0]);
        return 1;
}

const struct mbax_family mbax_generic = {
        .name = "generic",
        .spans = generic_spans,
        .decode = generic_decode,
        .rates = generic_rates,
        .move = generic_move,
        .command = generic_command,
};

/* ---- the backend map ---- */

const struct mbax_family *mbax_family_find(const char *name)
{
        static const struct mbax_family *const builtin[] = {&mbax_azd};

        for (size_t i = 0; i < ELEMENTSOF(builtin); i++)
                if (strcmp(builtin[i]->name, name) == 0)
                        return builtin[i];
        return NULL;
}

/* Resolves profile name into c: a rig-file profile (or "gonio-default") or a built-in
 * family, never both. */
static int resolve_profile(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                           const char *name, struct mbax_conf *c)
{
        const struct rig_modbus_profile *p = rigconf_profile(rc, name);
        const struct mbax_family *f = mbax_family_find(name);

        if (p && f)
                return yconf_error(yc, yconf_get(m, "profile"), "profile",
                                   "profile '%s' is built in; give the rig file's another name",
                                   name);
        if (!p && !f)
                return yconf_error(yc, yconf_get(m, "profile"), "profile",
                                   "no register profile named '%s' (built in: gonio-default, "
                                   "azd; or define it under 'profiles')",
                                   name);
        *c = (struct mbax_conf){.unit = c->unit,
                                .family = p ? &mbax_generic : f,
                                .profile = p,
                                .scale = p ? p->scale : AZD_DEFAULT_SCALE,
                                .word_swap = p && p->word_swap};
        return 0;
}

int mbax_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "unit", "profile", "scale", NULL};
        char profile[RIG_NAME_MAX] = "gonio-default";
        struct mbax_conf *c = conf;
        long unit = 1;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_int(yc, m, "unit", 1, MBUS_UNIT_MAX, &unit)) < 0 ||
            (r = yconf_str(yc, m, "profile", profile, sizeof(profile))) < 0)
                return r;
        c->unit = (int)unit;
        if ((r = resolve_profile(yc, m, rc, profile, c)) < 0 ||
            (r = yconf_double(yc, m, "scale", 1e-3, 1e9, &c->scale)) < 0)
                return r;
        *addr = (struct rig_addr){.key = "unit", .value = c->unit};
        return 0;
}
