/* proto.h - the register profile of Modbus axis drives (docs/modbus-profile.md):
 * pure encoding and decoding, no I/O. Shared with gonio-sim's emulated drives. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/axis/axis.h"
#include "drivers/transport/modbus.h"

/* Bits of the status register. */
#define AXIS_ST_ENABLED     (1u << 0)
#define AXIS_ST_HOMED       (1u << 1)
#define AXIS_ST_MOVING      (1u << 2)
#define AXIS_ST_IN_POSITION (1u << 3)
#define AXIS_ST_FAULT       (1u << 4)
#define AXIS_ST_HOME_SWITCH (1u << 5)

/* Codes of the fault register. */
enum mbax_fault {
        MBAX_FAULT_NONE,
        MBAX_FAULT_STALL,
        MBAX_FAULT_FOLLOWING,
        MBAX_FAULT_LIMIT,
        MBAX_FAULT_OVERTEMP,
};

/* What the backend reads from an axis's map "modbus: { bus: drives, unit: 1, profile: p }". */
struct mbax_conf {
        int unit; /* Modbus unit id, 1 when not given */
        /* the register profile ("gonio-default" when not given), resolved at load: borrowed
         * from the rig config */
        const struct rig_modbus_profile *profile;
};

/* The backend (api.c), registered in drivers/registry.c as "modbus". */
extern const struct axis_ops mbax_ops;
extern const struct rig_backend mbax_backend;

/* Parses the backend map m into conf (a struct mbax_conf) and addr (the unit), resolving the
 * profile in rc: unknown keys, a unit outside 1..247 and an unknown profile are errors at
 * their key's line. Returns 0 or -EINVAL (message in yc). Pure. */
int mbax_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);

/* Splits v into two registers in the profile's word order (high word first unless
 * word_swap). Never fails. */
void mbax_put_i32(const struct rig_modbus_profile *p, int32_t v, uint16_t regs[2]);

/* Joins two registers in the profile's word order. Never fails. */
int32_t mbax_get_i32(const struct rig_modbus_profile *p, const uint16_t regs[2]);

/* Degrees to position counts (rounded). Returns 0, or -ERANGE beyond int32 or for a
 * non-finite value or a scale <= 0. */
int mbax_deg_to_counts(const struct rig_modbus_profile *p, double deg, int32_t *ret);

/* Position counts to degrees; modulo 360 into [0, 360) when continuous. */
double mbax_counts_to_deg(const struct rig_modbus_profile *p, int32_t counts, bool continuous);

/* The count target delta_deg away from the raw count cur (continuous axes: the travel the
 * axis class chose). Returns 0 or -ERANGE beyond the int32 counter. */
int mbax_count_target(const struct rig_modbus_profile *p, int32_t cur, double delta_deg,
                      int32_t *ret);

/* Encodes a speed or acceleration (deg/s, deg/s^2) as the uint16 register in units of
 * 0.1, clamped to 1..65535. */
uint16_t mbax_rate_reg(double value);

/* Fills the flags and fault code of st (not the position) from the two registers. */
void mbax_decode_status(uint16_t status, uint16_t fault, struct axis_state *st);
