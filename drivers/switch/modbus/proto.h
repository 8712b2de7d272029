/* proto.h - the "modbus-coil" switch backend: one coil of a Modbus relay module.
 * Pure checks and decoding, no I/O. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/switch/switch.h"

/* Highest unit address of a Modbus serial line (Modbus over serial line spec, 2.2). */
#define MBSW_UNIT_MAX 247
#define MBSW_COIL_MAX 0xffff

/* The backend's ops (api.c), registered in drivers/registry.c as "modbus-coil". */
extern const struct sw_ops mbsw_ops;

/* Checks the unit and coil address of c. Returns 0 or -EINVAL. */
int mbsw_check_conf(const struct rig_switch_conf *c);

/* Decodes one coil as returned by FC01 (one byte per coil). Returns 0, or -EPROTO
 * when the byte is neither 0 nor 1. */
int mbsw_decode_coil(uint8_t v, bool *on);
