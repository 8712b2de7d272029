/* proto.c - pure checks and decoding for the "modbus-coil" switch backend. */
#include <errno.h>

#include "drivers/switch/modbus/proto.h"

int mbsw_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "unit", "coil", NULL};
        struct mbsw_conf *c = conf;
        long unit = 1, coil = 0;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_int(yc, m, "unit", 1, MBUS_UNIT_MAX, &unit)) < 0 ||
            (r = yconf_int(yc, m, "coil", 0, MBSW_COIL_MAX, &coil)) < 0)
                return r;
        *c = (struct mbsw_conf){.unit = (int)unit, .coil = (int)coil};
        *addr = (struct rig_addr){
                .key = "unit", .value = c->unit, .sub_key = "coil", .sub = c->coil};
        return 0;
}

int mbsw_check_conf(const struct mbsw_conf *c)
{
        if (!c || c->unit < 0 || c->unit > MBUS_UNIT_MAX || c->coil < 0 || c->coil > MBSW_COIL_MAX)
                return -EINVAL;
        return 0;
}

int mbsw_decode_coil(uint8_t v, bool *on)
{
        if (v > 1)
                return -EPROTO;
        *on = v == 1;
        return 0;
}
