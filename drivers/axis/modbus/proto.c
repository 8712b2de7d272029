/* proto.c - pure encoding and decoding of the Modbus axis register profile. */
#include <errno.h>
#include <math.h>

#include "drivers/axis/modbus/proto.h"

void mbax_put_i32(const struct rig_modbus_profile *p, int32_t v, uint16_t regs[2])
{
        uint32_t u = (uint32_t)v;
        uint16_t hi = (uint16_t)(u >> 16), lo = (uint16_t)(u & 0xffffu);

        regs[0] = p->word_swap ? lo : hi;
        regs[1] = p->word_swap ? hi : lo;
}

int32_t mbax_get_i32(const struct rig_modbus_profile *p, const uint16_t regs[2])
{
        uint32_t hi = p->word_swap ? regs[1] : regs[0];
        uint32_t lo = p->word_swap ? regs[0] : regs[1];

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

int mbax_deg_to_counts(const struct rig_modbus_profile *p, double deg, int32_t *ret)
{
        if (!(p->scale > 0))
                return -ERANGE;
        return to_i32(deg * p->scale, ret);
}

double mbax_counts_to_deg(const struct rig_modbus_profile *p, int32_t counts, bool continuous)
{
        double deg = (double)counts / p->scale;

        if (!continuous)
                return deg;
        deg = fmod(deg, 360.0);
        if (deg < 0)
                deg += 360.0;
        return deg >= 360.0 ? 0.0 : deg; /* -tiny + 360 rounds to 360 */
}

int mbax_count_target(const struct rig_modbus_profile *p, int32_t cur, double delta_deg,
                      int32_t *ret)
{
        if (!(p->scale > 0) || !isfinite(delta_deg))
                return -ERANGE;
        return to_i32((double)cur + delta_deg * p->scale, ret);
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

int mbax_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "unit", "profile", NULL};
        char profile[RIG_NAME_MAX] = "gonio-default";
        struct mbax_conf *c = conf;
        long unit = 1;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_int(yc, m, "unit", 1, MBUS_UNIT_MAX, &unit)) < 0 ||
            (r = yconf_str(yc, m, "profile", profile, sizeof(profile))) < 0)
                return r;
        c->unit = (int)unit;
        c->profile = rigconf_profile(rc, profile);
        if (!c->profile)
                return yconf_error(yc, yconf_get(m, "profile"), "profile",
                                   "no register profile named '%s'", profile);
        *addr = (struct rig_addr){.key = "unit", .value = c->unit};
        return 0;
}
