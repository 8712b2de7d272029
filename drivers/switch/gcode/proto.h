/* proto.h - the "gcode-laser" switch backend: a line laser of the Horus/Ciclop board,
 * switched with M71 T<n> (on) and M70 T<n> (off) on the board's G-code line (docs/gcode.md).
 * Pure parsing and encoding, no I/O. */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#include "common/rigconf.h"
#include "drivers/switch/switch.h"

/* Laser outputs of the board: T1..T4. */
#define GCSW_TOOL_MAX 4
/* BEWARE: the Horus firmware switches a laser off by itself after it has been on for 255 s
 * (a timer in its laser control), without a word on the line. */
#define GCSW_AUTO_OFF_S 255

/* What the backend reads from "gcode-laser: { bus: ciclop, tool: 1 }". */
struct gcsw_conf {
        int tool; /* 1 when not given */
};

/* The backend (api.c), registered in drivers/registry.c as "gcode-laser". */
extern const struct sw_ops gcsw_ops;
extern const struct rig_backend gcsw_backend;

/* Parses the backend map m into conf (a struct gcsw_conf) and addr (the tool): unknown keys
 * and a tool outside 1..4 are errors at their key's line. Returns 0 or -EINVAL. Pure. */
int gcsw_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);

/* Writes "M71 T1" (on) or "M70 T1" (off) into buf. Returns the length or -ENOBUFS. */
int gcsw_format(char *buf, size_t len, int tool, bool on);
