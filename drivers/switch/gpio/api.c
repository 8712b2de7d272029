/* api.c - the "gpio" switch backend: a lamp or laser on one GPIO output line, requested at open
 * (off) through drivers/gpio/gpiod.h and held until close. A write counts once the line reads
 * back the value written. */
#include <errno.h>
#include <stdlib.h>

#include "common/cleanup.h"
#include "common/log.h"
#include "drivers/gpio/gpiod.h"
#include "drivers/switch/gpio/proto.h"

static const struct opt_desc gpsw_opts[] = {
        {OPT_STATE, OPT_GET | OPT_SET},
};

static int gpsw_get(struct sw *s, bool *on)
{
        const struct gpsw_conf *c = s->conf->backend.conf;
        int v;

        if (!s->priv)
                return -ENOTCONN;
        v = gpio_request_get_value(s->priv, 0);
        if (v < 0)
                return sw_set_cause(s, v, "read line %s of %s: %m", c->line,
                                    gpio_request_chip(s->priv));
        *on = v;
        return 0;
}

static int gpsw_set(struct sw *s, bool on)
{
        const struct gpsw_conf *c = s->conf->backend.conf;
        bool now;
        int r;

        if (!s->priv)
                return -ENOTCONN;
        r = gpio_request_set_value(s->priv, 0, on);
        if (r < 0)
                return sw_set_cause(s, r, "write line %s of %s: %m", c->line,
                                    gpio_request_chip(s->priv));
        r = gpsw_get(s, &now);
        if (r < 0)
                return r;
        if (now != on)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EIO), "line %s reads %s after writing %s",
                                    c->line, now ? "on" : "off", on ? "on" : "off");
        return 0;
}

static void gpsw_close(struct sw *s)
{
        s->priv = gpio_request_release(s->priv);
}

static int gpsw_open(struct sw *s)
{
        const struct gpsw_conf *c = s->conf->backend.conf;
        char err[GPIO_ERR_MAX] = "";
        struct gpio_line_settings ls;
        struct gpio_request *req;
        int r;

        if (s->priv)
                return 0;
        if (!c)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EINVAL),
                                    "no GPIO settings (not loaded from a rig file)");
        ls = (struct gpio_line_settings){
                .line = c->line, .direction = GPIO_OUTPUT, .active_low = c->active_low};
        r = gpio_request_lines(c->chip, s->conf->name, &ls, 1, &req, err, sizeof(err));
        if (r < 0)
                return sw_set_cause(s, r, "%s", err);
        s->priv = req;
        return 0;
}

const struct rig_backend gpsw_backend = {
        .name = "gpio",
        .cls = RIG_CLASS_SWITCH,
        .bus_types = 1u << RIG_BUS_LOCAL,
        .conf_size = sizeof(struct gpsw_conf),
        .parse_conf = gpsw_parse_conf,
        .ops = &gpsw_ops,
};

const struct sw_ops gpsw_ops = {
        .name = "gpio",
        .opts = gpsw_opts,
        .n_opts = ELEMENTSOF(gpsw_opts),
        .open = gpsw_open,
        .close = gpsw_close,
        .set = gpsw_set,
        .get = gpsw_get,
};
