/* output.c - gonioctl's output: compact JSON for --json, aligned tables for people,
 * a progress line on a terminal, watch lines and error messages. The human printers
 * tolerate missing members (shown as "-"), so a newer server never crashes them. */
#include <assert.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "client/output.h"
#include "common/cleanup.h"

#define PROGRESS_COLS  79
#define TABLE_MAX_COLS 16

/* Cells added row by row, printed with each column padded to its widest cell. */
struct table {
        size_t ncols;
        const char *align; /* 'l' or 'r' per column */
        char **cells;
        size_t n, cap;
};

static void table_addf(struct table *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void table_addf(struct table *t, const char *fmt, ...)
{
        char *s = NULL;
        va_list ap;

        if (t->n == t->cap) {
                size_t cap = MAX(t->cap * 2, (size_t)32);
                char **c = realloc(t->cells, cap * sizeof(char *));

                if (!c)
                        return; /* out of memory: the cell is lost, the table stays valid */
                t->cells = c;
                t->cap = cap;
        }
        va_start(ap, fmt);
        if (vasprintf(&s, fmt, ap) < 0)
                s = NULL;
        va_end(ap);
        t->cells[t->n++] = s;
}

/* Adds literal cells: a NULL-terminated list of strings. */
static void table_cells(struct table *t, ...) __attribute__((sentinel));

static void table_cells(struct table *t, ...)
{
        const char *c;
        va_list ap;

        va_start(ap, t);
        while ((c = va_arg(ap, const char *)))
                table_addf(t, "%s", c);
        va_end(ap);
}

/* Prints and frees the table; rows that are incomplete (after ENOMEM) are dropped. */
static void table_print(struct table *t)
{
        size_t width[TABLE_MAX_COLS] = {}, rows = t->n / t->ncols;

        assert(t->ncols <= TABLE_MAX_COLS);

        for (size_t i = 0; i < rows * t->ncols; i++) {
                size_t len = t->cells[i] ? strlen(t->cells[i]) : 0;

                width[i % t->ncols] = MAX(width[i % t->ncols], len);
        }
        for (size_t r = 0; r < rows; r++) {
                for (size_t c = 0; c < t->ncols; c++) {
                        const char *s = t->cells[r * t->ncols + c] ?: "";
                        bool last = c + 1 == t->ncols;
                        int w = last && t->align[c] == 'l' ? 0 : (int)width[c];

                        printf(t->align[c] == 'r' ? "%*s%s" : "%-*s%s", w, s, last ? "\n" : "  ");
                }
        }
        for (size_t i = 0; i < t->n; i++)
                free(t->cells[i]);
        free(t->cells);
}

static const char *str_or_dash(json_t *v)
{
        return json_is_string(v) && json_string_length(v) > 0 ? json_string_value(v) : "-";
}

static const char *get_str(json_t *o, const char *key)
{
        return str_or_dash(json_object_get(o, key));
}

/* A position with 3 decimals, or "-". */
static void cell_pos(struct table *t, json_t *v)
{
        if (json_is_number(v))
                table_addf(t, "%.3f", json_number_value(v));
        else
                table_addf(t, "-");
}

static void cell_bool(struct table *t, json_t *v, const char *yes, const char *no)
{
        table_addf(t, "%s", json_is_boolean(v) ? (json_is_true(v) ? yes : no) : "-");
}

/* Names of an array of strings or of objects with "name", or a plain string, joined. */
static void cell_names(struct table *t, json_t *v, const char *empty)
{
        _cleanup_free_ char *s = NULL;
        size_t len = 0, i;
        FILE *f;
        json_t *e;

        if (!json_is_array(v) || json_array_size(v) == 0) {
                table_addf(t, "%s", json_is_string(v) ? str_or_dash(v) : empty);
                return;
        }
        f = open_memstream(&s, &len);
        if (!f) {
                table_addf(t, "?");
                return;
        }
        json_array_foreach(v, i, e) fprintf(
                f, "%s%s", i ? "," : "", json_is_object(e) ? get_str(e, "name") : str_or_dash(e));
        fclose(f);
        table_addf(t, "%s", s);
}

void out_init(struct out *o, bool json, bool quiet)
{
        *o = (struct out){.json = json, .quiet = quiet};
        o->progress = !json && !quiet && isatty(STDERR_FILENO);
}

void out_progress_end(struct out *o)
{
        if (!o->progress_shown)
                return;
        fputs("\r\033[K", stderr);
        o->progress_shown = false;
}

void out_result(struct out *o, out_print_fn human, const char *text, json_t *result)
{
        out_progress_end(o);
        if (o->quiet)
                return;
        if (o->json) {
                _cleanup_free_ char *s = json_dumps(result, JSON_COMPACT | JSON_ENCODE_ANY);

                printf("%s\n", s ?: "null");
        } else if (human)
                human(result);
        else if (text)
                printf("%s\n", text);
        fflush(stdout);
}

void out_error(struct out *o, const char *what, const char *fmt, ...)
{
        char msg[sizeof(o->error)];
        va_list ap;

        out_progress_end(o);
        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        if (what)
                fprintf(stderr, "gonioctl: %s: %s\n", what, msg);
        else
                fprintf(stderr, "%s\n", msg);
        if (!o->error[0])
                snprintf(o->error, sizeof(o->error), "%s%s%s", what ?: "", what ? ": " : "", msg);
}

void out_error_object(struct out *o, const char *code, int exit_code, const char *fallback)
{
        const char *msg = o->error[0] ? o->error : fallback;
        json_t *e, *j;

        if (!o->json || o->error_printed)
                return;
        e = json_pack("{s:s,s:i,s:s?}", "code", code, "exit", exit_code, "message", msg);
        if (e && o->rpc_code)
                json_object_set_new(e, "rpc_code", json_integer(o->rpc_code));
        if (e && o->error_detail)
                json_object_update_missing(e, o->error_detail);
        j = e ? json_pack("{s:o}", "error", e) : NULL;
        if (j) {
                bool quiet = o->quiet;

                o->quiet = false; /* --quiet silences results, not errors */
                out_result(o, NULL, NULL, j);
                o->quiet = quiet;
        }
        json_decref(j);
        o->error_printed = true;
}

void out_done(struct out *o)
{
        json_decref(o->error_detail);
        o->error_detail = NULL;
}

/* "method key=value ..." with reals to 3 decimals, into f. */
static void format_notification(FILE *f, const char *method, json_t *params)
{
        const char *key;
        json_t *v;

        fputs(method, f);
        json_object_foreach(params, key, v)
        {
                _cleanup_free_ char *s = NULL;

                if (json_is_string(v))
                        fprintf(f, " %s=%s", key, json_string_value(v));
                else if (json_is_real(v))
                        fprintf(f, " %s=%.3f", key, json_real_value(v));
                else if ((s = json_dumps(v, JSON_COMPACT | JSON_ENCODE_ANY)))
                        fprintf(f, " %s=%s", key, s);
        }
}

void out_progress(struct out *o, const char *method, json_t *params)
{
        char line[PROGRESS_COLS + 1] = "";
        FILE *f;

        if (!o->progress)
                return;
        f = fmemopen(line, sizeof(line), "w");
        if (!f)
                return;
        setbuf(f, NULL);
        format_notification(f, method, params);
        fclose(f);
        line[PROGRESS_COLS] = '\0';
        fprintf(stderr, "\r\033[K%s", line);
        o->progress_shown = true;
}

void out_notification(struct out *o, const char *method, json_t *params)
{
        if (o->quiet)
                return;
        if (o->json) {
                json_t *m = json_pack("{s:s,s:O?}", "method", method, "params", params);
                _cleanup_free_ char *s = m ? json_dumps(m, JSON_COMPACT) : NULL;

                json_decref(m);
                if (s)
                        printf("%s\n", s);
        } else {
                struct timespec ts;
                struct tm tm;
                char when[16];

                clock_gettime(CLOCK_REALTIME, &ts);
                localtime_r(&ts.tv_sec, &tm);
                strftime(when, sizeof(when), "%H:%M:%S", &tm);
                printf("%s.%03ld ", when, ts.tv_nsec / 1000000);
                format_notification(stdout, method, params);
                putchar('\n');
        }
        fflush(stdout);
}

/* Key/value lines, aligned. */
static void kv(struct table *t, const char *key, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

static void kv(struct table *t, const char *key, const char *fmt, ...)
{
        char buf[1024];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(buf, sizeof(buf), fmt, ap);
        va_end(ap);
        table_addf(t, "%s", key);
        table_addf(t, "%s", buf);
}

static void print_axes(json_t *axes)
{
        struct table t = {.ncols = 6, .align = "lrllll"};
        size_t i;
        json_t *a;

        table_cells(&t, "AXIS", "POSITION", "MOVING", "HOMED", "FAULT", "LIMITS", NULL);
        json_array_foreach(axes, i, a)
        {
                json_t *lo = json_object_get(a, "min"), *hi = json_object_get(a, "max");

                table_addf(&t, "%s", get_str(a, "name"));
                cell_pos(&t, json_object_get(a, "position"));
                cell_bool(&t, json_object_get(a, "moving"), "yes", "no");
                cell_bool(&t, json_object_get(a, "homed"), "yes", "no");
                if (json_is_string(json_object_get(a, "fault")))
                        table_addf(&t, "%s", get_str(a, "fault"));
                else
                        cell_bool(&t, json_object_get(a, "fault"), "yes", "no");
                if (json_is_true(json_object_get(a, "continuous")))
                        table_addf(&t, "continuous");
                else if (json_is_number(lo) && json_is_number(hi))
                        table_addf(&t, "%.3f .. %.3f", json_number_value(lo),
                                   json_number_value(hi));
                else
                        table_addf(&t, "-");
        }
        table_print(&t);
}

static void print_lamps(json_t *lamps)
{
        struct table t = {.ncols = 2, .align = "ll"};
        size_t i;
        json_t *l;

        table_cells(&t, "LAMP", "STATE", NULL);
        json_array_foreach(lamps, i, l)
        {
                table_addf(&t, "%s", get_str(l, "name"));
                cell_bool(&t, json_object_get(l, "on"), "on", "off");
        }
        table_print(&t);
}

static void print_cameras(json_t *cams)
{
        struct table t = {.ncols = 3, .align = "lrr"};
        size_t i;
        json_t *c;

        table_cells(&t, "CAMERA", "SIZE", "BITS", NULL);
        json_array_foreach(cams, i, c)
        {
                table_addf(&t, "%s", get_str(c, "name"));
                table_addf(&t, "%lldx%lld", json_integer_value(json_object_get(c, "width")),
                           json_integer_value(json_object_get(c, "height")));
                table_addf(&t, "%lld", json_integer_value(json_object_get(c, "bits")));
        }
        table_print(&t);
}

/* Prints a non-empty array with fn, preceded by an empty line. */
static void section(json_t *arr, void (*fn)(json_t *))
{
        if (json_array_size(arr) == 0)
                return;
        putchar('\n');
        fn(arr);
}

void out_print_status(json_t *r)
{
        json_t *fault = json_object_get(r, "fault"), *ds = json_object_get(r, "dataset");
        json_t *lasers = json_object_get(r, "lasers"), *l;
        size_t i;
        struct table t = {.ncols = 2, .align = "ll"};

        kv(&t, "state", "%s", get_str(r, "state"));
        kv(&t, "homed", "%s", json_is_true(json_object_get(r, "homed")) ? "yes" : "no");
        if (json_is_object(fault))
                kv(&t, "fault", "%s: %s", get_str(fault, "device"), get_str(fault, "message"));
        else
                kv(&t, "fault", "-");
        if (json_is_object(ds))
                kv(&t, "dataset", "%s (%lld captures) %s", get_str(ds, "name"),
                   json_integer_value(json_object_get(ds, "count")), get_str(ds, "path"));
        else
                kv(&t, "dataset", "-");
        json_array_foreach(lasers, i, l) kv(&t, "laser", "%s %s", get_str(l, "name"),
                                            json_is_true(json_object_get(l, "on")) ? "on" : "off");
        if (json_array_size(lasers) == 0)
                kv(&t, "laser", "-");
        table_print(&t);
        section(json_object_get(r, "axes"), print_axes);
        section(json_object_get(r, "lamps"), print_lamps);
        section(json_object_get(r, "cameras"), print_cameras);
}

/* One option of a device: name, access, unit, range (none when min == max == 0). */
static void describe_option(struct table *t, json_t *opt)
{
        bool get = json_is_true(json_object_get(opt, "get"));
        bool set = json_is_true(json_object_get(opt, "set"));
        double lo = json_number_value(json_object_get(opt, "min"));
        double hi = json_number_value(json_object_get(opt, "max"));

        table_addf(t, "%s", get_str(opt, "name"));
        table_addf(t, "%s", get && set ? "get,set" : get ? "get" : set ? "set" : "-");
        table_addf(t, "%s", get_str(opt, "unit"));
        if (lo != 0 || hi != 0)
                table_addf(t, "%g .. %g", lo, hi);
        else
                table_addf(t, "-");
}

/* One row per device found: family, path, and what identifies it. */
static long long get_int(json_t *o, const char *key)
{
        return (long long)json_integer_value(json_object_get(o, key));
}

/* What one discovered device is: a relay board, a USB device, a card name or a driver. */
static void device_what(struct table *t, json_t *d)
{
        const char *label = json_string_value(json_object_get(d, "label"));
        const char *usb = json_string_value(json_object_get(d, "usb"));

        if (json_object_get(d, "relays"))
                table_addf(t, "%s %s, HID relay board, %lld relays", get_str(d, "id"),
                           get_str(d, "product"), get_int(d, "relays"));
        else if (json_object_get(d, "id"))
                table_addf(t, "%s %s %s", get_str(d, "id"), get_str(d, "manufacturer"),
                           get_str(d, "product"));
        else if (json_object_get(d, "name"))
                table_addf(t, "%s", get_str(d, "name"));
        else
                table_addf(t, "%s%s%s%s%s", get_str(d, "driver"), label ? " " : "",
                           label ? label : "", usb ? " usb " : "", usb ? usb : "");
}

#define SIZES_LISTED 8 /* more sizes than this and a range: the range is shown */

/* The sizes of a format: "640x480 1280x720", or its range "16x16-1920x1080" (with the number
 * of sizes it lists, if any) where there is no list or a long one. */
static void cell_sizes(struct table *t, json_t *fmt)
{
        json_t *sizes = json_object_get(fmt, "sizes"), *r = json_object_get(fmt, "range"), *e;
        size_t n = json_array_size(sizes), len = 0, i;
        _cleanup_free_ char *s = NULL;
        FILE *f = open_memstream(&s, &len);

        if (!f) {
                table_addf(t, "?");
                return;
        }
        if (json_is_object(r) && (n == 0 || n > SIZES_LISTED)) {
                fprintf(f, "%lldx%lld-%lldx%lld", get_int(r, "min_width"), get_int(r, "min_height"),
                        get_int(r, "max_width"), get_int(r, "max_height"));
                if (n)
                        fprintf(f, " (%zu sizes)", n);
        } else {
                json_array_foreach(sizes, i, e)
                {
                        fprintf(f, "%s%lldx%lld", i ? " " : "", get_int(e, "width"),
                                get_int(e, "height"));
                }
        }
        fclose(f);
        table_addf(t, "%s", len ? s : "-");
}

/* "WHO formats:" and a table of the formats (V4L2's description or libcamera's name). */
static void print_formats(const char *who, json_t *formats)
{
        struct table t = {.ncols = 3, .align = "lll"};
        size_t i;
        json_t *f;

        printf("\n%s formats:\n", who);
        table_cells(&t, "FOURCC", "DESCRIPTION", "SIZES", NULL);
        json_array_foreach(formats, i, f)
        {
                table_addf(&t, "%s", get_str(f, "fourcc"));
                table_addf(&t, "%s",
                           get_str(f, json_object_get(f, "name") ? "name" : "description"));
                cell_sizes(&t, f);
        }
        table_print(&t);
}

static void print_controls(const char *who, json_t *controls)
{
        struct table t = {.ncols = 6, .align = "llrrrr"};
        size_t i;
        json_t *c;

        printf("\n%s controls:\n", who);
        table_cells(&t, "CONTROL", "TYPE", "MIN", "MAX", "STEP", "DEFAULT", NULL);
        json_array_foreach(controls, i, c)
        {
                table_cells(&t, get_str(c, "name"), get_str(c, "type"), NULL);
                table_addf(&t, "%lld", get_int(c, "min"));
                table_addf(&t, "%lld", get_int(c, "max"));
                table_addf(&t, "%lld", get_int(c, "step"));
                table_addf(&t, "%lld", get_int(c, "default"));
        }
        table_print(&t);
}

static void print_lines(const char *who, json_t *lines)
{
        struct table t = {.ncols = 5, .align = "rllll"};
        size_t i;
        json_t *l;

        printf("\n%s lines:\n", who);
        table_cells(&t, "LINE", "NAME", "CONSUMER", "DIRECTION", "USED", NULL);
        json_array_foreach(lines, i, l)
        {
                table_addf(&t, "%lld", get_int(l, "offset"));
                table_cells(&t, get_str(l, "name"), get_str(l, "consumer"), get_str(l, "direction"),
                            NULL);
                cell_bool(&t, json_object_get(l, "used"), "used", "free");
        }
        table_print(&t);
}

/* Why a node could not be asked for its details, when it could not. */
static void print_node_error(json_t *d)
{
        if (json_is_string(json_object_get(d, "error")))
                printf("\n%s: cannot query: %s\n", get_str(d, "path"), get_str(d, "error"));
}

/* The details of each device that has them: formats, controls, lines. */
static void print_device_details(json_t *r)
{
        size_t i;
        json_t *d;

        json_array_foreach(json_object_get(r, "v4l2"), i, d)
        {
                print_node_error(d);
                if (json_array_size(json_object_get(d, "formats")))
                        print_formats(get_str(d, "path"), json_object_get(d, "formats"));
                if (json_array_size(json_object_get(d, "controls")))
                        print_controls(get_str(d, "path"), json_object_get(d, "controls"));
        }
        json_array_foreach(json_object_get(r, "gpio"), i, d)
        {
                print_node_error(d);
                if (json_array_size(json_object_get(d, "lines")))
                        print_lines(get_str(d, "path"), json_object_get(d, "lines"));
        }
        json_array_foreach(json_object_get(r, "libcamera"), i, d)
        {
                if (json_array_size(json_object_get(d, "formats")))
                        print_formats(get_str(d, "id"), json_object_get(d, "formats"));
        }
}

void out_print_devices(json_t *r)
{
        static const char *const families[] = {"serial", "v4l2", "gpio", "usb", "libcamera"};
        struct table t = {.ncols = 3, .align = "lll"};
        json_t *d;
        size_t i;

        table_cells(&t, "KIND", "PATH", "WHAT", NULL);
        for (size_t f = 0; f < ELEMENTSOF(families); f++)
                json_array_foreach(json_object_get(r, families[f]), i, d)
                {
                        table_addf(&t, "%s", families[f]);
                        table_addf(&t, "%s",
                                   get_str(d, json_object_get(d, "path")       ? "path"
                                              : json_object_get(d, "bus_path") ? "bus_path"
                                                                               : "id"));
                        if (json_object_get(d, "model")) /* a libcamera camera */
                                table_addf(&t, "%s", get_str(d, "model"));
                        else
                                device_what(&t, d);
                }
        table_print(&t);
        if (json_is_string(json_object_get(r, "libcamera_error")))
                printf("libcamera: %s\n", get_str(r, "libcamera_error"));
        print_device_details(r);
}

void out_print_describe(json_t *r)
{
        struct table t = {.ncols = 7, .align = "lllllll"};
        size_t i, k;
        json_t *d, *opt;

        table_cells(&t, "DEVICE", "CLASS", "BACKEND", "OPTION", "ACCESS", "UNIT", "RANGE", NULL);
        json_array_foreach(json_object_get(r, "devices"), i, d)
        {
                json_t *opts = json_object_get(d, "options");

                table_addf(&t, "%s", get_str(d, "name"));
                table_addf(&t, "%s", get_str(d, "class"));
                table_addf(&t, "%s", get_str(d, "backend"));
                if (json_array_size(opts) == 0)
                        table_cells(&t, "-", "-", "-", "-", NULL);
                json_array_foreach(opts, k, opt)
                {
                        if (k > 0)
                                table_cells(&t, "", "", "", NULL);
                        describe_option(&t, opt);
                }
        }
        table_print(&t);
}

void out_print_home(json_t *r)
{
        struct table t = {.ncols = 2, .align = "lr"};
        size_t i;
        json_t *a;

        table_cells(&t, "AXIS", "POSITION", NULL);
        json_array_foreach(json_object_get(r, "axes"), i, a)
        {
                table_addf(&t, "%s", get_str(a, "name"));
                cell_pos(&t, json_object_get(a, "position"));
        }
        table_print(&t);
}

void out_print_move(json_t *r)
{
        json_t *target = json_object_get(r, "target");

        if (json_is_number(target))
                printf("%s moving to %.3f\n", get_str(r, "axis"), json_number_value(target));
        else if (json_is_array(json_object_get(r, "axes")))
                out_print_home(r); /* {axes: [{name, position}]}, as home answers */
        else
                printf("%s %.3f\n", get_str(r, "axis"),
                       json_number_value(json_object_get(r, "position")));
}

void out_print_stop(json_t *r)
{
        struct table t = {.ncols = 2, .align = "ll"};

        table_addf(&t, "stopped");
        cell_names(&t, json_object_get(r, "stopped"), "nothing was moving");
        table_print(&t);
}

static void print_switch(json_t *r, const char *key)
{
        printf("%s %s\n", get_str(r, key), json_is_true(json_object_get(r, "on")) ? "on" : "off");
}

void out_print_lamp(json_t *r)
{
        print_switch(r, "lamp");
}

void out_print_laser(json_t *r)
{
        print_switch(r, "laser");
}

/* The captures table shared by capture and dataset info. */
static void print_captures(json_t *caps)
{
        struct table t = {.ncols = 10, .align = "rlrrrllrll"};
        size_t i;
        json_t *c;

        table_cells(&t, "ID", "CAMERA", "TURNTABLE", "LIGHT_ARM", "CAMERA_ARM", "LAMPS", "LASER",
                    "SIZE", "PIXFMT", "FILE", NULL);
        json_array_foreach(caps, i, c)
        {
                table_addf(&t, "%lld", json_integer_value(json_object_get(c, "id")));
                table_addf(&t, "%s", get_str(c, "camera"));
                cell_pos(&t, json_object_get(c, "turntable"));
                cell_pos(&t, json_object_get(c, "light_arm"));
                cell_pos(&t, json_object_get(c, "camera_arm"));
                cell_names(&t, json_object_get(c, "lamps"), "-");
                cell_bool(&t, json_object_get(c, "laser"), "on", "off");
                table_addf(&t, "%lldx%lld", json_integer_value(json_object_get(c, "width")),
                           json_integer_value(json_object_get(c, "height")));
                table_addf(&t, "%s", get_str(c, "pixfmt"));
                table_addf(&t, "%s", get_str(c, "file"));
        }
        table_print(&t);
}

void out_print_capture(json_t *r)
{
        print_captures(json_object_get(r, "captures"));
}

void out_print_dataset(json_t *r)
{
        printf("dataset %s: %lld captures in %s\n", get_str(r, "name"),
               json_integer_value(json_object_get(r, "count")), get_str(r, "path"));
}

void out_print_dataset_list(json_t *r)
{
        struct table t = {.ncols = 4, .align = "lrll"};
        size_t i;
        json_t *d;

        table_cells(&t, "NAME", "COUNT", "CREATED", "PATH", NULL);
        json_array_foreach(json_object_get(r, "datasets"), i, d)
        {
                table_addf(&t, "%s", get_str(d, "name"));
                table_addf(&t, "%lld", json_integer_value(json_object_get(d, "count")));
                table_addf(&t, "%s", get_str(d, "created"));
                table_addf(&t, "%s", get_str(d, "path"));
        }
        table_print(&t);
}

void out_print_dataset_info(json_t *r)
{
        struct table t = {.ncols = 2, .align = "ll"};

        kv(&t, "name", "%s", get_str(r, "name"));
        kv(&t, "path", "%s", get_str(r, "path"));
        kv(&t, "created", "%s", get_str(r, "created"));
        kv(&t, "count", "%lld", json_integer_value(json_object_get(r, "count")));
        kv(&t, "rig", "%s", get_str(r, "rig"));
        table_addf(&t, "cameras");
        cell_names(&t, json_object_get(r, "cameras"), "-");
        table_print(&t);
        section(json_object_get(r, "captures"), print_captures);
}

void out_print_pretty(json_t *r)
{
        _cleanup_free_ char *s = json_dumps(r, JSON_INDENT(2) | JSON_ENCODE_ANY);

        printf("%s\n", s ?: "null");
}
