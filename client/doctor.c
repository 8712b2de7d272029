/* doctor.c - gonioctl doctor (doctor.h): a list of checks, each ok, warn or fail with a hint
 * saying what to do, from the socket file up to the room a session needs. */
#include <errno.h>
#include <grp.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "client/cmd.h"
#include "client/conn.h"
#include "client/doctor.h"
#include "client/session.h"
#include "common/cleanup.h"
#include "protocol/proto.h"

#define PNG_RATIO                                                                                  \
        0.6 /* a stored frame's bytes over its raw size, about (noise compresses badly)            \
             */

static void add(json_t *checks, const char *name, const char *status, const char *hint,
                const char *fmt, ...) __attribute__((format(printf, 5, 6)));

static void add(json_t *checks, const char *name, const char *status, const char *hint,
                const char *fmt, ...)
{
        char detail[512];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(detail, sizeof(detail), fmt, ap);
        va_end(ap);
        json_array_append_new(checks, json_pack("{s:s,s:s,s:s,s:s?}", "name", name, "status",
                                                status, "detail", detail, "hint", hint));
}

/* Whether this user may connect to a socket of group gid. */
static bool in_group(gid_t gid, uid_t owner)
{
        gid_t groups[NGROUPS_MAX];
        int n = getgroups(NGROUPS_MAX, groups);

        if (geteuid() == 0 || geteuid() == owner || getegid() == gid)
                return true;
        for (int i = 0; i < n; i++)
                if (groups[i] == gid)
                        return true;
        return false;
}

/* The socket file: there, a socket, reachable by this user. False when it is not. */
static bool check_socket(const struct args *a, json_t *checks)
{
        char path[108];
        struct stat st;
        struct group *g;
        int r;

        if (a->socket)
                snprintf(path, sizeof(path), "%s", a->socket);
        else
                (void)proto_socket_path(path, sizeof(path));
        if ((r = stat(path, &st) < 0 ? -errno : 0) < 0 || !S_ISSOCK(st.st_mode)) {
                add(checks, "socket", "fail",
                    "start goniod (systemctl start goniod.socket), or name its socket: --socket "
                    "PATH or $GONIO_SOCKET",
                    "%s: %s", path, r < 0 ? strerror(-r) : "not a socket");
                return false;
        }
        g = getgrgid(st.st_gid);
        if (!in_group(st.st_gid, st.st_uid)) {
                add(checks, "socket", "fail",
                    "add yourself to the socket's group (sudo usermod -aG GROUP $USER) and log in "
                    "again",
                    "%s: group %s, which you are not in", path, g ? g->gr_name : "?");
                return false;
        }
        add(checks, "socket", "ok", NULL, "%s (mode %03o, group %s)", path, st.st_mode & 0777,
            g ? g->gr_name : "?");
        return true;
}

/* One device of status: open, and (axes) homed. Whether it fails. */
static bool check_device(json_t *checks, json_t *d, bool axis)
{
        const char *name = json_string_value(json_object_get(d, "name")) ?: "?";

        if (!json_is_true(json_object_get(d, "open"))) {
                add(checks, name, "fail",
                    "check its cable, power and port (gonioctl devices lists the ports here), "
                    "then gonioctl fault clear",
                    "%s does not answer", name);
                return true;
        }
        if (axis && !json_is_true(json_object_get(d, "homed")))
                add(checks, name, "warn", "gonioctl home", "%s is not homed", name);
        else
                add(checks, name, "ok", NULL, "%s answers", name);
        return false;
}

/* The fault and every device of status st; whether any fails. */
static bool check_rig(json_t *checks, json_t *st)
{
        static const char *const lists[] = {"axes", "lamps", "lasers", "cameras"};
        json_t *fault = json_object_get(st, "fault"), *d;
        bool failed = false;
        size_t i;

        if (json_is_object(fault)) {
                add(checks, "fault", "fail", "fix the device, then gonioctl fault clear",
                    "fault on %s: %s", json_string_value(json_object_get(fault, "device")) ?: "?",
                    json_string_value(json_object_get(fault, "message")) ?: "?");
                failed = true;
        } else
                add(checks, "fault", "ok", NULL, "no fault latched (state %s)",
                    json_string_value(json_object_get(st, "state")) ?: "?");
        for (size_t k = 0; k < ELEMENTSOF(lists); k++)
                json_array_foreach(json_object_get(st, lists[k]), i, d) failed |=
                        check_device(checks, d, k == 0);
        return failed;
}

/* The largest frame one capture stores, raw, from describe's camera configs. */
static double frame_bytes(struct conn *conn, int64_t deadline)
{
        _cleanup_(json_decrefp) json_t *desc = NULL;
        struct conn_error e;
        double most = 0;
        json_t *d;
        size_t i;

        if (conn_call(conn, "describe", json_object(), deadline, -1, NULL, NULL, &desc, &e) < 0)
                return 0;
        json_array_foreach(json_object_get(desc, "devices"), i, d)
        {
                json_t *c = json_object_get(d, "config");
                double b = json_number_value(json_object_get(c, "width")) *
                           json_number_value(json_object_get(c, "height")) * 3 *
                           json_number_value(json_object_get(c, "bits")) / 8;
                most = b > most ? b : most;
        }
        return most;
}

/* The room on the data root against what the session file would store; whether short. */
static bool check_storage(const struct args *a, json_t *checks, struct conn *conn, json_t *st,
                          int64_t deadline)
{
        json_t *s = json_object_get(st, "storage"), *plan = NULL;
        _cleanup_(json_decrefp) json_t *params = json_object();
        double free_b = json_number_value(json_object_get(s, "free_bytes")), need;
        const char *root = json_string_value(json_object_get(s, "root")) ?: "?";
        struct conn_error e;
        int64_t captures;

        if (a->nwords < 2 || csession_file_params(a->words[1], params) < 0 ||
            conn_call(conn, "session.plan", json_incref(params), deadline, -1, NULL, NULL, &plan,
                      &e) < 0) {
                if (a->nwords >= 2)
                        add(checks, "session", "fail", "gonioctl validate FILE --rig RIG says why",
                            "%s: goniod cannot plan it", a->words[1]);
                add(checks, "storage", "ok", NULL, "%s: %.1f GB free", root, free_b / 1e9);
                return a->nwords >= 2;
        }
        captures = json_integer_value(json_object_get(plan, "captures"));
        need = (double)captures * frame_bytes(conn, deadline) * PNG_RATIO;
        json_decref(plan);
        add(checks, "storage",
            free_b < need         ? "fail"
            : free_b < 1.2 * need ? "warn"
                                  : "ok",
            free_b < 1.2 * need ? "free room on the data root, or put it on a larger disk" : NULL,
            "%s: %.2f GB free, the session's %lld captures need about %.1f MB", root, free_b / 1e9,
            (long long)captures, need / 1e6);
        return free_b < need;
}

/* The result: ok and the checks; the exit code of the worst. A failure prints the checks
 * itself (its result is not printed): for people above the error, with --json inside the
 * error object. */
static int finish(struct out *o, json_t *checks, int code, json_t **ret)
{
        *ret = json_pack("{sbso}", "ok", code == EXIT_OK, "checks", checks);
        if (code == EXIT_OK)
                return code;
        if (!o->json && !o->quiet)
                doctor_print(*ret);
        out_error(o, "doctor", "%s", "some checks failed");
        json_decref(o->error_detail);
        o->error_detail = json_pack("{sO}", "checks", checks);
        return code;
}

int doctor_command(const struct args *a, struct out *o, json_t **ret)
{
        _cleanup_(conn_freep) struct conn *conn = NULL;
        _cleanup_(json_decrefp) json_t *st = NULL;
        json_t *checks = json_array();
        int64_t deadline = conn_now_ms() + 10000;
        struct conn_error e;
        struct out quiet = *o;
        bool dev, room;

        if (cmd_tcp_address(a)) /* no socket file: whether goniod answers says it all */
                add(checks, "socket", "ok", NULL, "over TCP: %s", cmd_tcp_address(a));
        else if (!check_socket(a, checks))
                return finish(o, checks, EXIT_CONNECT, ret);
        quiet.quiet = true;
        if (cmd_connect(a, &quiet, &conn) != EXIT_OK ||
            conn_call(conn, "status", json_object(), deadline, -1, NULL, NULL, &st, &e) < 0) {
                add(checks, "goniod", "fail", "is goniod running? journalctl -u goniod says why",
                    "goniod does not answer%s%s", quiet.error[0] ? ": " : " on the socket",
                    quiet.error); /* why: a TLS certificate not trusted, a wrong token... */
                return finish(o, checks, EXIT_CONNECT, ret);
        }
        add(checks, "goniod", "ok", NULL, "goniod answers (protocol %d)", PROTO_VERSION);
        dev = check_rig(checks, st);
        room = check_storage(a, checks, conn, st, deadline);
        return finish(o, checks, dev ? EXIT_DEVICE : room ? EXIT_STORAGE : EXIT_OK, ret);
}

void doctor_print(json_t *result)
{
        json_t *c;
        size_t i;

        json_array_foreach(json_object_get(result, "checks"), i, c)
        {
                const char *hint = json_string_value(json_object_get(c, "hint"));
                printf("%-4s  %s\n", json_string_value(json_object_get(c, "status")),
                       json_string_value(json_object_get(c, "detail")));
                if (hint)
                        printf("      -> %s\n", hint);
        }
}
