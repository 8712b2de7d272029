/* proto.h - the register profiles of Modbus axis drives (docs/modbus-profile.md): pure
 * encoding and decoding, no I/O. Shared with gonio-sim's emulated drives.
 *
 * A profile is data plus a few small functions, as libsigrok's model tables: a family
 * (struct mbax_family) says which registers a poll reads and how they decode, and which
 * register writes start a move, home, stop or reset. The generic family takes its
 * addresses from a rig-file profile (struct rig_modbus_profile, "gonio-default" built in);
 * the other families are built in with a fixed map ("azd": Oriental Motor AZ series). The
 * axis backend (api.c) only does the I/O these describe. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/axis/axis.h"
#include "drivers/transport/modbus.h"

/* Bits of the generic status register. */
#define AXIS_ST_ENABLED     (1u << 0)
#define AXIS_ST_HOMED       (1u << 1)
#define AXIS_ST_MOVING      (1u << 2)
#define AXIS_ST_IN_POSITION (1u << 3)
#define AXIS_ST_FAULT       (1u << 4)
#define AXIS_ST_HOME_SWITCH (1u << 5)

/* Codes of the generic fault register. */
enum mbax_fault {
        MBAX_FAULT_NONE,
        MBAX_FAULT_STALL,
        MBAX_FAULT_FOLLOWING,
        MBAX_FAULT_LIMIT,
        MBAX_FAULT_OVERTEMP,
};

/* Oriental Motor AZ series (profile "azd"): holding registers of its Modbus RTU map, 32-bit
 * values upper word first (docs/modbus-profile.md has the sources). */
#define AZD_REG_DIRECT       0x0058 /* direct data operation block: 8 int32, 16 registers */
#define AZD_DIRECT_REGS      16
#define AZD_REG_DIRECT_TRIG  0x0066 /* its trigger (int32): 1 reflects all data and starts */
#define AZD_REG_INPUT        0x007C /* driver input command (int32; bits in the lower word) */
#define AZD_REG_OUTPUT       0x007E /* driver output status (int32; bits in the lower word) */
#define AZD_REG_ALARM        0x0080 /* present alarm (int32), 0 when none */
#define AZD_REG_FEEDBACK_POS 0x00CC /* feedback position (int32), steps */
#define AZD_OP_ABSOLUTE      1      /* direct data operation type: absolute positioning */
#define AZD_CURRENT_FULL     1000   /* operating current, 0.1 % units */
/* Driver input command bits (R-IN, default assignment). */
#define AZD_IN_ZHOME   (1u << 4)
#define AZD_IN_STOP    (1u << 5)
#define AZD_IN_ALM_RST (1u << 7)
/* Driver output status bits (R-OUT, default assignment). */
#define AZD_OUT_HOME_END (1u << 4)
#define AZD_OUT_READY    (1u << 5)
#define AZD_OUT_ALM_A    (1u << 7)
#define AZD_OUT_MOVE     (1u << 13)
#define AZD_OUT_IN_POS   (1u << 14)
/* The AZ's alarm code for a stall: excessive position deviation. */
#define AZD_ALARM_DEVIATION 0x10
/* Counts per degree of an "azd" axis without a `scale`: an AZ at its 1000 steps/rev behind
 * a 36:1 gear. */
#define AZD_DEFAULT_SCALE 100.0

struct mbax_family;

/* What the backend reads from an axis's map "modbus: { bus: drives, unit: 1, profile: p }". */
struct mbax_conf {
        int unit; /* Modbus unit id, 1 when not given */
        /* the family of the profile (generic for the rig file's own and "gonio-default") */
        const struct mbax_family *family;
        /* generic family: the register profile, resolved at load, borrowed from the rig config;
         * NULL for a built-in family */
        const struct rig_modbus_profile *profile;
        double scale;   /* position counts per degree (key `scale`, else the profile's) */
        bool word_swap; /* 32-bit values low word first */
};

/* Most registers one family write puts in one request. */
#define MBAX_WRITE_MAX AZD_DIRECT_REGS
/* Most register writes one operation takes. */
#define MBAX_WRITES_MAX 2
/* Most separate register spans a poll reads. */
#define MBAX_SPANS_MAX 3
/* Most registers a poll reads, all spans together. */
#define MBAX_STATE_REGS 8

/* One register write (function 0x06 for one register, 0x10 for more). */
struct mbax_write {
        const char *what; /* for messages: "write target" */
        uint16_t addr;
        int n;
        uint16_t regs[MBAX_WRITE_MAX];
};

/* Registers a poll reads: a span of n from addr. */
struct mbax_span {
        const char *what; /* for messages: "read status" */
        uint16_t addr;
        int n;
};

enum mbax_cmd { MBAX_CMD_HOME, MBAX_CMD_STOP, MBAX_CMD_RESET };

/* A register-map family. Every function is pure and fills at most the *_MAX entries. */
struct mbax_family {
        const char *name; /* the built-in profile name ("azd"); the generic family's is unused */
        /* The spans a poll reads, in order; returns their count. */
        int (*spans)(const struct mbax_conf *c, struct mbax_span s[MBAX_SPANS_MAX]);
        /* Decodes the spans' registers, concatenated in span order, into the flags and fault
         * code of st and the raw position count. */
        void (*decode)(const struct mbax_conf *c, const uint16_t *regs, struct axis_state *st,
                       int32_t *counts);
        /* The writes that set the speed and acceleration of the following moves (deg/s,
         * deg/s^2; 0 leaves it to the drive); returns their count (0: moves carry them). */
        int (*rates)(const struct mbax_conf *c, double speed, double accel,
                     struct mbax_write w[MBAX_WRITES_MAX]);
        /* The writes that start a move to target counts at speed and accel; returns their
         * count, or -ERANGE for a speed the drive cannot take. */
        int (*move)(const struct mbax_conf *c, int32_t target, double speed, double accel,
                    struct mbax_write w[MBAX_WRITES_MAX]);
        /* The writes of a command; returns their count. */
        int (*command)(const struct mbax_conf *c, enum mbax_cmd cmd,
                       struct mbax_write w[MBAX_WRITES_MAX]);
};

/* The families: generic (a rig_modbus_profile's registers) and the built-in ones. */
extern const struct mbax_family mbax_generic;
extern const struct mbax_family mbax_azd;

/* The backend (api.c), registered in drivers/registry.c as "modbus". */
extern const struct axis_ops mbax_ops;
extern const struct rig_backend mbax_backend;

/* Parses the backend map m into conf (a struct mbax_conf) and addr (the unit), resolving the
 * profile: one of rc's (the rig file's own and "gonio-default"), else a built-in family.
 * Unknown keys, a unit outside 1..247, a bad scale, an unknown profile and a rig-file
 * profile named as a built-in one are errors at their key's line. Returns 0 or -EINVAL
 * (message in yc). Pure. */
int mbax_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);

/* The built-in family named name, or NULL. */
const struct mbax_family *mbax_family_find(const char *name);

/* Splits v into two registers, high word first unless word_swap. Never fails. */
void mbax_put_i32(bool word_swap, int32_t v, uint16_t regs[2]);

/* Joins two registers in that word order. Never fails. */
int32_t mbax_get_i32(bool word_swap, const uint16_t regs[2]);

/* Degrees to position counts at scale counts/degree (rounded). Returns 0, or -ERANGE
 * beyond int32 or for a non-finite value or a scale <= 0. */
int mbax_deg_to_counts(double scale, double deg, int32_t *ret);

/* Position counts to degrees; modulo 360 into [0, 360) when continuous. */
double mbax_counts_to_deg(double scale, int32_t counts, bool continuous);

/* The count target delta_deg away from the raw count cur (continuous axes: the travel the
 * axis class chose). Returns 0 or -ERANGE beyond the int32 counter. */
int mbax_count_target(double scale, int32_t cur, double delta_deg, int32_t *ret);

/* Encodes a speed or acceleration (deg/s, deg/s^2) as the uint16 register in units of
 * 0.1, clamped to 1..65535. */
uint16_t mbax_rate_reg(double value);

/* Fills the flags and fault code of st (not the position) from the generic status and
 * fault registers. */
void mbax_decode_status(uint16_t status, uint16_t fault, struct axis_state *st);

/* Fills the flags and fault code of st from the AZ's driver output status (lower word) and
 * present alarm code. */
void mbax_azd_decode_status(uint16_t output, int32_t alarm, struct axis_state *st);
