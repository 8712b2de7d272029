/* api.c - the "modbus-coil" switch backend: a lamp or laser on one coil of a Modbus
 * relay module. A write (FC05) counts only once a read back (FC01) confirms it. */
#include <errno.h>

#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"
#include "drivers/switch/modbus/proto.h"

static const struct opt_desc mbsw_opts[] = {
        {OPT_STATE, OPT_GET | OPT_SET},
};

/* The unit and coil from the rig file; NULL in a conf built by hand (open refuses it). */
static const struct mbsw_conf *conf(const struct sw *s)
{
        return s->conf->backend.conf;
}

/* A failed coil access: "write coil 3: cause", or the port alone when it could not be
 * opened. Returns r. */
static int coil_error(struct sw *s, int r, const char *what)
{
        const struct transport *t = bus_transport(s->bus);

        if (t->open_failed)
                return sw_set_cause(s, r, "%s", transport_cause(t));
        return sw_set_cause(s, r, "%s coil %d: %s", what, conf(s)->coil, transport_cause(t));
}

static int mbsw_get(struct sw *s, bool *on)
{
        uint8_t v;
        int r;

        r = mbus_read_coils(bus_transport(s->bus), conf(s)->unit, conf(s)->coil, 1, &v);
        if (r < 0)
                return coil_error(s, r, "read");
        r = mbsw_decode_coil(v, on);
        if (r < 0)
                return sw_set_cause(s, r, "coil %d read back as 0x%02x", conf(s)->coil, v);
        return 0;
}

static int mbsw_open(struct sw *s)
{
        bool on;

        if (mbsw_check_conf(conf(s)) < 0)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EINVAL),
                                    "no valid Modbus unit and coil in the rig file");
        return mbsw_get(s, &on);
}

static int mbsw_set(struct sw *s, bool on)
{
        bool now;
        int r;

        r = mbus_write_coil(bus_transport(s->bus), conf(s)->unit, conf(s)->coil, on);
        if (r < 0)
                return coil_error(s, r, "write");
        r = mbsw_get(s, &now);
        if (r < 0)
                return r;
        if (now != on)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EIO), "coil %d reads %s after writing %s",
                                    conf(s)->coil, now ? "on" : "off", on ? "on" : "off");
        return 0;
}

const struct rig_backend mbsw_backend = {
        .name = "modbus-coil",
        .cls = RIG_CLASS_SWITCH,
        .bus_types = 1u << RIG_BUS_MODBUS_RTU | 1u << RIG_BUS_MODBUS_TCP,
        .conf_size = sizeof(struct mbsw_conf),
        .parse_conf = mbsw_parse_conf,
        .ops = &mbsw_ops,
};

const struct sw_ops mbsw_ops = {
        .name = "modbus-coil",
        .opts = mbsw_opts,
        .n_opts = ELEMENTSOF(mbsw_opts),
        .open = mbsw_open,
        .set = mbsw_set,
        .get = mbsw_get,
};
