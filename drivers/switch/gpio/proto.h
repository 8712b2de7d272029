/* proto.h - the "gpio" switch backend: a lamp or laser on one GPIO output line. Its rig-file
 * map, no I/O. */
#pragma once

#include <stdbool.h>

#include "common/rigconf.h"
#include "drivers/switch/switch.h"

/* What the backend reads from a switch's map "gpio: { bus: io, chip: gonio-gpio, line: lamp,
 * active_low: false }". */
struct gpsw_conf {
        char chip[RIG_PATH_MAX]; /* name, path, number or label */
        char line[RIG_NAME_MAX]; /* offset or line name */
        bool active_low;         /* on drives the pin low */
};

/* The backend (api.c), registered in drivers/registry.c as "gpio" when built with libgpiod. */
extern const struct sw_ops gpsw_ops;
extern const struct rig_backend gpsw_backend;

/* Parses the backend map m into conf (a struct gpsw_conf): chip and line are required, unknown
 * keys are errors at their line. addr gets no address (the kernel refuses a line held twice).
 * Returns 0 or -EINVAL (message in yc). Pure. */
int gpsw_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);
