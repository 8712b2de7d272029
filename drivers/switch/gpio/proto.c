/* proto.c - the rig-file map of the "gpio" switch backend. */
#include <errno.h>

#include "drivers/switch/gpio/proto.h"

int gpsw_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "chip", "line", "active_low", NULL};
        struct gpsw_conf *c = conf;
        int r;

        *c = (struct gpsw_conf){};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_str_req(yc, m, "chip", c->chip, sizeof(c->chip))) < 0 ||
            (r = yconf_str_req(yc, m, "line", c->line, sizeof(c->line))) < 0 ||
            (r = yconf_bool(yc, m, "active_low", &c->active_low)) < 0)
                return r;
        *addr = (struct rig_addr){};
        return 0;
}
