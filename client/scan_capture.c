/* scan_capture.c - gonioctl scan DATASET (see scan_capture.h): continuous mode asks goniod
 * for scan.continuous on the open dataset (one pass per laser); stop-and-go mode writes a
 * session file (the turntable sweep, each laser alone and the unlit frame at every angle,
 * the lamps given, the camera) and runs it as a session. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "client/cmd.h"
#include "client/scan_capture.h"
#include "client/session.h"
#include "common/cleanup.h"

#define SCAN_FROM    0.0
#define SCAN_TO      360.0
#define SCAN_STEP    0.45
#define SCAN_SLACK_S 120 /* on top of the frames' time, for the reply of a continuous scan */
#define SCAN_MIN_FPS 0.1 /* the slowest frame rate a rig file allows */
#define SCAN_CALL_S  30

/* The scan's angles from the options (defaults: a full turn at 0.45 deg). */
struct range {
        double from, to, step;
};

static void read_range(const struct args *a, struct range *rg)
{
        *rg = (struct range){SCAN_FROM, SCAN_TO, SCAN_STEP};
        if (a->given & ARG_START)
                rg->from = a->start;
        if (a->given & ARG_END)
                rg->to = a->end;
        if (a->given & ARG_STEP)
                rg->step = a->step;
}

/* Opens DATASET in goniod, creating it when it does not exist; its directory into *path
 * (a new reference). */
static int open_dataset(struct out *o, struct conn *conn, const char *name, json_t **path)
{
        struct conn_error e;
        json_t *res = NULL;
        int r = -ENOENT;

        for (int create = 0; create < 2 && r < 0; create++) {
                r = conn_call(conn, "dataset.open",
                              json_pack("{s:s,s:b}", "name", name, "create", create),
                              conn_now_ms() + SCAN_CALL_S * 1000, -1, NULL, NULL, &res, &e);
                if (r == -EREMOTEIO && e.code == -32005 && !create)
                        continue; /* no such dataset: create it */
                if (r < 0)
                        return cmd_call_failed(o, "dataset.open", r, &e);
        }
        *path = json_incref(json_object_get(res, "path"));
        json_decref(res);
        return EXIT_OK;
}

/* The number of the rig's lasers (goniod's status), at least 1. */
static size_t rig_lasers(struct conn *conn)
{
        struct conn_error e;
        json_t *st = NULL;
        size_t n = 1;

        if (conn_call(conn, "status", json_object(), conn_now_ms() + SCAN_CALL_S * 1000, -1, NULL,
                      NULL, &st, &e) >= 0)
                n = MAX(json_array_size(json_object_get(st, "lasers")), (size_t)1);
        json_decref(st);
        return n;
}

static int scan_continuous(const struct args *a, struct out *o, struct conn *conn,
                           const char *dataset, const struct range *rg, json_t **ret)
{
        double frames = (fabs(rg->to - rg->from) / rg->step + 1) * (double)rig_lasers(conn);
        json_t *params = json_pack("{s:s,s:f,s:f,s:f}", "dataset", dataset, "from", rg->from, "to",
                                   rg->to, "step", rg->step);
        struct conn_error e;
        int r;

        if (a->camera)
                json_object_set_new(params, "camera", json_string(a->camera));
        if (a->given & ARG_EXPOSURE)
                json_object_set_new(params, "exposure_us", json_integer(a->exposure_us));
        if (a->given & ARG_GAIN)
                json_object_set_new(params, "gain", json_real(a->gain));
        r = conn_call(conn, "scan.continuous", params,
                      conn_now_ms() + (int64_t)((frames / SCAN_MIN_FPS + SCAN_SLACK_S) * 1000), -1,
                      NULL, NULL, ret, &e);
        return r < 0 ? cmd_call_failed(o, "scan.continuous", r, &e) : EXIT_OK;
}

/* The session file of a stop-and-go scan into *text (free it). */
static int stop_session_text(const struct args *a, const char *dataset, const struct range *rg,
                             char **text)
{
        _cleanup_free_ char *lamps = NULL, *cameras = NULL;
        char exposure[64] = "", gain[64] = "";

        if (asprintf(&lamps, "[%s]", a->lamps ?: "") < 0 ||
            asprintf(&cameras, a->camera ? "[%s]" : "all", a->camera) < 0)
                return -ENOMEM;
        if (a->given & ARG_EXPOSURE)
                snprintf(exposure, sizeof(exposure), "exposure_us: %ld\n", a->exposure_us);
        if (a->given & ARG_GAIN)
                snprintf(gain, sizeof(gain), "gain: %.17g\n", a->gain);
        if (asprintf(text,
                     "name: scan-%lld\n"
                     "dataset: %s\n"
                     "sweep:\n"
                     "  turntable: { from: %.17g, to: %.17g, step: %.17g }\n"
                     "cameras: %s\n"
                     "lamps: %s\n"
                     "laser: each\n"
                     "unlit: true\n"
                     "%s%s",
                     (long long)time(NULL), dataset, rg->from, rg->to, rg->step, cameras, lamps,
                     exposure, gain) < 0)
                return -ENOMEM;
        return 0;
}

static int scan_stop(const struct args *a, struct out *o, struct conn *conn, const char *dataset,
                     const struct range *rg, json_t **ret)
{
        _cleanup_close_ int sfd = cmd_intr_fd();
        _cleanup_free_ char *text = NULL;
        struct conn_error e;
        json_t *res = NULL;
        int r;

        if (stop_session_text(a, dataset, rg, &text) < 0) {
                out_error(o, "scan", "out of memory");
                return EXIT_PROTOCOL;
        }
        r = conn_call(conn, "session.run", json_pack("{s:s,s:s}", "file", "scan", "text", text),
                      conn_now_ms() + SCAN_CALL_S * 4000, sfd, NULL, NULL, &res, &e);
        if (r < 0)
                return cmd_call_failed(o, "session.run", r, &e);
        if (o->json)
                out_notification(o, "session.state", res);
        r = csession_follow(o, conn, sfd, res);
        json_decref(res);
        if (r == EXIT_OK &&
            conn_call(conn, "session.status", json_object(), conn_now_ms() + SCAN_CALL_S * 1000, -1,
                      NULL, NULL, ret, &e) < 0)
                *ret = json_object();
        return r;
}

int scan_capture(const struct args *a, struct out *o, json_t **ret)
{
        _cleanup_(conn_freep) struct conn *conn = NULL;
        const char *dataset = a->words[1], *mode = a->mode ?: "continuous";
        json_t *path = NULL;
        struct range rg;
        int r;

        if (strcmp(mode, "continuous") != 0 && strcmp(mode, "stop") != 0) {
                out_error(o, "scan", "--mode is continuous or stop, not '%s'", mode);
                return EXIT_USAGE;
        }
        read_range(a, &rg);
        if ((r = cmd_connect(a, o, &conn)) != EXIT_OK)
                return r;
        if (strcmp(mode, "stop") == 0)
                r = scan_stop(a, o, conn, dataset, &rg, ret);
        else if ((r = open_dataset(o, conn, dataset, &path)) == EXIT_OK)
                r = scan_continuous(a, o, conn, dataset, &rg, ret);
        if (r == EXIT_OK && !path)
                r = open_dataset(o, conn, dataset, &path);
        if (r == EXIT_OK)
                json_object_set_new(*ret, "path", path);
        else
                json_decref(path);
        return r;
}

void scan_capture_print(json_t *r)
{
        json_t *lasers = json_object_get(r, "lasers"), *l;
        size_t n = MAX(json_array_size(lasers), (size_t)1), i;

        if (!json_object_get(r, "stored")) /* stop-and-go: the session's status */
                return out_print_session_status(r);
        printf("scan -> dataset %s, camera %s: %lld of %lld angles x %zu laser(s) stored (%lld "
               "frames, %lld late), %.2f deg/s in %lld legs per laser, %.1f s\n",
               json_string_value(json_object_get(r, "dataset")),
               json_string_value(json_object_get(r, "camera")),
               json_integer_value(json_object_get(r, "stored")),
               json_integer_value(json_object_get(r, "positions")) * (json_int_t)n, n,
               json_integer_value(json_object_get(r, "frames")),
               json_integer_value(json_object_get(r, "late")),
               json_number_value(json_object_get(r, "speed_deg_s")),
               json_integer_value(json_object_get(r, "legs")),
               json_number_value(json_object_get(r, "duration_s")));
        printf("largest gap between stored angles %.3f deg; read-backs at most %.3f deg apart\n",
               json_number_value(json_object_get(r, "max_gap_deg")),
               json_number_value(json_object_get(r, "interp_spread_deg")));
        json_array_foreach(lasers, i, l)
                printf("pass %zu: laser %s\n", i + 1, json_string_value(l));
}
