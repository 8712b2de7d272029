/* args.c - gonioctl's option parser: a table of long options, values checked here,
 * and which command accepts which option checked by cmd.c. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "client/args.h"
#include "common/cleanup.h"

enum opt_id {
        O_SOCKET,
        O_JSON,
        O_TIMEOUT,
        O_QUIET,
        O_HELP,
        O_VERSION,
        O_RELATIVE,
        O_NO_WAIT,
        O_CAMERA,
        O_EXPOSURE,
        O_GAIN,
        O_BITS,
        O_COUNT,
        O_FROM,
        O_BOARD,
        O_FORCE,
        O_NO_MESH,
        O_TRIANGLES,
        O_LASER,
        O_CALIBRATION,
        O_START,
        O_END,
        O_STEP,
        O_MODE,
        O_LAMPS,
        O_SPHERE,
        O_LAMP_RADIUS,
        O_NOMINAL,
        O_RIG,
        O_STATE,
        O_FOR,
};

static const struct {
        const char *name;
        enum opt_id id;
        const char *arg; /* the value's name in --help, NULL: a flag */
        unsigned bit;    /* enum arg_opt for command options, 0 for global ones */
        const char *help;
} options[] = {
        {"socket", O_SOCKET, "PATH", 0, "goniod's socket"},
        {"json", O_JSON, NULL, 0, "results and errors as JSON on stdout"},
        {"timeout", O_TIMEOUT, "SEC", 0, "reply timeout"},
        {"quiet", O_QUIET, NULL, 0, "print nothing on success"},
        {"help", O_HELP, NULL, 0, "usage"},
        {"version", O_VERSION, NULL, 0, "version"},
        {"relative", O_RELATIVE, NULL, ARG_RELATIVE, "DEG is relative to the position"},
        {"no-wait", O_NO_WAIT, NULL, ARG_NO_WAIT, "return once goniod accepted the move"},
        {"camera", O_CAMERA, "NAME", ARG_CAMERA, "the camera (default: every one, or the only)"},
        {"exposure", O_EXPOSURE, "US", ARG_EXPOSURE, "exposure in microseconds"},
        {"gain", O_GAIN, "G", ARG_GAIN, "analogue gain"},
        {"bits", O_BITS, "8|16", ARG_BITS, "bits per sample"},
        {"count", O_COUNT, "N", ARG_COUNT, "stop after N notifications"},
        {"from", O_FROM, "DIR", ARG_FROM, "work on the dataset at DIR, without goniod"},
        {"board", O_BOARD, "SPEC", ARG_BOARD,
         "chessboard:COLSxROWS:MM or charuco:COLSxROWS:MM:MARKER_MM"},
        {"force", O_FORCE, NULL, ARG_FORCE, "replace a better or existing result"},
        {"no-mesh", O_NO_MESH, NULL, ARG_NO_MESH, "the point cloud only"},
        {"triangles", O_TRIANGLES, "N", ARG_TRIANGLES, "the mesh's target triangle count"},
        {"laser", O_LASER, "NAME", ARG_LASER, "the laser (default: every one)"},
        {"calibration", O_CALIBRATION, "FILE", ARG_CALIBRATION, "the calibration file"},
        {"start", O_START, "DEG", ARG_START, "first turntable angle"},
        {"end", O_END, "DEG", ARG_END, "last turntable angle"},
        {"step", O_STEP, "DEG", ARG_STEP, "turntable step"},
        {"mode", O_MODE, "MODE", ARG_MODE, "continuous or stop"},
        {"lamps", O_LAMPS, "A,B", ARG_LAMPS, "lamps lit (comma-separated names)"},
        {"sphere", O_SPHERE, "MM", ARG_SPHERE, "the mirror sphere's diameter"},
        {"lamp-radius", O_LAMP_RADIUS, "MM", ARG_LAMP_RADIUS, "the lamps' radius"},
        {"nominal", O_NOMINAL, NULL, ARG_NOMINAL, "the rig file's lamp positions"},
        {"rig", O_RIG, "RIG-FILE", ARG_RIG, "the rig a session file runs on"},
        {"state", O_STATE, "STATE", ARG_STATE,
         "idle (default), homing, moving, stopping, capturing, storing or fault"},
        {"for", O_FOR, "SEC", ARG_FOR, "hold it on SEC seconds, then switch it off"},
};

static char last_error[256]; /* the first usage error, for --json (args_last_error) */

int args_usage_error(const char *what, const char *fmt, ...)
{
        char msg[200];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        fprintf(stderr, "gonioctl: %s: %s\nTry 'gonioctl --help'.\n", what, msg);
        if (!last_error[0])
                snprintf(last_error, sizeof(last_error), "%s: %s", what, msg);
        return -EINVAL;
}

const char *args_last_error(void)
{
        return last_error[0] ? last_error : NULL;
}

void args_print_options(FILE *f, unsigned opts)
{
        for (size_t k = 0; k < ELEMENTSOF(options); k++) {
                char left[40];

                if (!(options[k].bit & opts))
                        continue;
                snprintf(left, sizeof(left), "--%s%s%s", options[k].name, options[k].arg ? " " : "",
                         options[k].arg ?: "");
                fprintf(f, "  %-22s %s\n", left, options[k].help);
        }
}

const char *args_opt_name(unsigned bit)
{
        for (size_t k = 0; k < ELEMENTSOF(options); k++)
                if (bit != 0 && options[k].bit == bit)
                        return options[k].name;
        return NULL;
}

int args_parse_double(const char *s, double *ret)
{
        char *end;
        double v;

        errno = 0;
        v = strtod(s, &end);
        if (errno != 0 || end == s || *end != '\0' || !isfinite(v))
                return -EINVAL;
        *ret = v;
        return 0;
}

int args_parse_long(const char *s, long min, long max, long *ret)
{
        char *end;
        long v;

        errno = 0;
        v = strtol(s, &end, 10);
        if (errno != 0 || end == s || *end != '\0' || v < min || v > max)
                return -EINVAL;
        *ret = v;
        return 0;
}

/* Stores the value of option id. Returns 0 or -EINVAL (message printed). */
static int set_value(struct args *a, enum opt_id id, const char *v)
{
        long l;

        switch (id) {
        case O_SOCKET:
                a->socket = v;
                return 0;
        case O_TIMEOUT:
                if (args_parse_double(v, &a->timeout_s) < 0 || a->timeout_s <= 0 ||
                    a->timeout_s > 86400)
                        break;
                return 0;
        case O_CAMERA:
                a->camera = v;
                return 0;
        case O_EXPOSURE:
                return args_parse_long(v, 1, INT_MAX, &a->exposure_us) < 0 ? -EINVAL : 0;
        case O_GAIN:
                if (args_parse_double(v, &a->gain) < 0 || a->gain < 0)
                        break;
                return 0;
        case O_BITS:
                if (args_parse_long(v, 8, 16, &l) < 0 || (l != 8 && l != 16))
                        break;
                a->bits = (int)l;
                return 0;
        case O_COUNT:
                return args_parse_long(v, 1, LONG_MAX, &a->count) < 0 ? -EINVAL : 0;
        case O_FROM:
                a->from = v;
                return 0;
        case O_BOARD:
                a->board = v;
                return 0;
        case O_TRIANGLES:
                return args_parse_long(v, 1, INT_MAX, &a->triangles) < 0 ? -EINVAL : 0;
        case O_LASER:
                a->laser = v;
                return 0;
        case O_CALIBRATION:
                a->calib = v;
                return 0;
        case O_START:
                return args_parse_double(v, &a->start);
        case O_END:
                return args_parse_double(v, &a->end);
        case O_STEP:
                if (args_parse_double(v, &a->step) < 0 || a->step <= 0)
                        break;
                return 0;
        case O_MODE:
                a->mode = v;
                return 0;
        case O_LAMPS:
                a->lamps = v;
                return 0;
        case O_RIG:
                a->rig = v;
                return 0;
        case O_STATE:
                a->state = v;
                return 0;
        case O_FOR:
                if (args_parse_double(v, &a->for_s) < 0 || a->for_s <= 0 || a->for_s > 86400)
                        break;
                return 0;
        case O_SPHERE:
                if (args_parse_double(v, &a->sphere_mm) < 0 || a->sphere_mm <= 0)
                        break;
                return 0;
        case O_LAMP_RADIUS:
                if (args_parse_double(v, &a->lamp_radius_mm) < 0 || a->lamp_radius_mm < 0)
                        break;
                return 0;
        default:
                break;
        }
        return -EINVAL;
}

static void set_flag(struct args *a, enum opt_id id)
{
        a->json |= id == O_JSON;
        a->quiet |= id == O_QUIET;
        a->help |= id == O_HELP;
        a->version |= id == O_VERSION;
}

/* Handles argv[*i] = "--name[=value]"; advances *i past a separate value. */
static int parse_option(struct args *a, int argc, char **argv, int *i)
{
        const char *arg = argv[*i] + 2, *eq = strchr(arg, '=');
        size_t n = eq ? (size_t)(eq - arg) : strlen(arg);

        for (size_t k = 0; k < ELEMENTSOF(options); k++) {
                const char *v = eq ? eq + 1 : NULL;

                if (strlen(options[k].name) != n || strncmp(options[k].name, arg, n) != 0)
                        continue;
                a->given |= options[k].bit;
                if (!options[k].arg) {
                        if (eq)
                                return args_usage_error(argv[*i], "takes no value");
                        set_flag(a, options[k].id);
                        return 0;
                }
                if (!v && *i + 1 >= argc)
                        return args_usage_error(argv[*i], "needs a value");
                if (!v)
                        v = argv[++*i];
                if (set_value(a, options[k].id, v) < 0)
                        return args_usage_error(options[k].name, "invalid value '%s'", v);
                return 0;
        }
        return args_usage_error(argv[*i], "unknown option");
}

/* True for words that are options: "-x" or "--x", but not numbers like "-10" or "-.5". */
static bool is_option(const char *s)
{
        return s[0] == '-' && s[1] != '\0' && s[1] != '.' && (s[1] < '0' || s[1] > '9');
}

int args_parse(int argc, char **argv, struct args *a)
{
        bool options_done = false, own_options = false;

        *a = (struct args){};
        a->words = calloc((size_t)MAX(argc, 1), sizeof(char *));
        if (!a->words)
                return -ENOMEM;
        for (int i = 1; i < argc; i++) {
                const char *s = argv[i];
                int r;

                if (own_options && !options_done &&
                    (strcmp(s, "--help") == 0 || strcmp(s, "-h") == 0)) {
                        a->help = true;
                        continue;
                }
                if (options_done || own_options || !is_option(s)) {
                        a->words[a->nwords++] = argv[i];
                        /* `model` subcommands and `dataset export` parse their own
                         * options (client/model.h, client/export.h), all but --help */
                        own_options |= (a->nwords == 1 && strcmp(s, "model") == 0) ||
                                       (a->nwords == 2 && strcmp(s, "export") == 0 &&
                                        strcmp(a->words[0], "dataset") == 0);
                        continue;
                }
                if (strcmp(s, "--") == 0) {
                        options_done = true;
                        continue;
                }
                if (strcmp(s, "-h") == 0) {
                        a->help = true;
                        continue;
                }
                if (s[1] != '-')
                        return args_usage_error(s, "unknown option");
                r = parse_option(a, argc, argv, &i);
                if (r < 0)
                        return r;
        }
        return 0;
}

void args_done(struct args *a)
{
        free(a->words);
        a->words = NULL;
}
