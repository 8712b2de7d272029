/* proto.c - pure checks and decoding for the "modbus-coil" switch backend. */
#include <errno.h>

#include "drivers/switch/modbus/proto.h"

int mbsw_check_conf(const struct rig_switch_conf *c)
{
        if (c->unit < 0 || c->unit > MBSW_UNIT_MAX || c->coil < 0 || c->coil > MBSW_COIL_MAX)
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
