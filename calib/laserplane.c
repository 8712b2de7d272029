/* laserplane.c - a laser's plane from the line on a board at several poses (laserplane.h). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/laserplane.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"

#define LP_MAX_CORNERS   1024
#define LP_RANSAC_ITERS  300
#define LP_EDGE_FRACTION 0.15 /* points this fraction of a square from its edges are dropped */
#define LP_LINE_MM       0.5  /* a view's points farther from its line on the board: spurious */

/* True when board point (bx, by) is near the edge between two squares, where the line's
 * centre is pulled towards the white square. */
static bool lp_near_edge(double bx, double by, double sq)
{
        double fx = bx / sq - floor(bx / sq), fy = by / sq - floor(by / sq);
        double m = LP_EDGE_FRACTION;

        return fx < m || fx > 1 - m || fy < m || fy > 1 - m;
}

/* The board's pose in the laser-off frame f: R, t (board to camera). Returns the corners
 * found (0: not found) or -errno. */
static int lp_board_pose(const struct gn_frame *f, const struct cal_lp_opts *o, double R[9],
                         double t[3])
{
        struct cal_image im = {f->data, f->width, f->height, f->channels, f->bits, f->stride};
        double uv[2 * LP_MAX_CORNERS], obj[3 * LP_MAX_CORNERS];

        return cal_board_pose(&o->board, &o->k, &im, uv, obj, LP_MAX_CORNERS, R, t);
}

/* Cuts the rays of the line's pixels uv (2n) with the board's plane (R, t); keeps the points
 * on the board's squares, half a square in from their edge and away from the edges between
 * squares, into pts (3 each, camera frame) and bxy (2 each, board frame). Returns the number
 * kept or -errno. */
static int lp_cut(double *uv, int n, const struct cal_lp_opts *o, const double R[9],
                  const double t[3], double *pts, double *bxy)
{
        const struct cal_board *b = &o->board;
        double m[3] = {R[2], R[5], R[8]}, h = 0.5 * b->square_mm;
        int kept = 0, e;

        if (n == 0)
                return 0;
        if ((e = cal_cv_undistort(uv, n, &o->k, uv)) < 0)
                return e;
        for (int i = 0; i < n; i++) {
                double ray[3] = {uv[2 * i], uv[2 * i + 1], 1}, X[3], d[3], bx, by;
                double s = cal_dot(m, t) / cal_dot(m, ray);
                for (int k = 0; k < 3; k++) {
                        X[k] = s * ray[k];
                        d[k] = X[k] - t[k];
                }
                bx = R[0] * d[0] + R[3] * d[1] + R[6] * d[2]; /* R^T d */
                by = R[1] * d[0] + R[4] * d[1] + R[7] * d[2];
                if (s <= 0 || bx < h || by < h || bx > b->squares_x * b->square_mm - h ||
                    by > b->squares_y * b->square_mm - h || lp_near_edge(bx, by, b->square_mm))
                        continue;
                memcpy(pts + 3 * kept, X, sizeof(X));
                bxy[2 * kept] = bx;
                bxy[2 * kept++ + 1] = by;
        }
        return kept;
}

/* Distance of (x, y) from the line through a and b. */
static double lp_line_dist(const double *a, const double *b, const double *p)
{
        double dx = b[0] - a[0], dy = b[1] - a[1], l = hypot(dx, dy);

        return l > 0 ? fabs(dx * (p[1] - a[1]) - dy * (p[0] - a[0])) / l : INFINITY;
}

/* Keeps (compacted to the front of pts) the points of one view on the straight line that
 * most of them form on the board (RANSAC in the board frame, bxy): speckle and noise off the
 * line go. Returns the number kept. */
static int lp_on_line(double *pts, const double *bxy, int n)
{
        int best_k = 0, ia = 0, ib = 0, k = 0;
        uint64_t s = 0x2545f4914f6cdd1dULL;

        for (int it = 0; it < LP_RANSAC_ITERS && n >= 2; it++) {
                int a, b, c = 0;
                s = s * 6364136223846793005ULL + 1442695040888963407ULL;
                a = (s >> 33) % n;
                s = s * 6364136223846793005ULL + 1442695040888963407ULL;
                b = (s >> 33) % n;
                for (int i = 0; i < n; i++)
                        c += lp_line_dist(bxy + 2 * a, bxy + 2 * b, bxy + 2 * i) <= LP_LINE_MM;
                if (c > best_k) {
                        best_k = c;
                        ia = a;
                        ib = b;
                }
        }
        for (int i = 0; i < n && best_k > 0; i++)
                if (lp_line_dist(bxy + 2 * ia, bxy + 2 * ib, bxy + 2 * i) <= LP_LINE_MM)
                        memmove(pts + 3 * k++, pts + 3 * i, 3 * sizeof(double));
        return k;
}

/* The points of one view into pts (room for 3 x on->height); why says what was wrong when
 * it returns 0. Returns the number of points or -errno. */
static int lp_view(const struct cal_lp_view *v, const struct cal_lp_opts *o, double *pts, char *why,
                   size_t wlen)
{
        int h = v->on->height, n = 0, e;
        double R[9], t[3];
        struct laserline_opts lo;
        _cleanup_free_ float *c = malloc(h * sizeof(float));
        _cleanup_free_ double *uv = malloc(2 * h * sizeof(double));
        _cleanup_free_ double *bxy = malloc(2 * h * sizeof(double));

        if (!c || !uv || !bxy)
                return -ENOMEM;
        if ((e = lp_board_pose(v->board ?: v->off, o, R, t)) <= 0) {
                snprintf(why, wlen, e < 0 ? "laser-off frame unusable" : "board not found");
                return e;
        }
        laserline_opts_default(&lo, o->channel);
        struct laserline_result r = {.centre = c, .n = h};
        if ((e = laserline_extract(v->on, v->off, &lo, &r)) < 0) {
                snprintf(why, wlen, "frames unusable (%s)", strerror(-e));
                return e;
        }
        for (int y = 0; y < h; y++)
                if (!isnan(c[y])) {
                        uv[2 * n] = c[y];
                        uv[2 * n++ + 1] = y;
                }
        if ((e = lp_cut(uv, n, o, R, t, pts, bxy)) < 0)
                return e;
        int k = lp_on_line(pts, bxy, e);
        snprintf(why, wlen,
                 "%d line points, %d on the board away from the squares' edges, %d on one line", n,
                 e, k);
        return k;
}

static double lp_dist(const struct cal_plane *p, const double *x)
{
        return fabs(cal_dot(p->n, x) + p->d);
}

/* Copies the points of pts within tol of p to in (3 each); returns their number. */
static size_t lp_inliers(const double *pts, size_t n, const struct cal_plane *p, double tol,
                         double *in)
{
        size_t k = 0;

        for (size_t i = 0; i < n; i++)
                if (lp_dist(p, pts + 3 * i) <= tol) {
                        if (in)
                                memcpy(in + 3 * k, pts + 3 * i, 3 * sizeof(double));
                        k++;
                }
        return k;
}

/* RANSAC over planes through three of the points (a fixed sequence: reproducible). */
static void lp_ransac(const double *pts, size_t n, double tol, struct cal_plane *best)
{
        uint64_t s = 0x9e3779b97f4a7c15ULL;
        size_t best_k = 0;

        for (int it = 0; it < LP_RANSAC_ITERS; it++) {
                const double *q[3];
                double u[3], w[3];
                struct cal_plane p;
                for (int j = 0; j < 3; j++) {
                        s = s * 6364136223846793005ULL + 1442695040888963407ULL;
                        q[j] = pts + 3 * ((s >> 33) % n);
                }
                for (int k = 0; k < 3; k++) {
                        u[k] = q[1][k] - q[0][k];
                        w[k] = q[2][k] - q[0][k];
                }
                cal_cross(u, w, p.n);
                if (cal_dot(p.n, p.n) < 1e-12)
                        continue;
                cal_normalize(p.n);
                p.d = -cal_dot(p.n, q[0]);
                size_t k = lp_inliers(pts, n, &p, tol, NULL);
                if (k > best_k) {
                        best_k = k;
                        *best = p;
                }
        }
}

/* RANSAC, then least squares on the inliers, twice. */
static int lp_fit(const double *pts, size_t n, double tol, struct cal_laser *out)
{
        _cleanup_free_ double *in = malloc(3 * n * sizeof(double));
        int e = 0;

        if (!in)
                return -ENOMEM;
        if (n < 3)
                return -EINVAL;
        lp_ransac(pts, n, tol, &out->plane);
        for (int pass = 0; pass < 2 && e == 0; pass++) {
                out->inliers = lp_inliers(pts, n, &out->plane, tol, in);
                e = cal_plane_fit(in, out->inliers, &out->plane, &out->rms_mm, &out->spread_mm);
        }
        out->points = n;
        if (out->plane.d > 0) /* the camera on the negative side */
                for (int k = 0; k < 3; k++)
                        out->plane.n[k] = -out->plane.n[k];
        out->plane.d = -fabs(out->plane.d);
        return e;
}

/* Appends "view i (why)" to the list of views without the line in bad. */
static void lp_note(char *bad, size_t len, size_t i, const char *why)
{
        size_t l = strlen(bad);

        if (l + 1 < len)
                snprintf(bad + l, len - l, "%sview %zu (%s)", l ? ", " : "", i, why);
}

/* Gathers the points of every view into pts (3 x height each); the views without the line in
 * bad. Returns the number of points or -errno. */
static int lp_gather(const struct cal_lp_view *v, size_t n, const struct cal_lp_opts *o,
                     int min_points, double *pts, struct cal_laser *out, char *bad, size_t blen)
{
        size_t np = 0;
        char why[128];

        for (size_t i = 0; i < n; i++) {
                int k = lp_view(&v[i], o, pts + 3 * np, why, sizeof(why));
                if (k < 0 && k != -EINVAL)
                        return k;
                if (k < min_points) {
                        lp_note(bad, blen, i, why);
                        continue;
                }
                np += k;
                out->n_used++;
        }
        return np;
}

int cal_laser_solve(const struct cal_lp_view *v, size_t n, const struct cal_lp_opts *o,
                    struct cal_laser *out, char *err, size_t errlen)
{
        int min_views = o->min_views > 0 ? o->min_views : CAL_LP_MIN_VIEWS;
        int min_points = o->min_points > 0 ? o->min_points : CAL_LP_MIN_POINTS;
        size_t rows = 0;
        int np, e;

        memset(out, 0, sizeof(*out));
        out->n_views = n;
        for (size_t i = 0; i < n; i++)
                rows += v[i].on ? v[i].on->height : 0;
        for (size_t i = 0; i < n; i++)
                if (!v[i].on || !(v[i].off || v[i].board) || !cal_board_valid(&o->board)) {
                        snprintf(err, errlen, "view %zu: no frame, or a bad board", i);
                        return -EINVAL;
                }
        _cleanup_free_ double *pts = malloc((3 * rows + 3) * sizeof(double));
        if (!pts)
                return -ENOMEM;
        if ((np = lp_gather(v, n, o, min_points, pts, out, out->unused, sizeof(out->unused))) < 0) {
                snprintf(err, errlen, "%s", cal_cv_last_error());
                return np;
        }
        if (out->n_used < min_views) {
                snprintf(err, errlen,
                         "no laser line found on the board in %zu of %zu views: %s; need the line "
                         "across the board in at least %d: is the laser on, and does its line "
                         "cross the board where the camera sees it?",
                         n - out->n_used, n, out->unused, min_views);
                return -ENODATA;
        }
        if ((e = lp_fit(pts, np, o->inlier_mm > 0 ? o->inlier_mm : CAL_LP_INLIER_MM, out)) < 0)
                return e;
        if (out->spread_mm < 1.0) {
                snprintf(err, errlen,
                         "the laser points lie on one line (%.2f mm across it): tilt the board "
                         "or move it along the laser between views",
                         out->spread_mm);
                return -ENODATA;
        }
        return 0;
}

void cal_laser_vs_axis(const struct cal_plane *p, const struct cal_turntable *tt, double *angle_deg,
                       double *dist_mm)
{
        *angle_deg = asin(fmin(fabs(cal_dot(p->n, tt->axis)), 1)) * 180 / M_PI;
        *dist_mm = lp_dist(p, tt->origin);
}

void cal_laser_agreement(const struct cal_plane *a, const struct cal_plane *b,
                         const struct cal_turntable *tt, double *angle_deg, double *dist_mm)
{
        double c = fabs(cal_dot(a->n, b->n)), A[9], x[3];

        *angle_deg = acos(fmin(c, 1)) * 180 / M_PI;
        *dist_mm = 0;
        if (!tt)
                return;
        for (int k = 0; k < 3; k++) {
                A[k] = a->n[k];
                A[3 + k] = b->n[k];
                A[6 + k] = tt->axis[k];
        }
        x[0] = -a->d;
        x[1] = -b->d;
        x[2] = cal_dot(tt->axis, tt->origin);
        if (*angle_deg > 0.01 && cal_solve(A, x, 3) == 0) { /* the planes' common line */
                double d[3] = {x[0] - tt->origin[0], x[1] - tt->origin[1], x[2] - tt->origin[2]};
                *dist_mm = sqrt(cal_dot(d, d));
        } else { /* parallel: their distance at the axis origin */
                double s = cal_dot(a->n, b->n) < 0 ? -1 : 1;
                *dist_mm = fabs(cal_dot(a->n, tt->origin) + a->d -
                                s * (cal_dot(b->n, tt->origin) + b->d));
        }
}

void cal_plane_to_turntable(const struct cal_plane *cam, const struct cal_turntable *tt,
                            struct cal_plane *out)
{
        double n[3];

        for (int k = 0; k < 3; k++)
                n[k] = tt->R[k] * cam->n[0] + tt->R[3 + k] * cam->n[1] + tt->R[6 + k] * cam->n[2];
        out->d = cam->d + cal_dot(cam->n, tt->t);
        memcpy(out->n, n, sizeof(n));
}
