/* session.c - gonioctl's session commands (see session.h). */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "client/cmd.h"
#include "client/session.h"
#include "common/cleanup.h"
#include "protocol/proto.h"

#define FILE_MAX   (PROTO_MAX_LINE / 2) /* a session file, escaped, fits one request */
#define BAR_WIDTH  30
#define PAUSE_WAIT 30000 /* ms for a pause asked by Ctrl-C to take effect */

int csession_file_params(const char *path, json_t *params)
{
        _cleanup_fclose_ FILE *f = fopen(path, "re");
        _cleanup_free_ char *text = malloc(FILE_MAX + 1);
        size_t n;

        if (!f || !text) {
                fprintf(stderr, "gonioctl: %s: %s\n", path, strerror(f ? ENOMEM : errno));
                return -EINVAL;
        }
        n = fread(text, 1, FILE_MAX + 1, f);
        if (ferror(f) || n > FILE_MAX) {
                fprintf(stderr, "gonioctl: %s: %s\n", path,
                        ferror(f) ? strerror(errno) : "larger than a session file may be");
                return -EINVAL;
        }
        text[n] = 0;
        if (json_object_set_new(params, "file", json_string(path)) < 0 ||
            json_object_set_new(params, "text", json_stringn(text, n)) < 0) {
                fprintf(stderr, "gonioctl: %s: not UTF-8 text\n", path);
                return -EINVAL;
        }
        return 0;
}

static const char *str(json_t *o, const char *key)
{
        return json_string_value(json_object_get(o, key)) ?: "";
}

static double num(json_t *o, const char *key)
{
        return json_number_value(json_object_get(o, key));
}

static void fmt_duration(char *buf, size_t len, double s)
{
        long t = s > 0 && s < 1e7 ? (long)(s + 0.5) : 0;

        snprintf(buf, len, "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
}

/* The state to show: how it ended once it has. */
static const char *shown_state(json_t *st)
{
        return strcmp(str(st, "state"), "none") == 0 ? str(st, "ended") : str(st, "state");
}

/* The progress line of a session status: bar, count, rate, ETA, state. */
static void progress_line(struct out *o, json_t *st)
{
        double planned = num(st, "planned"), captured = num(st, "captured");
        int fill = planned > 0 ? (int)(BAR_WIDTH * captured / planned) : 0;
        char bar[BAR_WIDTH + 1], eta[32];

        if (!o->progress)
                return;
        for (int i = 0; i < BAR_WIDTH; i++)
                bar[i] = i < fill ? '#' : '.';
        bar[BAR_WIDTH] = 0;
        fmt_duration(eta, sizeof(eta), num(st, "eta_s"));
        fprintf(stderr, "\r\033[K[%s] %.0f/%.0f  %.1f/s  ETA %s  %s", bar, captured, planned,
                num(st, "rate_per_s"), eta, shown_state(st));
        o->progress_shown = true;
}

/* What the follower has seen of the session. */
struct follow {
        struct out *o;
        json_t *last; /* the last status */
};

static void on_event(const char *method, json_t *params, void *userdata)
{
        struct follow *f = userdata;

        if (strncmp(method, "session.", 8) != 0 || !params)
                return;
        if (f->o->json)
                out_notification(f->o, method, params);
        if (strcmp(method, "session.state") == 0 && !f->o->json && !f->o->quiet && !f->o->progress)
                printf("session %s: %s %s\n", str(params, "name"), shown_state(params),
                       str(params, "reason"));
        progress_line(f->o, params);
        json_decref(f->last);
        f->last = json_incref(params);
}

/* The exit code of a session that stopped running, from its last status. */
static int exit_code(struct out *o, json_t *st)
{
        const char *state = str(st, "state");

        out_progress_end(o);
        if (!o->json && !o->quiet)
                out_print_session_status(st);
        if (strcmp(state, "none") == 0 && strcmp(str(st, "ended"), "done") == 0)
                return EXIT_OK;
        if (json_is_integer(json_object_get(st, "code")))
                return cmd_exit_for_code(json_integer_value(json_object_get(st, "code")));
        return EXIT_CANCELED;
}

static bool running(json_t *st)
{
        const char *state = str(st, "state");

        return strcmp(state, "none") != 0 && strcmp(state, "paused") != 0;
}

/* Ctrl-C: asks goniod to pause the session and waits until it has. */
static int pause_on_interrupt(struct follow *f, struct conn *conn, int intr_fd)
{
        struct conn_error e;
        json_t *res = NULL;
        char buf[128];
        int64_t deadline = conn_now_ms() + PAUSE_WAIT;
        int r;

        (void)!read(intr_fd, buf, sizeof(buf));
        out_error(f->o, "session", "interrupted: pausing the session at the next capture");
        r = conn_call(conn, "session.pause", json_object(), deadline, -1, on_event, f, &res, &e);
        json_decref(res);
        if (r < 0 && r != -EREMOTEIO)
                return EXIT_PROTOCOL;
        while (running(f->last))
                if (conn_wait_notification(conn, deadline, -1, on_event, f, &e) < 0)
                        return EXIT_PROTOCOL;
        exit_code(f->o, f->last);
        return EXIT_INTERRUPTED;
}

int csession_follow(struct out *o, struct conn *conn, int intr_fd, json_t *status)
{
        struct follow f = {.o = o, .last = json_incref(status)};
        struct conn_error e;
        int r = 0;

        progress_line(o, status);
        while (running(f.last)) {
                r = conn_wait_notification(conn, CONN_NO_DEADLINE, intr_fd, on_event, &f, &e);
                if (r == -EINTR) {
                        r = pause_on_interrupt(&f, conn, intr_fd);
                        json_decref(f.last);
                        return r;
                }
                if (r < 0) {
                        out_error(o, "session",
                                  "lost goniod: %s (the session goes on: gonioctl "
                                  "session watch)",
                                  e.message[0] ? e.message : strerror(-r));
                        json_decref(f.last);
                        return EXIT_PROTOCOL;
                }
        }
        r = exit_code(o, f.last);
        json_decref(f.last);
        return r;
}

void out_print_session_plan(json_t *r)
{
        json_t *kinds = json_object_get(r, "kinds"), *order = json_object_get(r, "order"), *v;
        const char *k;
        char est[32], low[32];
        size_t i;

        fmt_duration(est, sizeof(est), num(r, "estimate_s"));
        fmt_duration(low, sizeof(low), num(r, "lower_bound_s"));
        printf("session %s -> dataset %s (rig %s)\n", str(r, "session"), str(r, "dataset"),
               str(r, "rig"));
        printf("captures  %.0f in %.0f exposures (", num(r, "captures"), num(r, "shots"));
        const char *sep = "";

        json_object_foreach(kinds, k, v)
        {
                printf("%s%s %lld", sep, k, (long long)json_integer_value(v));
                sep = ", ";
        }
        printf(")\nmoves     %.0f, loops outermost first:", num(r, "moves"));
        json_array_foreach(order, i, v) printf(" %s", json_string_value(v));
        printf("\nduration  %s estimated (lower bound %s)\n", est, low);
        printf("skipped   %.0f\n", num(r, "skipped_count"));
        json_array_foreach(json_object_get(r, "skipped"), i, v)
                printf("  %s\n", json_string_value(v));
        if (num(r, "skipped_count") > json_array_size(json_object_get(r, "skipped")))
                printf("  ...\n");
}

void out_print_session_status(json_t *r)
{
        char el[32], eta[32];
        const char *state = str(r, "state");

        if (strcmp(state, "none") == 0 && !json_object_get(r, "name")) {
                printf("no session\n");
                return;
        }
        fmt_duration(el, sizeof(el), num(r, "elapsed_s"));
        fmt_duration(eta, sizeof(eta), num(r, "eta_s"));
        printf("session %s (dataset %s): %s%s%s\n", str(r, "name"), str(r, "dataset"),
               shown_state(r), str(r, "reason")[0] ? ": " : "", str(r, "reason"));
        printf("captured %.0f of %.0f, %.1f/s, elapsed %s, ETA %s\n", num(r, "captured"),
               num(r, "planned"), num(r, "rate_per_s"), el, eta);
}
