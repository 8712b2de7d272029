/* camera.c - camera intrinsics from board views in a dataset (camera.h): rows of one camera
 * are read through the ds_ API, the board's corners found by the OpenCV shim, the camera
 * calibrated, outlier views rejected one at a time with a reason. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "calib/camera.h"
#include "common/cleanup.h"
#include "common/sortx.h"

/* The corners found in one view, in board (obj, z = 0) and image (uv) coordinates. */
struct view_pts {
        int n;
        double *obj, *uv;
};

struct solve {
        struct cal_camera_opts o;
        struct cal_camera *out;
        struct view_pts *pts; /* out->n_views */
        size_t cap;
        char *err;
        size_t errlen;
};

_printf_(3, 4) static int fail(struct solve *s, int r, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(s->err, s->errlen, fmt, ap);
        va_end(ap);
        return r;
}

static const char *board_name(const struct cal_board *b)
{
        return b->type == CAL_BOARD_CHARUCO ? "ChArUco" : "chessboard";
}

/* The camera to solve: the one named, or the dataset's only camera. */
static int pick_camera(struct ds *d, struct solve *s)
{
        struct ds_summary sum;
        int r = ds_summary(d, &sum);

        if (r < 0)
                return fail(s, r, "cannot read the index of dataset %s: %s", ds_name(d),
                            ds_last_error(d));
        for (size_t i = 0; i < sum.n_cameras; i++)
                if (!s->o.camera ? sum.n_cameras == 1 : !strcmp(s->o.camera, sum.cameras[i].name)) {
                        snprintf(s->out->camera, sizeof(s->out->camera), "%s", sum.cameras[i].name);
                        return 0;
                }
        if (!s->o.camera && sum.n_cameras > 1)
                return fail(s, -EINVAL, "dataset %s has %zu cameras: name the one to calibrate",
                            ds_name(d), sum.n_cameras);
        return fail(s, -ENOENT, "dataset %s has no captures of camera %s", ds_name(d),
                    s->o.camera ? s->o.camera : "(any)");
}

static int add_row(const struct ds_capture *c, void *userdata)
{
        struct solve *s = userdata;
        struct cal_camera *out = s->out;

        if (strcmp(c->camera, out->camera) || strcmp(c->kind, "image") || c->bracket != 0)
                return 0;
        if (out->n_views == s->cap) {
                size_t cap = MAX(s->cap * 2, 16);
                struct cal_view *v = reallocarray(out->views, cap, sizeof(*v));
                struct view_pts *p = v ? reallocarray(s->pts, cap, sizeof(*p)) : NULL;

                if (v)
                        out->views = v;
                if (!p)
                        return -ENOMEM;
                s->pts = p;
                s->cap = cap;
        }
        out->views[out->n_views] = (struct cal_view){.row_id = c->id, .rms = NAN};
        snprintf(out->views[out->n_views].file, sizeof(out->views[0].file), "%s", c->file);
        s->pts[out->n_views++] = (struct view_pts){0};
        return 0;
}

/* True when the corners span at least two rows and two columns of the board (a single row
 * of points gives no plane). */
static bool spans_plane(const struct cal_board *b, const int *ids, int n)
{
        int nx = b->squares_x - 1;
        bool rows = false, cols = false;

        for (int i = 1; i < n; i++) {
                rows |= ids[i] / nx != ids[0] / nx;
                cols |= ids[i] % nx != ids[0] % nx;
        }
        return rows && cols;
}

/* Finds the board in view i; a view that cannot be used gets its reason. */
static int detect_view(struct ds *d, struct solve *s, size_t i)
{
        struct cal_view *v = &s->out->views[i];
        struct view_pts *p = &s->pts[i];
        const struct cal_board *b = &s->o.board;
        int max = cal_board_corners(b), r;
        _cleanup_free_ int *ids = calloc(max, sizeof(int));
        struct gn_frame f = {0};

        p->uv = calloc(2 * max, sizeof(double));
        p->obj = calloc(3 * max, sizeof(double));
        if (!ids || !p->uv || !p->obj)
                return -ENOMEM;
        r = ds_load_image(d, v->file, &f);
        if (r < 0) {
                snprintf(v->reason, sizeof(v->reason), "cannot read %s: %s", v->file, strerror(-r));
                return 0;
        }
        if (!s->out->width) {
                s->out->width = f.width;
                s->out->height = f.height;
        }
        if (f.width != s->out->width || f.height != s->out->height) {
                snprintf(v->reason, sizeof(v->reason), "image is %dx%d, the first view %dx%d",
                         f.width, f.height, s->out->width, s->out->height);
                gn_frame_free_data(&f);
                return 0;
        }
        struct cal_image im = {f.data, f.width, f.height, f.channels, f.bits, f.stride};
        r = cal_cv_find_corners(b, &im, p->uv, ids, max);
        gn_frame_free_data(&f);
        if (r < 0)
                return fail(s, r, "corner detection failed on %s: %s", v->file,
                            cal_cv_last_error());
        v->corners = r;
        if (r == 0)
                snprintf(v->reason, sizeof(v->reason), "board not found");
        else if (r < s->o.min_corners)
                snprintf(v->reason, sizeof(v->reason), "only %d corners of the board (need %d)", r,
                         s->o.min_corners);
        else if (!spans_plane(b, ids, r))
                snprintf(v->reason, sizeof(v->reason), "the %d corners found lie on one line", r);
        p->n = v->reason[0] ? 0 : r;
        for (int k = 0; k < p->n; k++)
                cal_board_corner_xy(b, ids[k], &p->obj[3 * k]);
        return 0;
}

/* Calibrates with every view that has points and no reason; view_rms gets each used view's
 * RMS (NAN for the others). */
static int fit(struct solve *s, double *view_rms)
{
        struct cal_camera *out = s->out;
        size_t total = 0, n = 0, at = 0;

        for (size_t i = 0; i < out->n_views; i++)
                total += s->pts[i].n;
        _cleanup_free_ double *obj = malloc(3 * total * sizeof(double) + 1);
        _cleanup_free_ double *uv = malloc(2 * total * sizeof(double) + 1);
        _cleanup_free_ int *counts = malloc(out->n_views * sizeof(int) + 1);
        _cleanup_free_ double *vr = malloc(out->n_views * sizeof(double) + 1);
        if (!obj || !uv || !counts || !vr)
                return -ENOMEM;
        for (size_t i = 0; i < out->n_views; i++) {
                const struct view_pts *p = &s->pts[i];
                if (out->views[i].reason[0] || !p->n)
                        continue;
                memcpy(obj + 3 * at, p->obj, 3 * p->n * sizeof(double));
                memcpy(uv + 2 * at, p->uv, 2 * p->n * sizeof(double));
                at += p->n;
                counts[n++] = p->n;
        }
        struct cal_cv_views v = {n, counts, obj, uv};
        struct cal_cv_fit res = {.view_rms = vr};
        int r = cal_cv_calibrate(&v, out->width, out->height, &out->k, &res);
        if (r < 0)
                return fail(s, r, "calibration of camera %s failed: %s", out->camera,
                            cal_cv_last_error());
        out->rms = res.rms;
        memcpy(out->std, res.std, sizeof(out->std));
        for (size_t i = 0, j = 0; i < out->n_views; i++)
                view_rms[i] = out->views[i].reason[0] || !s->pts[i].n ? NAN : vr[j++];
        out->n_used = n;
        return 0;
}

/* The view to reject next: the worst above the threshold, or -1. */
static ssize_t outlier(const struct solve *s, const double *view_rms, double *median)
{
        size_t n = 0, nv = s->out->n_views;
        _cleanup_free_ double *sorted = malloc(nv * sizeof(double) + 1);
        ssize_t worst = -1;

        if (!sorted)
                return -1;
        for (size_t i = 0; i < nv; i++)
                if (!isnan(view_rms[i]))
                        sorted[n++] = view_rms[i];
        qsort(sorted, n, sizeof(double), gn_cmp_double);
        *median = n % 2 ? sorted[n / 2] : (sorted[n / 2 - 1] + sorted[n / 2]) / 2;
        double limit = MAX(s->o.outlier_factor * *median, s->o.outlier_floor_px);
        for (size_t i = 0; i < nv; i++)
                if (!isnan(view_rms[i]) && view_rms[i] > limit &&
                    (worst < 0 || view_rms[i] > view_rms[worst]))
                        worst = (ssize_t)i;
        return worst;
}

/* RMS of view i against the intrinsics solved without it: its board pose by solvePnP, its
 * corners reprojected. NAN when that fails. */
static double rms_against_fit(const struct solve *s, size_t i)
{
        const struct view_pts *p = &s->pts[i];
        _cleanup_free_ double *uv = malloc(2 * p->n * sizeof(double) + 1);
        double rvec[3], tvec[3], sum = 0;

        if (!uv || cal_cv_solve_pnp(p->obj, p->uv, p->n, &s->out->k, rvec, tvec) < 0 ||
            cal_cv_project(p->obj, p->n, rvec, tvec, &s->out->k, uv) < 0)
                return NAN;
        for (int k = 0; k < 2 * p->n; k++)
                sum += (uv[k] - p->uv[k]) * (uv[k] - p->uv[k]);
        return sqrt(sum / p->n);
}

/* Fits, rejects the worst outlier while enough views remain, fits again. */
static int fit_rejecting(struct solve *s)
{
        struct cal_camera *out = s->out;
        _cleanup_free_ double *view_rms = malloc(out->n_views * sizeof(double) + 1);
        double median;
        ssize_t w;
        int r;

        if (!view_rms)
                return -ENOMEM;
        for (;;) {
                r = fit(s, view_rms);
                if (r < 0)
                        return r;
                w = outlier(s, view_rms, &median);
                if (w < 0 || out->n_used <= (size_t)s->o.min_views)
                        break;
                snprintf(out->views[w].reason, sizeof(out->views[w].reason),
                         "reprojection RMS %.2f px is %.1fx the median %.2f px: board moved, "
                         "blurred or misdetected",
                         view_rms[w], view_rms[w] / median, median);
        }
        for (size_t i = 0; i < out->n_views; i++) {
                out->views[i].used = !isnan(view_rms[i]);
                out->views[i].rms = out->views[i].used ? view_rms[i]
                                    : s->pts[i].n      ? rms_against_fit(s, i)
                                                       : NAN;
        }
        return 0;
}

/* The error when too few views show the board. */
static int too_few(struct solve *s, size_t found)
{
        const struct cal_board *b = &s->o.board;
        const struct cal_camera *out = s->out;

        if (!found)
                return fail(s, -ENODATA,
                            "board not found in any of %zu views of camera %s: check the board's "
                            "size in the rig/session (%dx%d squares, %s) matches the printed "
                            "board, that it is lit evenly without glare and in focus, and that "
                            "the camera sees it",
                            out->n_views, out->camera, b->squares_x, b->squares_y, board_name(b));
        return fail(s, -ENODATA,
                    "only %zu of %zu views of camera %s show the board well enough (need at "
                    "least %d): capture more views with the whole %dx%d %s in view, tilted "
                    "differently in each",
                    found, out->n_views, out->camera, s->o.min_views, b->squares_x, b->squares_y,
                    board_name(b));
}

static void defaults(struct solve *s, const struct cal_camera_opts *o)
{
        s->o = *o;
        if (s->o.min_views <= 0)
                s->o.min_views = CAL_MIN_VIEWS_DEFAULT;
        if (s->o.min_corners <= 0)
                s->o.min_corners = CAL_MIN_CORNERS_DEFAULT;
        if (s->o.outlier_factor <= 0)
                s->o.outlier_factor = CAL_OUTLIER_FACTOR;
        if (s->o.outlier_floor_px <= 0)
                s->o.outlier_floor_px = CAL_OUTLIER_FLOOR_PX;
}

static int solve_views(struct ds *d, struct solve *s)
{
        size_t found = 0;
        int r;

        for (size_t i = 0; i < s->out->n_views; i++) {
                r = detect_view(d, s, i);
                if (r < 0)
                        return r;
                found += !s->out->views[i].reason[0];
        }
        if (found < (size_t)s->o.min_views)
                return too_few(s, found);
        return fit_rejecting(s);
}

int cal_camera_solve(struct ds *d, const struct cal_camera_opts *o, struct cal_camera *out,
                     char *err, size_t errlen)
{
        struct solve s = {.out = out, .err = err, .errlen = errlen};
        time_t now = time(NULL);
        int r;

        memset(out, 0, sizeof(*out));
        defaults(&s, o);
        out->board = o->board;
        snprintf(out->dataset, sizeof(out->dataset), "%s", ds_path(d));
        strftime(out->solved, sizeof(out->solved), "%Y-%m-%dT%H:%M:%SZ", gmtime(&now));
        if (!cal_board_valid(&o->board))
                return fail(&s, -EINVAL, "bad board: %dx%d squares of %g mm (marker %g mm)",
                            o->board.squares_x, o->board.squares_y, o->board.square_mm,
                            o->board.marker_mm);
        r = pick_camera(d, &s);
        if (r >= 0)
                r = ds_rows(d, 0, -1, add_row, &s);
        if (r >= 0 && !out->n_views)
                r = fail(&s, -ENOENT, "dataset %s has no images of camera %s", ds_name(d),
                         out->camera);
        if (r >= 0)
                r = solve_views(d, &s);
        for (size_t i = 0; i < out->n_views && s.pts; i++) {
                free(s.pts[i].obj);
                free(s.pts[i].uv);
        }
        free(s.pts);
        return r < 0 ? r : 0;
}

int cal_board_parse(const char *spec, struct cal_board *b)
{
        char type[16], end;
        int n;

        *b = (struct cal_board){0};
        n = sscanf(spec, "%15[a-z]:%dx%d:%lf:%lf%c", type, &b->squares_x, &b->squares_y,
                   &b->square_mm, &b->marker_mm, &end);
        if (n == 4 && !strcmp(type, "chessboard"))
                b->type = CAL_BOARD_CHESSBOARD;
        else if (n == 5 && !strcmp(type, "charuco"))
                b->type = CAL_BOARD_CHARUCO;
        else
                return -EINVAL;
        return cal_board_valid(b) ? 0 : -EINVAL;
}

void cal_camera_clear(struct cal_camera *c)
{
        free(c->views);
        memset(c, 0, sizeof(*c));
}
