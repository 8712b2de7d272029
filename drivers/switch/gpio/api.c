/* api.c - the "gpio" switch backend: a lamp or laser on one GPIO output line, requested at open
 * (off) through drivers/gpio/gpiod.h and held until close. A write counts once the line reads
 * back the value written. When the chip vanishes (a USB expander unplugged) get and set fail
 * with -ENODEV saying so, and open (fault.clear) requests the line again once it is back. */
#include <errno.h>
#include <stdlib.h>

#include "common/cleanup.h"
#include "common/log.h"
#include "drivers/gpio/gpiod.h"
#include "drivers/switch/gpio/proto.h"

static const struct opt_desc gpsw_opts[] = {
        {OPT_STATE, OPT_GET | OPT_SET},
};

/* Records the failure r of reading or writing the line: a vanished chip, or the kernel's
 * errno. */
static int line_error(struct sw *s, int r, bool write)
{
        const struct gpsw_conf *c = s->conf->backend.conf;
        char doing[RIG_NAME_MAX + 32], buf[GPIO_ERR_MAX + sizeof(doing)];

        snprintf(doing, sizeof(doing), "%s line %s", write ? "writing" : "reading", c->line);
        if (gpio_request_lost_cause(s->priv, doing, buf, sizeof(buf)))
                return sw_set_cause(s, SYNTHETIC_ERRNO(ENODEV), "%s", buf);
        return sw_set_cause(s, r, "%s line %s of %s: %m", write ? "write" : "read", c->line,
                            gpio_request_chip(s->priv));
}

static int gpsw_get(struct sw *s, bool *on)
{
        int v;

        if (!s->priv)
                return -ENOTCONN;
        v = gpio_request_get_value(s->priv, 0);
        if (v < 0)
                return line_error(s, v, false);
        *on = v;
        return 0;
}

static int gpsw_set(struct sw *s, bool on)
{
        const struct gpsw_conf *c = s->conf->backend.conf;
        bool now = false;
        int r;

        if (!s->priv)
                return -ENOTCONN;
        r = gpio_request_set_value(s->priv, 0, on);
        if (r < 0)
                return line_error(s, r, true);
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

        if (s->priv) { /* open, or lost: fault.clear reopens it */
                req = s->priv;
                r = gpio_request_reopen(&req, err, sizeof(err));
                s->priv = req;
                return r < 0 ? sw_set_cause(s, r, "%s", err) : 0;
        }
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
