/* proto.c - the "gcode-laser" backend map and its command lines. */
#include <errno.h>
#include <stdio.h>

#include "drivers/switch/gcode/proto.h"

int gcsw_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "tool", NULL};
        struct gcsw_conf *c = conf;
        long tool = 1;
        int r;

        (void)rc;
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_int(yc, m, "tool", 1, GCSW_TOOL_MAX, &tool)) < 0)
                return r;
        *c = (struct gcsw_conf){.tool = (int)tool};
        *addr = (struct rig_addr){.key = "tool", .value = c->tool};
        return 0;
}

int gcsw_format(char *buf, size_t len, int tool, bool on)
{
        int n = snprintf(buf, len, "M%d T%d", on ? 71 : 70, tool);

        return n < 0 || (size_t)n >= len ? -ENOBUFS : n;
}
