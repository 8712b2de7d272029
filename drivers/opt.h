/* opt.h - what a driver supports, described as data (after libsigrok's devopts).
 *
 * The daemon refuses operations a driver does not advertise before calling it,
 * and the same tables feed the protocol's describe method and gonioctl help. */
#pragma once

enum opt_key {
        OPT_POSITION,
        OPT_VELOCITY,
        OPT_ACCEL,
        OPT_HOME,
        OPT_STOP,
        OPT_STATE,    /* switch on/off */
        OPT_EXPOSURE, /* microseconds */
        OPT_GAIN,
        OPT_BITS,
};

enum opt_flags { OPT_GET = 1, OPT_SET = 2, OPT_LIST = 4 };

struct opt_desc {
        enum opt_key key;
        int flags;
        const char *unit;
        double min, max;
};

/* The option's name as used in the protocol ("position", "exposure", ...); "unknown" for a
 * value outside the enum. Never NULL. */
const char *opt_key_name(enum opt_key key);

/* The entry for key in a table of n entries, or NULL when the driver lacks it. */
const struct opt_desc *opt_find(const struct opt_desc *opts, int n, enum opt_key key);
