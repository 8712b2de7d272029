/* calibrate.c - gonioctl calibrate camera|turntable|laser|lamps: the solves of calib/ on a
 * dataset's calibration captures (--from DATASET, offline, or captured on the rig as a
 * session first), their summaries, and the calibration file they are written into
 * (calib/calfile.h, docs/calibration.md). Every command shares one preparation (dataset,
 * camera, intrinsics, file) and one error path. Built with calib/ only where OpenCV is. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "client/calibrate.h"
#include "client/cmd.h"
#include "common/cleanup.h"

#ifdef GONIOCTL_CALIB
#include <time.h>

#include "calib/calfile.h"
#include "calib/lamps.h"
#include "calib/scan.h"
#include "calib/scan_cal.h"
#include "calib/turntable_geom.h"
#include "client/conn.h"
#include "client/session.h"
#include "common/riggeom.h"
#include "common/yconf.h"
#include "dataset/ds.h"
#include "drivers/registry.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);

struct solve;

/* What a calibration command solves and what it needs. */
struct kind {
        const char *name; /* "camera" */
        bool board;       /* needs --board (else: lamps, --sphere) */
        bool one_camera;  /* solves one camera (else every camera of the dataset) */
        bool intrinsics;  /* needs that camera's intrinsics from the file */
        int (*fn)(struct solve *s, json_t **ret);
};

/* One calibration command on its way: what it solves from and writes into. */
struct solve {
        const struct args *a;
        struct out *o;
        const char *what; /* "calibrate turntable", for messages */
        struct ds *d;
        char file[PATH_MAX]; /* the calibration file */
        char camera[DS_NAME_MAX];
        struct cal_board board;
        struct cal_intrinsics k; /* from the file's cameras section (turntable, laser) */
        char err[1024];
};

/* Prints s->err (or strerror) for r and returns its exit code. */
static int failed(struct solve *s, int r)
{
        out_error(s->o, s->what, "%s", s->err[0] ? s->err : strerror(-r));
        return cmd_exit_for_errno(r);
}

/* The camera: --camera, else the dataset's only one. */
static int pick_camera(struct solve *s)
{
        struct ds_summary sum;
        int r;

        if (s->camera[0]) /* the rig's */
                return 0;
        if (s->a->camera) {
                snprintf(s->camera, sizeof(s->camera), "%s", s->a->camera);
                return 0;
        }
        r = ds_summary(s->d, &sum);
        if (r < 0)
                return r;
        if (sum.n_cameras == 1) {
                snprintf(s->camera, sizeof(s->camera), "%s", sum.cameras[0].name);
                return 0;
        }
        snprintf(s->err, sizeof(s->err), "dataset %s has %s cameras: name one with --camera",
                 ds_path(s->d), sum.n_cameras ? "several" : "no");
        return sum.n_cameras ? -EINVAL : -ENODATA;
}

/* The intrinsics of s->camera from the calibration file. */
static int load_intrinsics(struct solve *s)
{
        struct cal_camera c;
        int r = cal_camera_read(s->file, s->camera, &c, s->err, sizeof(s->err));

        if (r == -ENOENT)
                snprintf(s->err, sizeof(s->err),
                         "no intrinsics of camera %s in %s: run gonioctl calibrate camera first "
                         "(or name the file that has them with --calibration)",
                         s->camera, s->file);
        if (r < 0)
                return r;
        s->k = c.k;
        return 0;
}

/* Opens dataset and fills s (file: the calibration file, NULL for DATASET/calibration.yaml)
 * for k. Returns an exit code, the error printed. */
static int prepare(struct solve *s, const char *dataset, const char *file, const struct kind *k)
{
        int r = ds_open(dataset, &s->d);

        if (r < 0) {
                out_error(s->o, s->what, "cannot open dataset %s: %s", dataset, strerror(-r));
                return EXIT_INVALID;
        }
        if (file)
                snprintf(s->file, sizeof(s->file), "%s", file);
        else
                snprintf(s->file, sizeof(s->file), "%s/calibration.yaml", ds_path(s->d));
        if (k->one_camera &&
            ((r = pick_camera(s)) < 0 || (k->intrinsics && (r = load_intrinsics(s)) < 0)))
                return failed(s, r);
        return EXIT_OK;
}

/* The calibration file s->file into *f (malloc'd); a missing file (-ENOENT) an error unless
 * optional, then *f is empty. */
static int read_calfile(struct solve *s, bool optional, struct cal_file **f)
{
        int r;

        *f = calloc(1, sizeof(**f));
        if (!*f)
                return -ENOMEM;
        r = cal_file_read(s->file, *f, s->err, sizeof(s->err));
        if (r == -ENOENT && optional)
                return 0;
        if (r == -ENOENT)
                snprintf(s->err, sizeof(s->err),
                         "no calibration file %s: run gonioctl calibrate camera and turntable "
                         "for each camera first (or name the file that has them with "
                         "--calibration)",
                         s->file);
        return r;
}

/* ---- on the rig: the capture session ---- */

#define RIG_TIMEOUT_S 30
#define LAMPS_ANGLES  16 /* turntable angles of the lamps' capture */

/* What a calibration capture needs of the rig, from describe. */
struct rig_info {
        char camera[DS_NAME_MAX], lamp[DS_NAME_MAX], laser[DS_NAME_MAX];
        char cameras[RIG_MAX_CAMERAS][DS_NAME_MAX]; /* every camera */
        int n_cameras;
        bool camera_arm;
        char calibration[PATH_MAX]; /* the rig's calibration file, "" if none */
};

/* Calls method with params (stolen); its result into *res. Returns an exit code. */
static int call(struct solve *s, struct conn *c, const char *method, json_t *params, json_t **res)
{
        struct conn_error e;
        int r = conn_call(c, method, params, conn_now_ms() + RIG_TIMEOUT_S * 1000, -1, NULL, NULL,
                          res, &e);

        if (r == -EREMOTEIO) {
                out_error(s->o, s->what, "%s: %s", method, e.message);
                return cmd_exit_for_code(e.code);
        }
        if (r < 0)
                out_error(s->o, s->what, "%s: %s", method, e.message[0] ? e.message : strerror(-r));
        return r < 0 ? EXIT_PROTOCOL : EXIT_OK;
}

/* Copies the name of the first device of class cls (or the one named want) into out;
 * counts them into *n. */
static void find_device(json_t *devs, const char *cls, const char *want, char *out, size_t len,
                        int *n)
{
        json_t *d;
        size_t i;

        *n = 0;
        json_array_foreach(devs, i, d)
        {
                const char *name = json_string_value(json_object_get(d, "name")) ?: "";

                if (strcmp(json_string_value(json_object_get(d, "class")) ?: "", cls) != 0)
                        continue;
                if (!want ? !*n : strcmp(name, want) == 0)
                        snprintf(out, len, "%s", name);
                ++*n;
        }
}

/* Copies the name of the nth device of class cls into out. */
static void find_nth(json_t *devs, const char *cls, int nth, char *out, size_t len)
{
        json_t *d;
        size_t i;

        json_array_foreach(devs, i, d)
        {
                if (strcmp(json_string_value(json_object_get(d, "class")) ?: "", cls) == 0 &&
                    nth-- == 0)
                        snprintf(out, len, "%s",
                                 json_string_value(json_object_get(d, "name")) ?: "");
        }
}

/* The rig's camera (--camera or its only one; one_camera: needed), first lamp, laser, camera
 * arm and calibration file (--calibration or the rig file's), from describe. Returns an exit
 * code. */
static int rig_info(struct solve *s, struct conn *c, bool one_camera, struct rig_info *ri)
{
        _cleanup_(json_decrefp) json_t *d = NULL;
        json_t *devs;
        char arm[DS_NAME_MAX] = "";
        int r = call(s, c, "describe", json_object(), &d), n;

        if (r != EXIT_OK)
                return r;
        devs = json_object_get(d, "devices");
        find_device(devs, "camera", s->a->camera, ri->camera, sizeof(ri->camera), &n);
        for (int i = 0; i < n && i < RIG_MAX_CAMERAS; i++, ri->n_cameras++)
                find_nth(devs, "camera", i, ri->cameras[i], sizeof(ri->cameras[i]));
        if (one_camera ? !ri->camera[0] || (n > 1 && !s->a->camera) : !n) {
                out_error(s->o, s->what, "%s: name one of the rig's %d cameras with --camera",
                          s->a->camera ? "no such camera"
                          : n          ? "which camera?"
                                       : "no camera",
                          n);
                return EXIT_INVALID;
        }
        find_device(devs, "lamp", NULL, ri->lamp, sizeof(ri->lamp), &n);
        find_device(devs, "laser", s->a->laser, ri->laser, sizeof(ri->laser), &n);
        find_device(devs, "axis", "camera_arm", arm, sizeof(arm), &n);
        ri->camera_arm = arm[0];
        snprintf(ri->calibration, sizeof(ri->calibration), "%s",
                 s->a->calib ?: json_string_value(json_object_get(
                                              json_object_get(d, "calibration"), "path"))
                                    ?: "");
        return EXIT_OK;
}

/* Says what the capture of kind needs that the rig lacks (exit 6), or EXIT_OK. */
static int rig_check(struct solve *s, const char *kind, const struct rig_info *ri)
{
        const char *lack = !ri->calibration[0]
                                   ? "calibration file: add 'calibration: PATH' to the rig "
                                     "file, or give --calibration FILE"
                           : !ri->lamp[0] ? "lamp"
                           : strcmp(kind, "laser") == 0 && !ri->laser[0]
                                   ? (s->a->laser ? "laser of that name" : "laser")
                                   : NULL;

        if (!lack)
                return EXIT_OK;
        out_error(s->o, s->what, "the rig has no %s", lack);
        return EXIT_INVALID;
}

/* The session file of the capture of kind ("camera", "turntable", "laser", "lamps") named
 * name: the board seen by the camera at 12 turntable angles with the first lamp lit (and
 * each laser alone, or only one_laser), or the mirror sphere seen by every camera at LAMPS_ANGLES
 * angles with each lamp lit alone. */
static char *session_text(const char *kind, const char *name, const struct rig_info *ri,
                          const char *one_laser)
{
        char *text = NULL, cams[DS_NAME_MAX + 2], lamps[DS_NAME_MAX + 2], sweep[64];
        char lasers[DS_NAME_MAX + 2] = "false";
        bool camera = strcmp(kind, "camera") == 0, laser = strcmp(kind, "laser") == 0,
             sphere = strcmp(kind, "lamps") == 0;

        if (laser)
                snprintf(lasers, sizeof(lasers), one_laser ? "[%s]" : "each", one_laser);
        snprintf(cams, sizeof(cams), sphere ? "all" : "[%s]", ri->camera);
        snprintf(lamps, sizeof(lamps), sphere ? "all" : "[%s]", ri->lamp);
        snprintf(sweep, sizeof(sweep), "{ from: 0, to: 359, step: %g }",
                 sphere ? 360.0 / LAMPS_ANGLES : 30.0);
        if (asprintf(&text,
                     "# gonioctl calibrate %s: %s on the turntable\n"
                     "name: %s\ndataset: %s\ncameras: %s\nlamps: %s\nlaser: %s\n"
                     "skip_occluded: false\nskip_glare: false\n"
                     "sweep:\n  turntable: %s\n%s",
                     kind, sphere ? "the mirror sphere" : "the board", name, name, cams, lamps,
                     lasers, sweep,
                     camera && ri->camera_arm ? "  camera_arm: [-15, 0, 15]\n" : "") < 0)
                return NULL;
        return text;
}

/* Runs the calibration capture of kind on the rig as a session, following it; the path of
 * its dataset into path. Returns an exit code. */
static int capture(struct solve *s, struct conn *c, const char *kind, const struct rig_info *ri,
                   char *path, size_t len)
{
        _cleanup_(json_decrefp) json_t *st = NULL, *info = NULL;
        _cleanup_free_ char *text = NULL;
        _cleanup_close_ int sfd = cmd_intr_fd();
        char name[DS_NAME_MAX], stamp[32];
        /* the session's progress on a terminal; with --json only the summary on stdout */
        struct out follow = {.quiet = s->o->quiet || s->o->json, .progress = s->o->progress};
        time_t now = time(NULL);
        struct tm tm;
        int r;

        strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", gmtime_r(&now, &tm));
        snprintf(name, sizeof(name), "calib-%s-%s", kind, stamp);
        text = session_text(kind, name, ri, s->a->laser);
        if (!text || sfd < 0)
                return EXIT_PROTOCOL;
        r = call(s, c, "session.run", json_pack("{s:s,s:s}", "file", name, "text", text), &st);
        if (r != EXIT_OK)
                return r;
        r = csession_follow(&follow, c, sfd, st);
        if (r != EXIT_OK) {
                out_error(s->o, s->what,
                          "the capture session %s did not finish, nothing was solved: see "
                          "gonioctl session status; once resumed and done, solve with --from "
                          "and the dataset %s",
                          name, name);
                return r;
        }
        r = call(s, c, "dataset.info", json_pack("{s:s}", "name", name), &info);
        if (r == EXIT_OK)
                snprintf(path, len, "%s", json_string_value(json_object_get(info, "path")) ?: "");
        return r;
}

/* Checks that the file s->file has every camera's intrinsics and pose (for the lamps). */
static int check_cameras(struct solve *s, const struct rig_info *ri)
{
        _cleanup_free_ struct cal_file *f = NULL;
        struct sec_camera cam;
        int r = read_calfile(s, false, &f);

        for (int i = 0; r >= 0 && i < ri->n_cameras; i++)
                r = scan_cal_camera(f, ri->cameras[i], &cam, s->err, sizeof(s->err));
        return r;
}

/* Without --from: runs the capture on the rig, then prepares s from its dataset and the
 * rig's calibration file. */
static int start_rig(struct solve *s, const struct kind *k)
{
        _cleanup_(conn_freep) struct conn *c = NULL;
        struct rig_info ri = {0};
        char path[PATH_MAX];
        int r = cmd_connect(s->a, s->o, &c);

        if (r == EXIT_OK)
                r = rig_info(s, c, k->one_camera, &ri);
        if (r == EXIT_OK)
                r = rig_check(s, k->name, &ri);
        if (r != EXIT_OK)
                return r;
        snprintf(s->camera, sizeof(s->camera), "%s", ri.camera);
        snprintf(s->file, sizeof(s->file), "%s", ri.calibration);
        if ((k->intrinsics && (r = load_intrinsics(s)) < 0) || /* before the rig moves */
            (!k->one_camera && (r = check_cameras(s, &ri)) < 0))
                return failed(s, r);
        r = capture(s, c, k->name, &ri, path, sizeof(path));
        return r == EXIT_OK ? prepare(s, path, ri.calibration, k) : r;
}

/* Checks the command line and prepares s: from --from DATASET, or from a capture of kind k
 * on the rig. */
static int start(struct solve *s, const struct kind *k)
{
        const struct args *a = s->a;

        if (k->board && (!a->board || cal_board_parse(a->board, &s->board) < 0)) {
                args_usage_error(s->what, "needs --board chessboard:XxY:SQUARE or "
                                          "charuco:XxY:SQUARE:MARKER (squares, mm)");
                return EXIT_USAGE;
        }
        if (!k->board && !(a->sphere_mm > 0)) {
                args_usage_error(s->what, "needs --sphere DIAMETER (mm) of the mirror sphere on "
                                          "the turntable, or --nominal");
                return EXIT_USAGE;
        }
        if (!a->from)
                return start_rig(s, k);
        return prepare(s, a->from, a->calib, k);
}

static void finish(struct solve *s)
{
        s->d = ds_close(s->d);
}

/* ---- camera ---- */

static json_t *camera_json(const struct cal_camera *c, const char *file)
{
        json_t *rej = json_array();

        for (size_t i = 0; rej && i < c->n_views; i++)
                if (!c->views[i].used)
                        json_array_append_new(rej,
                                              json_pack("{s:s,s:s,s:o?}", "file", c->views[i].file,
                                                        "reason", c->views[i].reason, "rms_px",
                                                        isnan(c->views[i].rms)
                                                                ? NULL
                                                                : json_real(c->views[i].rms)));
        return json_pack("{s:s,s:i,s:i,s:f,s:f,s:f,s:f,s:[fffff],s:[ffff],s:f,s:i,s:i,s:o,s:s}",
                         "camera", c->camera, "width", c->width, "height", c->height, "fx", c->k.fx,
                         "fy", c->k.fy, "cx", c->k.cx, "cy", c->k.cy, "dist", c->k.dist[0],
                         c->k.dist[1], c->k.dist[2], c->k.dist[3], c->k.dist[4], "std_px",
                         c->std[0], c->std[1], c->std[2], c->std[3], "rms_px", c->rms, "views_used",
                         (int)c->n_used, "views_rejected", (int)(c->n_views - c->n_used),
                         "rejected", rej, "file", file);
}

static int solve_camera(struct solve *s, json_t **ret)
{
        struct cal_camera_opts opts = {.board = s->board, .camera = s->camera};
        struct cal_camera c = {0};
        int r = cal_camera_solve(s->d, &opts, &c, s->err, sizeof(s->err));

        if (r >= 0)
                r = cal_camera_write(s->file, &c, s->a->given & ARG_FORCE, s->err, sizeof(s->err));
        if (r >= 0)
                *ret = camera_json(&c, s->file);
        cal_camera_clear(&c);
        return r;
}

/* ---- turntable ---- */

static json_t *vec_json(const double *v, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                json_array_append_new(a, json_real(v[i]));
        return a;
}

static json_t *turntable_json(const struct cal_file_turntable *t, const char *file)
{
        const struct cal_turntable *tt = &t->tt;

        return json_pack("{s:s,s:o,s:o,s:o,s:o,s:f,s:f,s:f,s:f,s:i,s:i,s:s}", "camera", t->camera,
                         "axis", vec_json(tt->axis, 3), "origin", vec_json(tt->origin, 3), "R",
                         vec_json(tt->R, 9), "t", vec_json(tt->t, 3), "rms_px", tt->rms_px,
                         "circle_rms_mm", tt->circle_rms_mm, "tilt_deg", tt->tilt_deg, "span_deg",
                         tt->span_deg, "views_used", tt->n_used, "views_given", tt->n_views, "file",
                         file);
}

static int solve_turntable(struct solve *s, json_t **ret)
{
        struct cal_tt_opts opts = {.board = s->board, .k = s->k};
        struct cal_file_turntable t = {.board = s->board};
        int r;

        snprintf(t.camera, sizeof(t.camera), "%s", s->camera);
        snprintf(t.dataset, sizeof(t.dataset), "%s", ds_path(s->d));
        r = cal_turntable_solve_ds(s->d, s->camera, &opts, &t.tt, s->err, sizeof(s->err));
        if (r >= 0)
                r = cal_turntable_write(s->file, &t, s->a->given & ARG_FORCE, s->err,
                                        sizeof(s->err));
        if (r >= 0)
                *ret = turntable_json(&t, s->file);
        return r;
}

/* ---- laser ---- */

/* The lasers to solve: their names, channels and the rows of each (cal_lp_opts.lasers). */
struct laser_set {
        char name[RIG_MAX_LASERS][DS_NAME_MAX];
        int channel[RIG_MAX_LASERS];
        uint32_t rows[RIG_MAX_LASERS];
        int n;
};

/* Adds the laser of rig-file mapping m (index i of n) to ls unless --laser names another. */
static void add_laser(struct solve *s, struct yconf *yc, struct fy_node *m, int i, int n,
                      struct laser_set *ls)
{
        static const char *const channels[] = {"red", "green", "blue"};
        char name[DS_NAME_MAX] = "laser", ch[16] = "red";

        if (yconf_str(yc, m, "name", name, sizeof(name)) < 0 ||
            yconf_str(yc, m, "channel", ch, sizeof(ch)) < 0 ||
            (s->a->laser && strcmp(s->a->laser, name) != 0) || ls->n == RIG_MAX_LASERS)
                return;
        snprintf(ls->name[ls->n], sizeof(ls->name[0]), "%s", name);
        for (int k = 0; k < 3; k++)
                if (strcmp(ch, channels[k]) == 0)
                        ls->channel[ls->n] = k;
        ls->rows[ls->n++] = n > 1 ? UINT32_C(1) << i : 0;
}

/* The lasers of the dataset's rig file (`lasers`, or the one `laser`; --laser: that one
 * alone), each from the rows it lit alone (any laser row with one laser); without a rig
 * file or a laser in it, one laser, --laser or "laser", red. Returns 0 or -ENOENT (--laser
 * names no laser of the rig file). */
static int lasers_of_rig(struct solve *s, struct laser_set *ls)
{
        char path[PATH_MAX + 16], err[256];
        struct yconf yc = {0};
        struct fy_node *list = NULL, *one = NULL;
        int n;

        *ls = (struct laser_set){0};
        snprintf(path, sizeof(path), "%s/rig.yaml", ds_path(s->d));
        if (yconf_open(&yc, path, err, sizeof(err)) == 0) {
                list = yconf_get(yconf_root(&yc), "lasers");
                one = yconf_get(yconf_root(&yc), "laser");
        }
        n = list ? MAX(yconf_seq_len(&yc, list, "lasers"), 0) : one != NULL;
        for (int i = 0; i < n; i++)
                add_laser(s, &yc, list ? yconf_seq_item(list, i) : one, i, n, ls);
        yconf_close(&yc);
        if (!n)
                snprintf(ls->name[ls->n++], sizeof(ls->name[0]), "%s", s->a->laser ?: "laser");
        if (!ls->n)
                snprintf(s->err, sizeof(s->err), "the dataset's rig file has no laser %s",
                         s->a->laser);
        return ls->n ? 0 : -ENOENT;
}

static json_t *laser_json(const struct cal_file_laser *l, const char *unused, const char *file)
{
        return json_pack("{s:s,s:s,s:{s:o,s:f},s:f,s:f,s:i,s:i,s:i,s:i,s:f,s:f,s:s,s:s}", "laser",
                         l->name, "camera", l->camera, "plane", "n", vec_json(l->plane.n, 3), "d",
                         l->plane.d, "rms_mm", l->rms_mm, "spread_mm", l->spread_mm, "points",
                         (int)l->points, "inliers", (int)l->inliers, "views_used", l->n_used,
                         "views_given", l->n_views, "axis_angle_deg", l->axis_angle_deg,
                         "axis_dist_mm", l->axis_dist_mm, "unused", unused, "file", file);
}

/* The laser's section as written (in the turntable frame) into a summary. */
static int laser_summary(struct solve *s, const char *name, const char *unused, json_t **ret)
{
        _cleanup_free_ struct cal_file *f = malloc(sizeof(*f));
        const struct cal_file_laser *l;
        int r;

        if (!f)
                return -ENOMEM;
        r = cal_file_read(s->file, f, s->err, sizeof(s->err));
        if (r < 0)
                return r;
        l = cal_file_laser(f, name);
        *ret = l ? laser_json(l, unused, s->file) : NULL;
        return 0;
}

/* Puts "NAME: " before s->err. */
static void prefix_err(struct solve *s, const char *name)
{
        char msg[sizeof(s->err)];

        snprintf(msg, sizeof(msg), "%s", s->err);
        snprintf(s->err, sizeof(s->err), "%s: %s", name, msg);
}

/* Writes plane p (turntable frame) of laser `name` over its section in f (the figures of its
 * solve kept), moved into the camera frame of the turntable section tt (the inverse of
 * cal_plane_to_turntable: x_cam = R x_tt + t). */
static int rewrite_plane(struct solve *s, const struct cal_file *f, const struct cal_turntable *tt,
                         const char *name, const double n_tt[3], double d_tt)
{
        const struct cal_file_laser *fl = cal_file_laser(f, name);
        struct cal_laser l;

        if (!fl)
                return -ENOENT;
        l = (struct cal_laser){.rms_mm = fl->rms_mm,
                               .spread_mm = fl->spread_mm,
                               .points = (size_t)fl->points,
                               .inliers = (size_t)fl->inliers,
                               .n_views = fl->n_views,
                               .n_used = fl->n_used};
        cal_mat_vec(tt->R, n_tt, l.plane.n);
        l.plane.d = d_tt - cal_dot(l.plane.n, tt->t);
        snprintf(l.unused, sizeof(l.unused), "refined jointly with the rig's other lasers");
        return cal_laser_write(s->file, name, s->camera, &l, ds_path(s->d), true, s->err,
                               sizeof(s->err));
}

/* The lasers' planes in the file just written, refined jointly (cal_lasers_refine, every
 * plane through the axis, the first laser's kept) on the dataset's laser frames triangulated
 * with them, and written back. The outcome as JSON: refined or why not (the clouds of the
 * capture do not overlap enough: then the planes stay as solved). */
static json_t *refine_lasers(struct solve *s)
{
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        _cleanup_(sec_free) struct sec_ctx c = {0};
        _cleanup_free_ struct cal_file *f = NULL;
        const struct cal_turntable *tt;
        struct cal_lr_opts lo = {.through_axis = true};
        struct cal_lr_result lr;
        struct scan_result sr;
        struct scan_calib cal;
        struct scan_opts so;
        char err[1024] = "";
        int r;

        scan_opts_default(&so);
        so.camera = s->camera;
        if ((r = scan_load_rig(s->d, registry_backends, &rc, err, sizeof(err))) >= 0 &&
            (r = read_calfile(s, false, &f)) >= 0 &&
            (r = scan_calib_from_file(f, rc, s->camera, &cal, err, sizeof(err))) >= 0 &&
            (r = scan_section(s->d, rc, &so, &cal, &c, &sr, err, sizeof(err))) >= 0)
                r = cal_lasers_refine(&c, &lo, &lr, err, sizeof(err));
        if (r < 0)
                return json_pack("{s:b,s:s}", "refined", false, "reason",
                                 err[0] ? err : strerror(-r));
        tt = &cal_file_turntable(f, s->camera)->tt;
        for (int i = 0; r >= 0 && i < c.n_lasers; i++)
                r = rewrite_plane(s, f, tt, rc->lasers[i].name, c.plane_n[i],
                                  -cal_dot(c.plane_n[i], c.plane_p[i]));
        return json_pack("{s:b,s:f,s:f,s:I,s:s*}", "refined", r >= 0, "rms_before_mm",
                         lr.rms_before, "rms_after_mm", lr.rms_after, "pairs",
                         (json_int_t)lr.pairs_after, "reason", r < 0 ? s->err : NULL);
}

/* Solves and writes laser i of ls; its summary into *ret. */
static int solve_one_laser(struct solve *s, const struct laser_set *ls, int i, json_t **ret)
{
        struct cal_lp_opts opts = {
                .board = s->board, .k = s->k, .channel = ls->channel[i], .lasers = ls->rows[i]};
        struct cal_laser l = {0};
        int r = cal_laser_solve_ds(s->d, s->camera, &opts, &l, s->err, sizeof(s->err));

        if (r >= 0)
                r = cal_laser_write(s->file, ls->name[i], s->camera, &l, ds_path(s->d),
                                    s->a->given & ARG_FORCE, s->err, sizeof(s->err));
        if (r >= 0)
                r = laser_summary(s, ls->name[i], l.unused, ret);
        if (r < 0 && ls->n > 1) /* say which laser */
                prefix_err(s, ls->name[i]);
        return r;
}

/* Every laser of the rig (or --laser's), each from the frames it lit alone; with two or more,
 * their planes refined jointly (refine_lasers). The summary is the first laser's, with
 * "lasers": every laser's, and "joint": the refinement. */
static int solve_laser(struct solve *s, json_t **ret)
{
        struct laser_set ls;
        json_t *all = json_array(), *one = NULL;
        int r = all ? lasers_of_rig(s, &ls) : -ENOMEM;

        for (int i = 0; r >= 0 && i < ls.n; i++) {
                r = solve_one_laser(s, &ls, i, &one);
                if (r >= 0 && (!one || json_array_append_new(all, one) < 0))
                        r = -ENOMEM;
        }
        if (r >= 0 && (*ret = json_deep_copy(json_array_get(all, 0))))
                r = json_object_set_new(*ret, "joint", ls.n > 1 ? refine_lasers(s) : json_null());
        if (r >= 0 && *ret)
                json_object_set(*ret, "lasers", all);
        json_decref(all);
        return r;
}

/* ---- lamps ---- */

/* What the lamps' solve reads: the rig file stored with the dataset, the calibration file,
 * the dataset's cameras with their calibration. */
struct lamps_in {
        struct rig_config *rc;
        struct cal_file *f;
        struct cal_lamps_camera cams[DS_SUMMARY_MAX_NAMES];
        size_t n_cams;
};

static void lamps_in_free(struct lamps_in *in)
{
        rigconf_free(in->rc);
        free(in->f);
}

/* The rig file stored with the dataset, the calibration file, and each camera of the
 * dataset with its intrinsics and pose in the turntable frame from the file. */
static int lamps_input(struct solve *s, struct lamps_in *in)
{
        struct ds_summary sum;
        int r = scan_load_rig(s->d, registry_backends, &in->rc, s->err, sizeof(s->err));

        if (r < 0 || (r = read_calfile(s, false, &in->f)) < 0 || (r = ds_summary(s->d, &sum)) < 0)
                return r;
        for (size_t i = 0; i < sum.n_cameras && i < ELEMENTSOF(in->cams); i++) {
                struct cal_lamps_camera *c = &in->cams[in->n_cams++];

                snprintf(c->name, sizeof(c->name), "%s", sum.cameras[i].name);
                r = scan_cal_camera(in->f, c->name, &c->cal, s->err, sizeof(s->err));
                if (r < 0)
                        return r;
        }
        return 0;
}

/* One lamp's line of the summary; source "measured" or "nominal", kept: why the file's
 * section was kept (NULL: written). */
static json_t *lamp_json(const struct cal_lamp_pos *l, const char *source, const char *kept)
{
        return json_pack(
                "{s:s,s:s,s:o,s:f,s:i,s:o*,s:s*}", "lamp", l->name, "source", source, "position_mm",
                vec_json(l->pos, 3), "rms_mm", l->rms_mm, "rays", l->n_obs, "nominal_dist_mm",
                isnan(l->nominal_dist_mm) ? NULL : json_real(l->nominal_dist_mm), "kept", kept);
}

/* Writes l into the file, over a nominal section (no observations) or with --force, else
 * never over a better one; appends its line to arr. Returns as cal_lamp_write, the error in
 * s->err unless one is there. */
static int write_lamp(struct solve *s, const struct cal_file *f, const struct cal_lamp_pos *l,
                      json_t *arr)
{
        const struct cal_lamp_pos *old = cal_file_lamp(f, l->name);
        bool force = (s->a->given & ARG_FORCE) || (old && old->n_obs == 0);
        char err[sizeof(s->err)];
        int r = cal_lamp_write(s->file, l, force, err, sizeof(err));

        json_array_append_new(arr, lamp_json(l, "measured", r < 0 ? err : NULL));
        if (r < 0 && !s->err[0])
                snprintf(s->err, sizeof(s->err), "%s", err);
        return r;
}

/* Why lamp `lamp` (rig index) of the solve gave no position: its views. */
static void lamp_failure(const struct cal_lamps *l, int lamp, char *why, size_t len)
{
        const char *first = NULL;
        int lit = 0, rays = 0;

        for (size_t i = 0; i < l->n_views; i++) {
                const struct cal_lamp_view *v = &l->views[i];
                if (v->lamp != lamp)
                        continue;
                lit++;
                rays += !isnan(v->highlight[0]) && v->sphere.n_edges;
                first = first ?: v->reason[0] ? v->reason : NULL;
        }
        snprintf(why, len, "a highlight on the sphere in %d of the %d views that light it%s%s%s",
                 rays, lit, first ? " (" : "", first ?: "", first ? ")" : "");
}

/* The lamps of the rig the solve gave no position, with why, into arr. */
static void lamps_failed(const struct rig_config *rc, const struct cal_lamps *l, json_t *arr)
{
        for (size_t i = 0; i < rc->n_lamps; i++) {
                char why[CAL_REASON_MAX + 128] = "never lit alone in the dataset";
                bool solved = false;
                for (size_t k = 0; k < l->n_lamps; k++) {
                        if (l->index[k] != (int)i)
                                continue;
                        solved = l->lamps[k].n_obs > 0;
                        lamp_failure(l, (int)i, why, sizeof(why));
                }
                if (!solved)
                        json_array_append_new(arr, json_pack("{s:s,s:s}", "lamp", rc->lamps[i].name,
                                                             "reason", why));
        }
}

/* The summary of a solve, its lamps written into the file. Returns 0 or the first write's
 * error. */
static int lamps_summary(struct solve *s, const struct lamps_in *in, const struct cal_lamps *l,
                         json_t **ret)
{
        json_t *lamps = json_array(), *failed = json_array();
        int r = 0;

        for (size_t k = 0; lamps && k < l->n_lamps; k++)
                if (l->lamps[k].n_obs > 0) {
                        int w = write_lamp(s, in->f, &l->lamps[k], lamps);
                        r = r ?: w;
                }
        if (failed)
                lamps_failed(in->rc, l, failed);
        *ret = json_pack("{s:{s:o,s:f,s:f},s:i,s:i,s:o,s:o,s:s}", "sphere", "centre_mm",
                         vec_json(l->sphere, 3), "rms_mm", l->sphere_rms_mm, "diameter_mm",
                         l->sphere_diam_mm, "views", (int)l->n_views, "views_used", (int)l->n_used,
                         "lamps", lamps, "failed", failed, "file", s->file);
        return r;
}

/* Appends to s->err what the lamps' capture needs on the turntable. */
static void lamps_hint(struct solve *s)
{
        size_t n = strlen(s->err);

        snprintf(s->err + n, sizeof(s->err) - n,
                 " (the sphere goes on the turntable 50 to 150 mm off its axis, all of it in "
                 "view of every camera: docs/calibration.md, \"Lamp positions\")");
}

static int solve_lamps(struct solve *s, json_t **ret)
{
        _cleanup_(lamps_in_free) struct lamps_in in = {0};
        struct cal_lamps_opts o = {.sphere_mm = s->a->sphere_mm,
                                   .lamp_radius_mm = s->a->lamp_radius_mm};
        struct cal_lamps l = {0};
        int r = lamps_input(s, &in), w;

        if (r < 0)
                return r;
        o.rc = in.rc;
        o.cams = in.cams;
        o.n_cams = in.n_cams;
        r = cal_lamps_solve_ds(s->d, &o, &l, s->err, sizeof(s->err));
        if (r < 0 && (r != -ENODATA || !l.n_lamps)) {
                if (r == -ENODATA)
                        lamps_hint(s);
                cal_lamps_clear(&l);
                return r;
        }
        if (r == 0)
                s->err[0] = 0;
        w = lamps_summary(s, &in, &l, ret);
        if (*ret && (r < 0 || w < 0 || json_array_size(json_object_get(*ret, "failed")))) {
                /* some lamps solved: their summary, then why not the others */
                out_result(s->o, calibrate_print_lamps, NULL, *ret);
                json_decref(*ret);
                *ret = NULL;
                if (r == 0 && w == 0)
                        snprintf(s->err, sizeof(s->err),
                                 "some of the rig's lamps were never lit alone in dataset %s: "
                                 "capture each lamp alone",
                                 ds_path(s->d));
        }
        cal_lamps_clear(&l);
        return r < 0 ? r : w < 0 ? w : *ret ? 0 : -ENODATA;
}

static const struct kind lamps_kind = {"lamps", false, false, false, solve_lamps};

/* The rig file of --nominal: the dataset's (--from DATASET) or RIG-FILE; the calibration
 * file (--calibration, else the dataset's or the rig file's) into s->file. Returns an exit
 * code. */
static int nominal_rig(struct solve *s, struct rig_config **rc)
{
        const struct args *a = s->a;
        const char *rig = a->nwords > 2 ? a->words[2] : NULL;
        int r;

        if (!a->from == !rig) {
                args_usage_error(s->what, "--nominal reads the lamps of RIG-FILE or of the rig "
                                          "file of --from DATASET: give one of them");
                return EXIT_USAGE;
        }
        if (a->from) {
                r = prepare(s, a->from, a->calib, &lamps_kind);
                if (r != EXIT_OK)
                        return r;
                r = scan_load_rig(s->d, registry_backends, rc, s->err, sizeof(s->err));
        } else if ((r = rigconf_load_stored(rig, registry_backends, rc, s->err, sizeof(s->err))) ==
                   0) {
                snprintf(s->file, sizeof(s->file), "%s", a->calib ?: (*rc)->calibration);
                if (!s->file[0]) {
                        snprintf(s->err, sizeof(s->err),
                                 "the rig file %s names no calibration file: add 'calibration: "
                                 "PATH' to it, or give --calibration FILE",
                                 rig);
                        r = -EINVAL;
                }
        }
        return r < 0 ? failed(s, r) : EXIT_OK;
}

/* Writes each lamp's nominal position of rc (riggeom, light arm at 0) into the file, with no
 * observations, but not over a measured section unless --force; the summary into *ret. */
static int write_nominal(struct solve *s, const struct rig_config *rc, json_t **ret)
{
        _cleanup_free_ struct cal_file *f = NULL;
        json_t *lamps = json_array();
        int r = read_calfile(s, true, &f);

        for (size_t i = 0; r >= 0 && lamps && i < rc->n_lamps; i++) {
                const struct cal_lamp_pos *old = cal_file_lamp(f, rc->lamps[i].name);
                struct cal_lamp_pos l = {.n_obs = 0};

                if (old && old->n_obs > 0 && !(s->a->given & ARG_FORCE)) {
                        json_array_append_new(lamps, lamp_json(old, "measured", NULL));
                        continue;
                }
                snprintf(l.name, sizeof(l.name), "%s", rc->lamps[i].name);
                riggeom_lamp_position(&rc->lamps[i], 0, l.pos);
                r = cal_lamp_write(s->file, &l, true, s->err, sizeof(s->err));
                json_array_append_new(lamps, lamp_json(&l, "nominal", NULL));
        }
        *ret = r < 0 ? NULL
                     : json_pack("{s:o,s:[],s:s}", "lamps", lamps, "failed", "file", s->file);
        if (r < 0)
                json_decref(lamps);
        return r;
}

/* gonioctl calibrate lamps --nominal. */
static int lamps_nominal(const struct args *a, struct out *o, json_t **ret)
{
        struct solve s = {.a = a, .o = o, .what = "calibrate lamps"};
        struct rig_config *rc = NULL;
        int r = nominal_rig(&s, &rc);

        if (r == EXIT_OK) {
                r = write_nominal(&s, rc, ret);
                r = r < 0 ? failed(&s, r) : *ret ? EXIT_OK : EXIT_PROTOCOL;
        }
        rigconf_free(rc);
        finish(&s);
        return r;
}

/* ---- the commands ---- */

/* Runs one calibration command: prepare, solve (k->fn), summary into *ret. */
static int run(const struct args *a, struct out *o, const struct kind *k, json_t **ret)
{
        char what[32];
        struct solve s = {.a = a, .o = o, .what = what};
        int r;

        snprintf(what, sizeof(what), "calibrate %s", k->name);
        r = start(&s, k);

        if (r == EXIT_OK) {
                r = k->fn(&s, ret);
                r = r < 0 ? failed(&s, r) : *ret ? EXIT_OK : EXIT_PROTOCOL;
        }
        finish(&s);
        return r;
}

int calibrate_camera(const struct args *a, struct out *o, json_t **ret)
{
        static const struct kind k = {"camera", true, true, false, solve_camera};

        return run(a, o, &k, ret);
}

int calibrate_turntable(const struct args *a, struct out *o, json_t **ret)
{
        static const struct kind k = {"turntable", true, true, true, solve_turntable};

        return run(a, o, &k, ret);
}

int calibrate_laser(const struct args *a, struct out *o, json_t **ret)
{
        static const struct kind k = {"laser", true, true, true, solve_laser};

        return run(a, o, &k, ret);
}

int calibrate_lamps(const struct args *a, struct out *o, json_t **ret)
{
        if (a->given & ARG_NOMINAL)
                return lamps_nominal(a, o, ret);
        if (a->nwords > 2) {
                args_usage_error("calibrate lamps", "RIG-FILE goes with --nominal only");
                return EXIT_USAGE;
        }
        return run(a, o, &lamps_kind, ret);
}
#else
static int no_opencv(struct out *o, const char *what)
{
        out_error(o, what, "gonioctl was built without OpenCV (-Dopencv=disabled)");
        return EXIT_INVALID;
}

int calibrate_camera(const struct args *a, struct out *o, json_t **ret)
{
        return no_opencv(o, "calibrate camera");
}

int calibrate_turntable(const struct args *a, struct out *o, json_t **ret)
{
        return no_opencv(o, "calibrate turntable");
}

int calibrate_laser(const struct args *a, struct out *o, json_t **ret)
{
        return no_opencv(o, "calibrate laser");
}

int calibrate_lamps(const struct args *a, struct out *o, json_t **ret)
{
        return no_opencv(o, "calibrate lamps");
}
#endif

/* ---- summaries for people ---- */

static double num(json_t *o, const char *key)
{
        return json_number_value(json_object_get(o, key));
}

static void print_vec(const char *what, json_t *v)
{
        json_t *x;
        size_t i;

        printf("%s [", what);
        json_array_foreach(v, i, x) printf("%s%.4f", i ? " " : "", json_number_value(x));
        printf("]");
}

void calibrate_print_camera(json_t *res)
{
        json_t *rej = json_object_get(res, "rejected"), *v;
        size_t i;

        printf("camera %s: %.0fx%.0f, %.0f views used, %.0f rejected\n",
               json_string_value(json_object_get(res, "camera")), num(res, "width"),
               num(res, "height"), num(res, "views_used"), num(res, "views_rejected"));
        printf("  fx %.3f  fy %.3f  cx %.3f  cy %.3f px\n", num(res, "fx"), num(res, "fy"),
               num(res, "cx"), num(res, "cy"));
        printf("  dist k1 k2 p1 p2 k3:");
        json_array_foreach(json_object_get(res, "dist"), i, v) printf(" %.5g", json_real_value(v));
        printf("\n  reprojection RMS %.3f px\n", num(res, "rms_px"));
        json_array_foreach(rej, i, v)
                printf("  rejected %s: %s\n", json_string_value(json_object_get(v, "file")),
                       json_string_value(json_object_get(v, "reason")));
        printf("written to %s\n", json_string_value(json_object_get(res, "file")));
}

void calibrate_print_turntable(json_t *res)
{
        printf("turntable seen by camera %s: board found in %.0f of %.0f views over %.1f deg\n",
               json_string_value(json_object_get(res, "camera")), num(res, "views_used"),
               num(res, "views_given"), num(res, "span_deg"));
        print_vec("  axis (camera frame)", json_object_get(res, "axis"));
        print_vec(", origin", json_object_get(res, "origin"));
        printf(" mm\n  reprojection RMS %.3f px, circle RMS %.3f mm, board tilt %.2f deg\n",
               num(res, "rms_px"), num(res, "circle_rms_mm"), num(res, "tilt_deg"));
        printf("written to %s\n", json_string_value(json_object_get(res, "file")));
}

/* One laser's summary. */
static void print_laser(json_t *res)
{
        json_t *plane = json_object_get(res, "plane");
        const char *unused = json_string_value(json_object_get(res, "unused"));

        printf("laser %s seen by camera %s: %.0f of %.0f views used, %.0f of %.0f points "
               "inliers\n",
               json_string_value(json_object_get(res, "laser")),
               json_string_value(json_object_get(res, "camera")), num(res, "views_used"),
               num(res, "views_given"), num(res, "inliers"), num(res, "points"));
        print_vec("  plane (turntable frame) n", json_object_get(plane, "n"));
        printf(" d %.4f mm\n  RMS %.4f mm, spread %.1f mm; %.3f deg and %.3f mm from the "
               "turntable axis\n",
               num(plane, "d"), num(res, "rms_mm"), num(res, "spread_mm"),
               num(res, "axis_angle_deg"), num(res, "axis_dist_mm"));
        if (unused && unused[0])
                printf("  not used: %s\n", unused);
}

void calibrate_print_laser(json_t *res)
{
        json_t *all = json_object_get(res, "lasers"), *joint = json_object_get(res, "joint"), *l;
        size_t i;

        if (json_array_size(all) == 0)
                print_laser(res);
        json_array_foreach(all, i, l) print_laser(l);
        if (json_is_true(json_object_get(joint, "refined")))
                printf("refined jointly: the surfaces agree within %.4f mm RMS (%.4f mm before, "
                       "%.0f points matched)\n",
                       num(joint, "rms_after_mm"), num(joint, "rms_before_mm"),
                       num(joint, "pairs"));
        else if (json_is_object(joint))
                printf("not refined jointly: %s\n",
                       json_string_value(json_object_get(joint, "reason")));
        printf("written to %s\n", json_string_value(json_object_get(res, "file")));
}

/* One lamp's line: where, how well, against the nominal geometry; or why not written. */
static void print_lamp(json_t *l)
{
        const char *kept = json_string_value(json_object_get(l, "kept"));
        bool nominal =
                strcmp(json_string_value(json_object_get(l, "source")) ?: "", "nominal") == 0;

        printf("  %s (%s): ", json_string_value(json_object_get(l, "lamp")),
               nominal ? "nominal, from the rig file" : "measured");
        print_vec("position", json_object_get(l, "position_mm"));
        if (!nominal)
                printf(" mm, RMS %.3f mm from %.0f rays, %.2f mm from nominal", num(l, "rms_mm"),
                       num(l, "rays"), num(l, "nominal_dist_mm"));
        else
                printf(" mm");
        printf(kept ? "\n    not written: %s\n" : "\n", kept);
}

void calibrate_print_lamps(json_t *res)
{
        json_t *sphere = json_object_get(res, "sphere"), *l;
        size_t i;

        if (sphere) {
                print_vec("mirror sphere: centre", json_object_get(sphere, "centre_mm"));
                printf(" mm, RMS %.3f mm, diameter %.2f mm; the rays of %.0f of %.0f views "
                       "used\n",
                       num(sphere, "rms_mm"), num(sphere, "diameter_mm"), num(res, "views_used"),
                       num(res, "views"));
        }
        printf("lamps (turntable frame at 0, light arm at 0):\n");
        json_array_foreach(json_object_get(res, "lamps"), i, l) print_lamp(l);
        json_array_foreach(json_object_get(res, "failed"), i, l)
                printf("  %s: failed: %s\n", json_string_value(json_object_get(l, "lamp")),
                       json_string_value(json_object_get(l, "reason")));
        printf("written to %s\n", json_string_value(json_object_get(res, "file")));
}
