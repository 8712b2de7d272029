/* args.h - gonioctl's command line: global and per-command long options (accepted
 * anywhere, "--opt VALUE" or "--opt=VALUE", "--" ends options) and the positional
 * words. Negative numbers ("-10") are positional, so `move camera_arm -10` works. */
#pragma once

#include <stdbool.h>
#include <stdio.h>

/* Options that only some commands accept (struct cmd lists which). */
enum arg_opt {
        ARG_RELATIVE = 1 << 0,
        ARG_NO_WAIT = 1 << 1,
        ARG_CAMERA = 1 << 2,
        ARG_EXPOSURE = 1 << 3,
        ARG_GAIN = 1 << 4,
        ARG_BITS = 1 << 5,
        ARG_COUNT = 1 << 6,
        ARG_FROM = 1 << 7,
        ARG_BOARD = 1 << 8,
        ARG_FORCE = 1 << 9,
        ARG_TRIANGLES = 1 << 10,
        ARG_LASER = 1 << 11,
        ARG_CALIBRATION = 1 << 12,
        ARG_START = 1 << 13,
        ARG_END = 1 << 14,
        ARG_STEP = 1 << 15,
        ARG_MODE = 1 << 16,
        ARG_LAMPS = 1 << 17,
        ARG_NO_MESH = 1 << 18,
        ARG_SPHERE = 1 << 19,
        ARG_LAMP_RADIUS = 1 << 20,
        ARG_NOMINAL = 1 << 21,
        ARG_RIG = 1 << 22,
        ARG_STATE = 1 << 23,
        ARG_FOR = 1 << 24,
};

struct args {
        const char *socket; /* --socket, NULL for the default path */
        bool json, quiet, help, version;
        double timeout_s;        /* --timeout, 0 when not given */
        unsigned given;          /* enum arg_opt bits seen */
        const char *camera;      /* --camera */
        long exposure_us;        /* --exposure */
        double gain;             /* --gain */
        int bits;                /* --bits */
        long count;              /* --count */
        const char *from;        /* --from: a dataset directory */
        const char *board;       /* --board: a board description (calib/camera.h) */
        const char *laser;       /* --laser: a laser's name */
        const char *calib;       /* --calibration: a calibration file */
        long triangles;          /* --triangles: a mesh's target triangle count */
        double start, end, step; /* --start, --end, --step: degrees (scan) */
        const char *mode;        /* --mode (scan) */
        const char *lamps;       /* --lamps: comma-separated names (scan) */
        double sphere_mm;        /* --sphere: the mirror sphere's diameter (calibrate lamps) */
        double lamp_radius_mm;   /* --lamp-radius (calibrate lamps) */
        const char *rig;         /* --rig: a rig file (validate) */
        const char *state;       /* --state: a rig state (wait) */
        double for_s;            /* --for: seconds to hold a laser or lamp on */
        char **words;            /* positional words (command first); borrowed from argv */
        int nwords;
};

/* Parses argv into a (zeroed first). Returns 0, or -EINVAL after printing the problem to
 * stderr (exit code 2), or -ENOMEM. Free a->words with args_done. */
int args_parse(int argc, char **argv, struct args *a);

/* Frees what args_parse allocated. */
void args_done(struct args *a);

/* Prints "gonioctl: <what>: <message>" and a hint to stderr; returns -EINVAL. The first
 * such message of the process is kept for args_last_error(). */
int args_usage_error(const char *what, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* The first usage error printed ("<what>: <message>"), or NULL. Valid until exit. */
const char *args_last_error(void);

/* Prints one line per option of the enum arg_opt bits in opts ("  --camera NAME  the camera")
 * to f, for a command's --help. */
void args_print_options(FILE *f, unsigned opts);

/* The long name of an enum arg_opt bit ("relative"), or NULL. */
const char *args_opt_name(unsigned bit);

/* Parses a whole decimal number (strtod rules, must be finite). Returns 0 or -EINVAL. */
int args_parse_double(const char *s, double *ret);

/* Parses a whole decimal integer in [min, max]. Returns 0 or -EINVAL. */
int args_parse_long(const char *s, long min, long max, long *ret);
