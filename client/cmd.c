/* cmd.c - gonioctl's subcommands as data: each row says how to build the params of one
 * JSON-RPC method from the command line and how to print its result. One runner does
 * the rest: connect, hello (checks the protocol version), call, print, exit code. */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <string.h>
#include <fcntl.h>
#include <unistd.h>

#include "drivers/discover.h"
#include "client/calibrate.h"
#include "client/scan_capture.h"
#include "client/cmd.h"
#include "client/conn.h"
#include "client/doctor.h"
#include "client/model.h"
#include "client/output.h"
#include "client/scan.h"
#include "client/export.h"
#include "client/hold.h"
#include "client/session.h"
#include "client/settings.h"
#include "client/validate.h"
#include "client/wait.h"
#include "common/cleanup.h"
#include "protocol/proto.h"
#include "gonio_version.h"

#define TIMEOUT_S      30  /* connect, hello and quick requests */
#define TIMEOUT_LONG_S 120 /* home, move, capture */
#define USAGE_COL      36  /* width of the synopsis column of --help */
#define CALIBRATE_OPTS (ARG_FROM | ARG_BOARD | ARG_CAMERA | ARG_FORCE | ARG_CALIBRATION)
#define STOP_WAIT_S    2 /* for the replies to stop and status after an interrupted wait */

struct cmd;

/* Builds the params of c's request from its positional arguments (argv[0..argc)).
 * Returns 0 or -EINVAL after printing a usage error. */
typedef int (*params_fn)(const struct cmd *c, const struct args *a, char **argv, int argc,
                         json_t **ret);

struct cmd {
        const char *group; /* "dataset", "fault", or NULL */
        const char *name;
        const char *args; /* synopsis of the arguments, for usage */
        const char *help;
        const char *method; /* NULL: the first argument names it (call) */
        int min_args, max_args;
        unsigned opts;      /* enum arg_opt accepted */
        int timeout_s;      /* default reply timeout */
        params_fn params;   /* NULL: {} */
        out_print_fn print; /* human output */
        const char *done;   /* human output when print is NULL */
        /* runs instead of a method once connected (watch, wait); returns an exit code */
        int (*run)(const struct args *a, struct out *o, struct conn *conn);
        bool stops;   /* waits for motion: an interrupted wait stops the rig (not --no-wait) */
        bool follows; /* follows the session its result describes until it ends or pauses */
        bool admin;   /* an admin method: over the admin socket (admin_socket) */
        bool holds;   /* switches on: holds them on while connected (hold_switch) */
        /* runs here, without goniod: fills its result (printed) or prints its error with
         * out_error; returns an enum gonioctl_exit value */
        int (*local)(const struct args *a, struct out *o, json_t **ret);
};

/* "move", "dataset open": the words naming c, for messages. */
static const char *cmd_title(const struct cmd *c, char *buf, size_t n)
{
        snprintf(buf, n, "%s%s%s", c->group ?: "", c->group ? " " : "", c->name);
        return buf;
}

static int usage_error(const struct cmd *c, const char *fmt, ...)
        __attribute__((format(printf, 2, 3)));

static int usage_error(const struct cmd *c, const char *fmt, ...)
{
        char t[64], msg[256];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        return args_usage_error(cmd_title(c, t, sizeof(t)), "%s", msg);
}

/* Sets key to a stolen value; returns -ENOMEM if either is missing. */
static int set(json_t *o, const char *key, json_t *v)
{
        return v && json_object_set_new(o, key, v) == 0 ? 0 : -ENOMEM;
}

static int parse_onoff(const struct cmd *c, const char *s, bool *on)
{
        if (strcmp(s, "on") != 0 && strcmp(s, "off") != 0)
                return usage_error(c, "expected on or off, not '%s'", s);
        *on = strcmp(s, "on") == 0;
        return 0;
}

static int p_home(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        json_t *axes;

        if (argc == 0)
                return 0; /* {}: all axes */
        axes = json_array();
        for (int i = 0; axes && i < argc; i++)
                if (json_array_append_new(axes, json_string(argv[i])) < 0) {
                        json_decref(axes);
                        return -ENOMEM;
                }
        return set(*ret, "axes", axes);
}

static int p_move(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        double pos;

        if (args_parse_double(argv[1], &pos) < 0)
                return usage_error(c, "invalid position '%s' (degrees)", argv[1]);
        if (set(*ret, "axis", json_string(argv[0])) < 0 ||
            set(*ret, "position", json_real(pos)) < 0 ||
            set(*ret, "relative", json_boolean(a->given & ARG_RELATIVE)) < 0)
                return -ENOMEM;
        return set(*ret, "wait", json_boolean(!(a->given & ARG_NO_WAIT)));
}

static int p_lamp(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        bool digits = argv[0][strspn(argv[0], "0123456789")] == '\0';
        long index;
        bool on = false;

        if (parse_onoff(c, argv[1], &on) < 0)
                return -EINVAL;
        if (digits && args_parse_long(argv[0], 0, INT32_MAX, &index) < 0)
                return usage_error(c, "invalid lamp index '%s'", argv[0]);
        if (set(*ret, "lamp", digits ? json_integer(index) : json_string(argv[0])) < 0)
                return -ENOMEM;
        return set(*ret, "on", json_boolean(on));
}

static int p_laser(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        bool on = false;

        if (parse_onoff(c, argv[0], &on) < 0)
                return -EINVAL;
        if (argc > 1 && set(*ret, "laser", json_string(argv[1])) < 0)
                return -ENOMEM;
        return set(*ret, "on", json_boolean(on));
}

/* {device, setting?} from DEVICE[.SETTING]: the setting is what follows the last dot. */
static int p_device(const struct cmd *c, const char *arg, bool need_setting, json_t *p)
{
        const char *dot = strrchr(arg, '.');

        if ((dot && (dot == arg || !dot[1])) || (need_setting && !dot))
                return usage_error(c, "expected DEVICE.SETTING, not '%s'", arg);
        if (set(p, "device", json_stringn(arg, dot ? (size_t)(dot - arg) : strlen(arg))) < 0)
                return -ENOMEM;
        return dot ? set(p, "setting", json_string(dot + 1)) : 0;
}

static int p_get(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        return argc > 0 ? p_device(c, argv[0], false, *ret) : 0;
}

static int p_set(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        double v;
        int r = p_device(c, argv[0], true, *ret);

        if (r < 0)
                return r;
        if (args_parse_double(argv[1], &v) < 0)
                return usage_error(c, "invalid value '%s' (a number)", argv[1]);
        return set(*ret, "value", json_real(v));
}

static int p_capture(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        if ((a->given & ARG_CAMERA) && set(*ret, "camera", json_string(a->camera)) < 0)
                return -ENOMEM;
        if ((a->given & ARG_EXPOSURE) && set(*ret, "exposure_us", json_integer(a->exposure_us)) < 0)
                return -ENOMEM;
        if ((a->given & ARG_GAIN) && set(*ret, "gain", json_real(a->gain)) < 0)
                return -ENOMEM;
        if ((a->given & ARG_BITS) && set(*ret, "bits", json_integer(a->bits)) < 0)
                return -ENOMEM;
        return 0;
}

/* {name} for dataset open/info, plus create:true for dataset create. */
static int p_dataset(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        if (argc > 0 && set(*ret, "name", json_string(argv[0])) < 0)
                return -ENOMEM;
        if (strcmp(c->name, "create") == 0)
                return set(*ret, "create", json_true());
        return 0;
}

static int p_session_file(const struct cmd *c, const struct args *a, char **argv, int argc,
                          json_t **ret)
{
        return csession_file_params(argv[0], *ret);
}

static int p_session_dataset(const struct cmd *c, const struct args *a, char **argv, int argc,
                             json_t **ret)
{
        return argc > 0 ? set(*ret, "dataset", json_string(argv[0])) : 0;
}

static int p_call(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        json_error_t jerr;
        json_t *p;

        if (argc < 2)
                return 0;
        p = json_loads(argv[1], 0, &jerr);
        if (!json_is_object(p) && !json_is_array(p)) {
                json_decref(p);
                return usage_error(c, "params must be a JSON object or array: %s", argv[1]);
        }
        json_decref(*ret);
        *ret = p;
        return 0;
}

static int p_wait(const struct cmd *c, const struct args *a, char **argv, int argc, json_t **ret)
{
        if (a->state && !wait_state_known(a->state))
                return usage_error(c, "unknown state '%s'", a->state);
        return 0;
}

static int run_watch(const struct args *a, struct out *o, struct conn *conn);

/* The devices of this machine, from $GONIO_SYSFS (for tests) or /sys. */
static int discover_here(const struct args *a, struct out *o, json_t **ret)
{
        const char *sysfs = getenv("GONIO_SYSFS");

        *ret = discover_all(sysfs && *sysfs ? sysfs : "/sys");
        if (!*ret)
                out_error(o, "devices", "out of memory");
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

static const struct cmd commands[] = {
        {NULL, "status", "", "rig state, axes, lamps, lasers, cameras, dataset", "status", 0, 0, 0,
         TIMEOUT_S, NULL, out_print_status},
        {NULL, "describe", "", "devices, backends and their options", "describe", 0, 0, 0,
         TIMEOUT_S, NULL, out_print_describe},
        {NULL, "home", "[AXIS...]", "home the given axes (default: all)", "home", 0, 64, 0,
         TIMEOUT_LONG_S, p_home, out_print_home, .stops = true},
        {NULL, "move", "AXIS DEG [--relative] [--no-wait]", "move an axis (degrees)", "move", 2, 2,
         ARG_RELATIVE | ARG_NO_WAIT, TIMEOUT_LONG_S, p_move, out_print_move, .stops = true},
        {NULL, "stop", "", "stop all motion now", "stop", 0, 0, 0, TIMEOUT_S, NULL, out_print_stop},
        {NULL, "lamp", "N|NAME on|off [--for SEC]",
         "switch a lamp (off_on_disconnect: held on as a laser)", "lamp.set", 2, 2, ARG_FOR,
         TIMEOUT_S, p_lamp, out_print_lamp, .holds = true},
        {NULL, "laser", "on|off [NAME] [--for SEC]",
         "switch the laser NAME, or every laser (on: held until Ctrl-C, SIGTERM or --for)",
         "laser.set", 1, 2, ARG_FOR, TIMEOUT_S, p_laser, out_print_laser, .holds = true},
        {NULL, "get", "[DEVICE[.SETTING]]",
         "device settings and their limits (axis speed, accel; camera exposure_us, gain)",
         "device.get", 0, 1, 0, TIMEOUT_S, p_get, settings_print_get},
        {NULL, "set", "DEVICE.SETTING VALUE",
         "change a device setting until goniod restarts (refused during a session)", "device.set",
         2, 2, 0, TIMEOUT_S, p_set, settings_print_set},
        {NULL, "capture", "[--camera NAME] [--exposure US] [--gain G] [--bits 8|16]",
         "capture into the open dataset", "capture", 0, 0,
         ARG_CAMERA | ARG_EXPOSURE | ARG_GAIN | ARG_BITS, TIMEOUT_LONG_S, p_capture,
         out_print_capture},
        {"dataset", "list", "", "list the datasets", "dataset.list", 0, 0, 0, TIMEOUT_S, NULL,
         out_print_dataset_list},
        {"dataset", "info", "[NAME]", "a dataset (default: the open one) and its last captures",
         "dataset.info", 0, 1, 0, TIMEOUT_S, p_dataset, out_print_dataset_info},
        {"dataset", "open", "NAME", "open an existing dataset", "dataset.open", 1, 1, 0, TIMEOUT_S,
         p_dataset, out_print_dataset},
        {"dataset", "create", "NAME", "create and open a new dataset", "dataset.open", 1, 1, 0,
         TIMEOUT_S, p_dataset, out_print_dataset},
        {"dataset", "check", "NAME", "verify rows, files, checksums and session plans",
         "dataset.check", 1, 1, 0, TIMEOUT_LONG_S, p_dataset, NULL, "dataset is consistent"},
        {"dataset", "export",
         "DATASET --format colmap|nerfstudio|ply|rti|gltf -o DIR [--model NAME] "
         "[--calibration FILE|nominal]",
         "write DATASET in a format other tools read into the new folder DIR (docs/exports.md; "
         "no goniod)",
         NULL, 1, INT_MAX, 0, TIMEOUT_S, NULL, export_print, .local = export_command},
        {"dataset", "close", "", "close the open dataset", "dataset.close", 0, 0, 0, TIMEOUT_S,
         NULL, NULL, "dataset closed"},
        {"fault", "clear", "", "clear a latched fault", "fault.clear", 0, 0, 0, TIMEOUT_S, NULL,
         NULL, "fault cleared"},
        {"fault", "override", "",
         "lift a latched fault without rechecking the devices (admin socket: root)",
         "fault.override", 0, 0, 0, TIMEOUT_S, NULL, NULL, "fault overridden", .admin = true},
        {"session", "plan", "FILE", "what a session file will do and how long it takes",
         "session.plan", 1, 1, 0, TIMEOUT_S, p_session_file, out_print_session_plan},
        {"session", "run", "FILE", "run a session file (Ctrl-C pauses it)", "session.run", 1, 1, 0,
         TIMEOUT_LONG_S, p_session_file, NULL, .follows = true},
        {"session", "resume", "[DATASET]", "resume the paused or interrupted session",
         "session.resume", 0, 1, 0, TIMEOUT_LONG_S, p_session_dataset, NULL, .follows = true},
        {"session", "pause", "", "pause the session at the next capture", "session.pause", 0, 0, 0,
         TIMEOUT_S, NULL, out_print_session_status},
        {"session", "abort", "[DATASET]",
         "end the session now (or an unfinished one after a restart)", "session.abort", 0, 1, 0,
         TIMEOUT_S, p_session_dataset, out_print_session_status},
        {"session", "status", "", "the session's state and progress", "session.status", 0, 0, 0,
         TIMEOUT_S, NULL, out_print_session_status},
        {"session", "watch", "", "follow the session until it ends or pauses", "session.status", 0,
         0, 0, TIMEOUT_S, NULL, NULL, .follows = true},
        {NULL, "watch", "[--count N]", "print notifications until interrupted", NULL, 0, 0,
         ARG_COUNT, TIMEOUT_S, NULL, NULL, .run = run_watch},
        {NULL, "wait", "[--state STATE]",
         "wait until the rig is in STATE (default idle); --timeout SEC: exit 10 after SEC", NULL, 0,
         0, ARG_STATE, TIMEOUT_S, p_wait, NULL, .run = wait_command},
        {NULL, "validate", "FILE [--rig RIG-FILE]",
         "check a rig file, or a session file against its rig file (no goniod)", NULL, 1, 1,
         ARG_RIG, TIMEOUT_S, NULL, validate_print, .local = validate_command},
        {NULL, "doctor", "[SESSION-FILE]",
         "check the socket, goniod, the fault, every device and the room a session needs", NULL, 0,
         1, 0, TIMEOUT_S, NULL, doctor_print, .local = doctor_command},
        {NULL, "devices", "", "serial ports, V4L2 nodes, gpiochips, USB devices here (no goniod)",
         NULL, 0, 0, 0, TIMEOUT_S, NULL, out_print_devices, .local = discover_here},
        {NULL, "scan",
         "DATASET [--mode continuous|stop] [--start A --end B --step S] ... | --from DIR ...",
         "capture a laser scan into DATASET (docs/scanning.md), or rebuild the point cloud and "
         "mesh of the dataset at DIR (no goniod)",
         NULL, 0, 1,
         ARG_MODE | ARG_FROM | ARG_START | ARG_END | ARG_STEP | ARG_CAMERA | ARG_EXPOSURE |
                 ARG_GAIN | ARG_LAMPS | ARG_TRIANGLES | ARG_FORCE | ARG_CALIBRATION | ARG_NO_MESH,
         TIMEOUT_S, NULL, scan_command_print, .local = scan_command},
        {"calibrate", "camera", "--board SPEC [--from DATASET] [CALIBRATE-OPTS]",
         "capture board views on the rig (or take DATASET's) and solve a camera's intrinsics", NULL,
         0, 0, CALIBRATE_OPTS, TIMEOUT_S, NULL, calibrate_print_camera, .local = calibrate_camera},
        {"calibrate", "turntable", "--board SPEC [--from DATASET] [CALIBRATE-OPTS]",
         "... and solve the turntable axis and the camera's pose", NULL, 0, 0, CALIBRATE_OPTS,
         TIMEOUT_S, NULL, calibrate_print_turntable, .local = calibrate_turntable},
        {"calibrate", "laser", "--board SPEC [--from DATASET] [--laser NAME] [CALIBRATE-OPTS]",
         "... and solve the laser plane in the turntable frame", NULL, 0, 0,
         CALIBRATE_OPTS | ARG_LASER, TIMEOUT_S, NULL, calibrate_print_laser,
         .local = calibrate_laser},
        {"calibrate", "lamps",
         "--sphere MM [--from DATASET] [--lamp-radius MM] [--calibration FILE] [--force] | "
         "--nominal RIG-FILE",
         "... and solve the lamps' positions from a mirror sphere off the turntable's axis, "
         "before a bright background; or write the rig file's (--nominal, or of --from's)",
         NULL, 0, 1,
         ARG_FROM | ARG_FORCE | ARG_CALIBRATION | ARG_SPHERE | ARG_LAMP_RADIUS | ARG_NOMINAL,
         TIMEOUT_S, NULL, calibrate_print_lamps, .local = calibrate_lamps},
        {NULL, "model",
         "fit DATASET [--name N] [--order P] [--components K] [--sample F] [--reg tikhonov|tsvd] "
         "[--reg-param X] [--tile N] [--threads N] [--calibration FILE|nominal] [--mesh FILE] "
         "[--force] | render DATASET/models/N (--light X,Y,Z|--dir X,Y,Z|--envmap FILE) "
         "--view AZ,EL [--distance MM] [--mode pixel|object] [--size WxH] [--intensity I] "
         "[--gain G] -o OUT.png | view DATASET/models/N [--bind ADDR] [--port N] "
         "[--envmap FILE]... | export --web DIR DATASET/models/N [--envmap FILE]...",
         "fit the appearance model of DATASET into DATASET/models/N, render it (docs/"
         "appearance.md), or show it in the browser (docs/viewer.md); no goniod",
         NULL, 1, INT_MAX, 0, TIMEOUT_S, NULL, model_print, .local = model_command},
        {NULL, "call", "METHOD [JSON-PARAMS]", "send any request, print its result", NULL, 1, 2, 0,
         TIMEOUT_S, p_call, out_print_pretty},
};

/* One line of the command list: "  move AXIS DEG ...   move an axis (degrees)". */
static void usage_line(FILE *f, const struct cmd *c)
{
        char t[64], line[128];

        snprintf(line, sizeof(line), "%s %s", cmd_title(c, t, sizeof(t)), c->args);
        if (strlen(line) > USAGE_COL)
                fprintf(f, "  %s\n  %-*s %s\n", line, USAGE_COL, "", c->help);
        else
                fprintf(f, "  %-*s %s\n", USAGE_COL, line, c->help);
}

static const char global_options[] =
        "  --socket PATH   goniod's socket (default $GONIO_SOCKET, else\n"
        "                  $XDG_RUNTIME_DIR/gonio/goniod.sock, else /run/gonio/goniod.sock)\n"
        "  --json          results, and errors as {\"error\":{...}}, as one line of JSON\n"
        "  --timeout SEC   reply timeout (default 30, home/move/capture 120)\n"
        "  --quiet         print nothing on success\n";

void cmd_usage(FILE *f)
{
        fprintf(f, "Usage: gonioctl [--socket PATH] [--json] [--timeout SEC] [--quiet] COMMAND "
                   "[ARGS]\n\nCommands:\n");
        for (size_t i = 0; i < ELEMENTSOF(commands); i++)
                usage_line(f, &commands[i]);
        fprintf(f,
                "\nOptions:\n%s"
                "  CALIBRATE-OPTS  [--camera NAME] [--calibration FILE] [--force]\n"
                "  --help, --version   (COMMAND --help: that command's usage)\n"
                "\nExit codes: 0 ok, 2 usage, 3 cannot connect, 4 protocol error or timeout,\n"
                "5 device fault, 6 invalid/not found/out of range, 7 storage, 8 canceled,\n"
                "9 busy or wrong state, 10 interrupted (move/home stopped, wait timed out).\n"
                "See gonioctl(1).\n",
                global_options);
}

/* The usage of one command: synopsis, what it does, its options. */
static void command_help(FILE *f, const struct cmd *c)
{
        char t[64];

        fprintf(f, "Usage: gonioctl [OPTIONS] %s %s\n\n%s\n", cmd_title(c, t, sizeof(t)), c->args,
                c->help);
        if (c->opts) {
                fprintf(f, "\nOptions of %s:\n", t);
                args_print_options(f, c->opts);
        }
        fprintf(f, "\nOPTIONS:\n%s\nSee gonioctl(1) for the exit codes.\n", global_options);
}

/* The commands of group (dataset, session...) when it names one: returns true. */
static bool group_help(FILE *f, const char *group)
{
        bool found = false;

        for (size_t i = 0; i < ELEMENTSOF(commands); i++) {
                if (!commands[i].group || strcmp(commands[i].group, group) != 0)
                        continue;
                if (!found)
                        fprintf(f, "Usage: gonioctl [OPTIONS] %s COMMAND [ARGS]\n\nCommands:\n",
                                group);
                found = true;
                usage_line(f, &commands[i]);
        }
        if (found)
                fprintf(f, "\nOPTIONS:\n%s", global_options);
        return found;
}

/* Finds the command named by words; *used gets the number of words naming it. */
static const struct cmd *find_cmd(char **words, int n, int *used)
{
        bool group = false;

        for (size_t i = 0; i < ELEMENTSOF(commands); i++) {
                const struct cmd *c = &commands[i];

                if (!c->group && strcmp(c->name, words[0]) == 0) {
                        *used = 1;
                        return c;
                }
                if (c->group && strcmp(c->group, words[0]) == 0) {
                        group = true;
                        if (n > 1 && strcmp(c->name, words[1]) == 0) {
                                *used = 2;
                                return c;
                        }
                }
        }
        if (group && n > 1)
                args_usage_error(words[0], "unknown subcommand '%s'", words[1]);
        else if (group)
                args_usage_error(words[0], "missing subcommand");
        else
                args_usage_error(words[0], "unknown command");
        return NULL;
}

/* Checks options and argument count, then builds the params. Returns 0 or -EINVAL. */
static int build_params(const struct cmd *c, const struct args *a, char **argv, int argc,
                        json_t **ret)
{
        unsigned extra = a->given & ~c->opts;

        if (extra)
                return usage_error(c, "does not take --%s", args_opt_name(extra & -extra));
        if (argc < c->min_args)
                return usage_error(c, "missing arguments (usage: %s %s)", c->name, c->args);
        if (argc > c->max_args)
                return usage_error(c, "unexpected argument '%s'", argv[c->max_args]);
        *ret = json_object();
        if (!*ret)
                return -ENOMEM;
        return c->params ? c->params(c, a, argv, argc, ret) : 0;
}

int cmd_exit_for_errno(int r)
{
        return r == -ENODATA || r == -ENOENT || r == -EINVAL || r == -EEXIST || r == -EBADMSG ||
                               r == -EDOM || r == -E2BIG
                       ? EXIT_INVALID
                       : EXIT_STORAGE;
}

int cmd_exit_for_code(int code)
{
        static const struct {
                int err, exit;
        } table[] = {
                {EIO, EXIT_DEVICE},     {ETIMEDOUT, EXIT_DEVICE}, {EINVAL, EXIT_INVALID},
                {ERANGE, EXIT_INVALID}, {ENOENT, EXIT_INVALID},   {ENOSYS, EXIT_INVALID},
                {ENOSPC, EXIT_STORAGE}, {EBADMSG, EXIT_STORAGE},  {ECANCELED, EXIT_CANCELED},
                {EBUSY, EXIT_BUSY},     {ESTALE, EXIT_BUSY},
        };
        int err = proto_code_to_errno(code);

        for (size_t i = 0; i < ELEMENTSOF(table); i++)
                if (table[i].err == err)
                        return table[i].exit;
        return EXIT_PROTOCOL;
}

/* Prints why a call of method failed and returns the exit code. */
int cmd_call_failed(struct out *o, const char *method, int r, const struct conn_error *e)
{
        if (r == -EREMOTEIO) {
                o->rpc_code = e->code;
                out_error(o, method, "%s", e->message);
                return cmd_exit_for_code(e->code);
        }
        if (r == -ETIMEDOUT)
                out_error(o, method, "timed out waiting for the reply");
        else if (r == -ECONNRESET)
                out_error(o, method, "connection closed by goniod");
        else if (e->message[0])
                out_error(o, method, "%s", e->message);
        else
                out_error(o, method, "%s", strerror(-r));
        return EXIT_PROTOCOL;
}

static void on_progress(const char *method, json_t *params, void *userdata)
{
        out_progress(userdata, method, params);
}

static void on_watch(const char *method, json_t *params, void *userdata)
{
        out_notification(userdata, method, params);
}

static int64_t deadline_after(double timeout_s)
{
        return conn_now_ms() + (int64_t)(timeout_s * 1000);
}

/* cmd_connect to the admin socket: $GONIO_ADMIN_SOCKET, else admin.sock beside the control
 * socket (--socket or the default path), as goniod places it. */
static int admin_connect(const struct args *a, struct out *o, struct conn **ret)
{
        char ctl[108], path[108];
        const char *env = getenv("GONIO_ADMIN_SOCKET"), *slash;
        struct args b = *a;

        if (env && *env)
                snprintf(path, sizeof(path), "%s", env);
        else {
                if (a->socket)
                        snprintf(ctl, sizeof(ctl), "%s", a->socket);
                else
                        (void)proto_socket_path(ctl, sizeof(ctl));
                slash = strrchr(ctl, '/');
                snprintf(path, sizeof(path), "%.*sadmin.sock", slash ? (int)(slash - ctl + 1) : 0,
                         ctl);
        }
        b.socket = path;
        return cmd_connect(&b, o, ret);
}

int cmd_connect(const struct args *a, struct out *o, struct conn **ret)
{
        char path[108];
        struct conn_error e;
        json_t *res = NULL, *params;
        int64_t deadline = deadline_after(a->timeout_s > 0 ? a->timeout_s : TIMEOUT_S);
        int r, proto;

        if (a->socket)
                r = snprintf(path, sizeof(path), "%s", a->socket) >= (int)sizeof(path)
                            ? -ENAMETOOLONG
                            : 0;
        else
                r = proto_socket_path(path, sizeof(path));
        if (r >= 0)
                r = conn_open(path, deadline, ret);
        if (r < 0) {
                out_error(o, "connect", "%s: %s", path, strerror(-r));
                return EXIT_CONNECT;
        }
        params = json_pack("{s:s,s:i}", "client", "gonioctl/" GONIO_VERSION, "protocol",
                           PROTO_VERSION);
        r = conn_call(*ret, "hello", params, deadline, -1, NULL, NULL, &res, &e);
        if (r < 0)
                return cmd_call_failed(o, "hello", r, &e);
        proto = (int)json_integer_value(json_object_get(res, "protocol"));
        json_decref(res);
        if (proto != PROTO_VERSION) {
                out_error(o, "hello", "goniod speaks protocol %d, gonioctl speaks %d", proto,
                          PROTO_VERSION);
                return EXIT_PROTOCOL;
        }
        return EXIT_OK;
}

/* The write end of the pipe cmd_intr_fd() returned last: what its signal handler writes to. */
static int intr_pipe_w = -1;

static void on_intr_signal(int sig)
{
        int saved = errno;
        unsigned char b = (unsigned char)sig;

        (void)!write(intr_pipe_w, &b, 1);
        errno = saved;
}

/* A handler, not a blocked mask and a signalfd: a mask is per thread, and a library may have
 * started threads before main() (OpenBLAS under OpenCV does), so a blocked signal would still
 * reach one of those and kill gonioctl by its default action. */
int cmd_intr_fd(void)
{
        struct sigaction sa = {.sa_handler = on_intr_signal, .sa_flags = SA_RESTART};
        int p[2];

        if (pipe2(p, O_CLOEXEC | O_NONBLOCK) < 0)
                return -errno;
        if (intr_pipe_w >= 0)
                close(intr_pipe_w);
        intr_pipe_w = p[1];
        sigemptyset(&sa.sa_mask);
        if (sigaction(SIGINT, &sa, NULL) < 0 || sigaction(SIGTERM, &sa, NULL) < 0) {
                int r = -errno;

                close(p[0]);
                return r;
        }
        return p[0];
}

/* Prints notifications until SIGINT/SIGTERM, --count N, or --timeout. */
static int run_watch(const struct args *a, struct out *o, struct conn *conn)
{
        int64_t deadline = a->timeout_s > 0 ? deadline_after(a->timeout_s) : CONN_NO_DEADLINE;
        _cleanup_close_ int sfd = cmd_intr_fd();
        struct conn_error e;
        long n = 0;

        if (sfd < 0) {
                out_error(o, "watch", "catching signals: %s", strerror(-sfd));
                return EXIT_PROTOCOL;
        }
        for (;;) {
                int r = conn_wait_notification(conn, deadline, sfd, on_watch, o, &e);

                if (r == -EINTR || r == -ETIMEDOUT)
                        return EXIT_OK;
                if (r < 0)
                        return cmd_call_failed(o, "watch", r, &e);
                if (a->count > 0 && ++n >= a->count)
                        return EXIT_OK;
        }
}

/* What ended a wait for motion. */
struct interruption {
        const char *code; /* "SIGINT", "SIGTERM" or "timeout" */
        char text[64];    /* for people: "Ctrl-C", "no reply within 0.5 s" */
};

/* r is -EINTR (a signal, read from sfd) or -ETIMEDOUT (after timeout_s). */
static void read_interruption(int sfd, int r, double timeout_s, struct interruption *why)
{
        unsigned char sig = 0;

        if (r == -ETIMEDOUT) {
                why->code = "timeout";
                snprintf(why->text, sizeof(why->text), "no reply within %g s", timeout_s);
        } else if (read(sfd, &sig, 1) == 1 && sig == SIGTERM) {
                why->code = "SIGTERM";
                snprintf(why->text, sizeof(why->text), "SIGTERM");
        } else {
                why->code = "SIGINT";
                snprintf(why->text, sizeof(why->text), "Ctrl-C");
        }
}

/* Appends "NAME at POS" to f and {axis, position} to list, the position from a status
 * result (NULL when unknown). */
static void report_axis(FILE *f, json_t *list, json_t *status, const char *name)
{
        json_t *ax, *pos = NULL;
        size_t i;

        if (!name)
                return;
        json_array_foreach(json_object_get(status, "axes"), i,
                           ax) if (strcmp(json_string_value(json_object_get(ax, "name")) ?: "",
                                          name) == 0) pos = json_object_get(ax, "position");
        fprintf(f, "%s%s at ", ftell(f) > 0 ? ", " : "", name);
        if (json_is_number(pos))
                fprintf(f, "%.3f", json_number_value(pos));
        else
                fputs("an unknown position", f);
        json_array_append_new(list, json_pack("{s:s,s:O?}", "axis", name, "position", pos));
}

/* Says where the axes of the interrupted request (params: "axis", or "axes", else all
 * axes of status) stopped: on stderr, and with --json as an error object on stdout. */
static void report_stopped(struct out *o, const char *method, json_t *params, json_t *status,
                           const struct interruption *why)
{
        const char *axis = json_string_value(json_object_get(params, "axis"));
        json_t *axes = json_object_get(params, "axes"), *ax, *list = json_array(), *j;
        _cleanup_free_ char *names = NULL, *msg = NULL;
        size_t len = 0, i;
        FILE *f = open_memstream(&names, &len);

        if (!f || !list) {
                out_error(o, method, "interrupted (%s): stopped every axis", why->text);
                if (f)
                        fclose(f);
                json_decref(list);
                return;
        }
        if (axis)
                report_axis(f, list, status, axis);
        json_array_foreach(axis ? NULL : axes ?: json_object_get(status, "axes"), i, ax)
                report_axis(f, list, status,
                            json_string_value(axes ? ax : json_object_get(ax, "name")));
        fclose(f);
        if (asprintf(&msg, "interrupted: stopped %s (%s; stop halts every axis of the rig)",
                     names[0] ? names : "the rig", why->text) < 0)
                msg = NULL;
        out_error(o, method, "%s", msg ?: "interrupted: stopped the rig");
        j = json_pack("{s:{s:s,s:s?,s:s,s:o}}", "error", "code", "interrupted", "message", msg,
                      "cause", why->code, "stopped", list);
        if (o->json && j) {
                out_result(o, NULL, NULL, j);
                o->error_printed = true;
        }
        json_decref(j);
}

/* After a wait for motion was interrupted, sends stop (the protocol has no per-axis stop:
 * it halts every axis), then reads where the axes stopped. Returns EXIT_INTERRUPTED, or
 * EXIT_PROTOCOL when goniod did not confirm the stop (the axes may still move). */
static int stop_interrupted(struct out *o, struct conn *conn, const char *method, json_t *params,
                            const struct interruption *why)
{
        int64_t deadline = deadline_after(STOP_WAIT_S);
        json_t *res = NULL, *status = NULL;
        struct conn_error e;
        int r = conn_call(conn, "stop", json_object(), deadline, -1, NULL, NULL, &res, &e);

        if (r < 0) {
                out_error(o, method,
                          "interrupted (%s), but stop failed: %s; the axes may still be moving",
                          why->text,
                          r == -ETIMEDOUT ? "no reply"
                          : e.message[0]  ? e.message
                                          : strerror(-r));
                return EXIT_PROTOCOL;
        }
        json_decref(res);
        if (conn_call(conn, "status", json_object(), deadline, -1, NULL, NULL, &status, &e) < 0)
                status = NULL;
        report_stopped(o, method, params, status, why);
        json_decref(status);
        return EXIT_INTERRUPTED;
}

static int run_method(const struct cmd *c, const struct args *a, struct out *o, struct conn *conn,
                      const char *method, json_t *params)
{
        double timeout_s = a->timeout_s > 0 ? a->timeout_s : c->timeout_s;
        bool stops = (c->stops && !(a->given & ARG_NO_WAIT)) || c->follows;
        /* a hold catches signals before its request: one that comes meanwhile ends the hold */
        _cleanup_close_ int sfd = stops || c->holds ? cmd_intr_fd() : -EBADF;
        _cleanup_(json_decrefp) json_t *sent = json_incref(params);
        struct interruption why;
        struct conn_error e;
        json_t *res = NULL;
        int r;

        r = conn_call(conn, method, params, deadline_after(timeout_s), stops ? sfd : -1,
                      on_progress, o, &res, &e);
        if (stops && (r == -EINTR || r == -ETIMEDOUT)) {
                read_interruption(sfd, r, timeout_s, &why);
                return stop_interrupted(o, conn, method, sent, &why);
        }
        if (r < 0)
                return cmd_call_failed(o, method, r, &e);
        if (c->follows) {
                if (o->json)
                        out_notification(o, "session.state", res);
                r = csession_follow(o, conn, sfd, res);
                json_decref(res);
                return r;
        }
        out_result(o, c->print, c->done, res);
        r = c->holds ? hold_switch(a, o, conn, method, sent, res, sfd) : EXIT_OK;
        json_decref(res);
        return r;
}

/* Runs a command that needs no goniod and prints its result. */
static int run_local(const struct cmd *c, const struct args *a, struct out *o, json_t *params)
{
        json_t *res = NULL;
        int r = c->local(a, o, &res);

        json_decref(params);
        if (r != EXIT_OK) {
                json_decref(res);
                return r;
        }
        out_result(o, c->print, c->done, res);
        json_decref(res);
        return EXIT_OK;
}

static int run_command(const struct args *a, struct out *o)
{
        _cleanup_(conn_freep) struct conn *conn = NULL;
        const struct cmd *c;
        json_t *params = NULL;
        int used, r;

        if (a->nwords == 0) {
                args_usage_error("usage", "missing command");
                return EXIT_USAGE;
        }
        c = find_cmd(a->words, a->nwords, &used);
        if (!c)
                return EXIT_USAGE;
        r = build_params(c, a, a->words + used, a->nwords - used, &params);
        if (r < 0) {
                json_decref(params);
                return r == -EINVAL ? EXIT_USAGE : EXIT_PROTOCOL;
        }
        if (c->local)
                return run_local(c, a, o, params);
        r = c->admin ? admin_connect(a, o, &conn) : cmd_connect(a, o, &conn);
        if (r != EXIT_OK) {
                json_decref(params);
                return r;
        }
        if (c->run) {
                json_decref(params);
                return c->run(a, o, conn);
        }
        return run_method(c, a, o, conn, c->method ?: a->words[used], params);
}

/* Prints the error object of a failed command (--json) and returns code: its "code" names
 * the exit code; its message is the first one printed, else this table's. */
static int failed(struct out *o, int code)
{
        static const struct {
                const char *name, *text;
        } exits[] = {
                [EXIT_USAGE] = {"usage", "usage error"},
                [EXIT_CONNECT] = {"connect", "cannot connect to goniod"},
                [EXIT_PROTOCOL] = {"protocol", "protocol error"},
                [EXIT_DEVICE] = {"device", "device fault"},
                [EXIT_INVALID] = {"invalid", "invalid request or input"},
                [EXIT_STORAGE] = {"storage", "storage error"},
                [EXIT_CANCELED] = {"canceled", "canceled"},
                [EXIT_BUSY] = {"busy", "busy or wrong state"},
                [EXIT_INTERRUPTED] = {"interrupted", "interrupted"},
        };
        bool known = code > 0 && code < (int)ELEMENTSOF(exits) && exits[code].name;

        if (code != EXIT_OK)
                out_error_object(o, known ? exits[code].name : "error", code,
                                 args_last_error()
                                         ?: known ? exits[code].text
                                                  : "failed");
        out_done(o);
        return code;
}

int cmd_run(const struct args *a)
{
        struct out o;

        out_init(&o, a->json, a->quiet);
        return failed(&o, run_command(a, &o));
}

int cmd_usage_failed(const struct args *a)
{
        struct out o;

        out_init(&o, a->json, a->quiet);
        return failed(&o, EXIT_USAGE);
}

int cmd_help(const struct args *a)
{
        const struct cmd *c;
        int used;

        if (a->nwords == 0) {
                cmd_usage(stdout);
                return EXIT_OK;
        }
        if (a->nwords == 1 && group_help(stdout, a->words[0]))
                return EXIT_OK;
        c = find_cmd(a->words, a->nwords, &used);
        if (!c)
                return cmd_usage_failed(a);
        command_help(stdout, c);
        return EXIT_OK;
}
