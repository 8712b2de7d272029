/* proto.h - the "modbus-coil" switch backend: one coil of a Modbus relay module.
 * Pure checks and decoding, no I/O. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/switch/switch.h"
#include "drivers/transport/modbus.h"

#define MBSW_COIL_MAX 0xffff

/* What the backend reads from a switch's map "modbus-coil: { bus: relays, unit: 10, coil: 0 }". */
struct mbsw_conf {
        int unit; /* 1 when not given */
        int coil; /* 0 when not given */
};

/* The backend (api.c), registered in drivers/registry.c as "modbus-coil". */
extern const struct sw_ops mbsw_ops;
extern const struct rig_backend mbsw_backend;

/* Parses the backend map m into conf (a struct mbsw_conf) and addr (unit and coil): unknown
 * keys and addresses out of range are errors at their key's line. Returns 0 or -EINVAL
 * (message in yc). Pure. */
int mbsw_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);

/* Checks the unit and coil address of c; NULL (a conf built without the rig file) is
 * invalid. Returns 0 or -EINVAL. */
int mbsw_check_conf(const struct mbsw_conf *c);

/* Decodes one coil as returned by FC01 (one byte per coil). Returns 0, or -EPROTO
 * when the byte is neither 0 nor 1. */
int mbsw_decode_coil(uint8_t v, bool *on);
