/* turntable.c - the turntable axis and a camera's pose in the turntable frame (turntable.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/turntable.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"

#define DEG         (M_PI / 180)
#define MAX_CORNERS 1024
#define N_PARAMS    10

/* The views where the board was found: corners (board mm, pixels), angle, solvePnP pose. */
struct tt_obs {
        int n;
        double obj[3 * MAX_CORNERS], uv[2 * MAX_CORNERS];
        double angle, R[9], t[3];
};

/* The fixed part of the model; params[10] perturb it: the board's rotation at angle 0
 * (RB * rod(p0..2)) and position (tB + p3..5), the axis direction (n0 + p6 e1 + p7 e2) and
 * point (a0 + p8 e1 + p9 e2). */
struct tt_model {
        double RB[9], tB[3], n0[3], a0[3], e1[3], e2[3];
        const struct tt_obs *obs;
        size_t n_obs, n_res;
        const struct cal_intrinsics *k;
};

static void tt_axis(const struct tt_model *m, const double *p, double n[3], double a[3])
{
        for (int i = 0; i < 3; i++) {
                n[i] = m->n0[i] + p[6] * m->e1[i] + p[7] * m->e2[i];
                a[i] = m->a0[i] + p[8] * m->e1[i] + p[9] * m->e2[i];
        }
        cal_normalize(n);
}

static void tt_board(const struct tt_model *m, const double *p, double RB[9], double tB[3])
{
        double dR[9];

        cal_rodrigues(p, dR);
        cal_mat_mul(m->RB, dR, RB);
        for (int i = 0; i < 3; i++)
                tB[i] = m->tB[i] + p[3 + i];
}

/* Pose of the board at turntable angle th (radians): R, t from its pose at angle 0 (RB,
 * tB) turned about the axis (n, a). */
static void tt_turn(const double n[3], const double a[3], double th, const double RB[9],
                    const double tB[3], double R[9], double t[3])
{
        double Rt[9], r[3] = {n[0] * th, n[1] * th, n[2] * th}, d[3];

        cal_rodrigues(r, Rt);
        cal_mat_mul(Rt, RB, R);
        for (int i = 0; i < 3; i++)
                d[i] = tB[i] - a[i];
        cal_mat_vec(Rt, d, t);
        for (int i = 0; i < 3; i++)
                t[i] += a[i];
}

/* Residuals (predicted minus seen pixels) of every corner of every view into r. */
static int tt_residuals(const struct tt_model *m, const double *p, double *r)
{
        double n[3], a[3], RB[9], tB[3], R[9], t[3], X[3 * MAX_CORNERS];
        static const double zero[3] = {0, 0, 0};
        size_t off = 0;

        tt_axis(m, p, n, a);
        tt_board(m, p, RB, tB);
        for (size_t v = 0; v < m->n_obs; v++) {
                const struct tt_obs *o = &m->obs[v];
                tt_turn(n, a, o->angle, RB, tB, R, t);
                for (int j = 0; j < o->n; j++) {
                        cal_mat_vec(R, o->obj + 3 * j, X + 3 * j);
                        for (int i = 0; i < 3; i++)
                                X[3 * j + i] += t[i];
                }
                int e = cal_cv_project(X, o->n, zero, zero, m->k, r + off);
                if (e < 0)
                        return e;
                for (int j = 0; j < 2 * o->n; j++)
                        r[off + j] -= o->uv[j];
                off += 2 * o->n;
        }
        return 0;
}

static double sumsq(const double *r, size_t n)
{
        double s = 0;

        for (size_t i = 0; i < n; i++)
                s += r[i] * r[i];
        return s;
}

/* Normal equations H = J^T J, g = J^T r of the residuals at p (forward differences). */
static int tt_normal_eq(const struct tt_model *m, const double *p, const double *r, double *J,
                        double H[N_PARAMS * N_PARAMS], double g[N_PARAMS])
{
        for (int k = 0; k < N_PARAMS; k++) {
                double q[N_PARAMS], h = k < 3 || (k >= 6 && k < 8) ? 1e-7 : 1e-5;
                memcpy(q, p, sizeof(q));
                q[k] += h;
                int e = tt_residuals(m, q, J + k * m->n_res);
                if (e < 0)
                        return e;
                for (size_t i = 0; i < m->n_res; i++)
                        J[k * m->n_res + i] = (J[k * m->n_res + i] - r[i]) / h;
        }
        for (int a = 0; a < N_PARAMS; a++) {
                g[a] = 0;
                for (size_t i = 0; i < m->n_res; i++)
                        g[a] += J[a * m->n_res + i] * r[i];
                for (int b = 0; b < N_PARAMS; b++) {
                        double s = 0;
                        for (size_t i = 0; i < m->n_res; i++)
                                s += J[a * m->n_res + i] * J[b * m->n_res + i];
                        H[a * N_PARAMS + b] = s;
                }
        }
        return 0;
}

/* One damped step from p: tries growing damping until the cost falls. Returns 1 when it
 * fell (p, r, *cost updated), 0 when no step helps, or -errno. */
static int tt_step(const struct tt_model *m, double *p, double *r, double *J, double *cost,
                   double *lambda)
{
        double H[N_PARAMS * N_PARAMS], g[N_PARAMS], A[N_PARAMS * N_PARAMS], d[N_PARAMS],
                q[N_PARAMS];
        _cleanup_free_ double *r2 = malloc(m->n_res * sizeof(double));
        int e;

        if (!r2)
                return -ENOMEM;
        if ((e = tt_normal_eq(m, p, r, J, H, g)) < 0)
                return e;
        for (; *lambda < 1e12; *lambda *= 10) {
                memcpy(A, H, sizeof(A));
                for (int k = 0; k < N_PARAMS; k++) {
                        A[k * N_PARAMS + k] *= 1 + *lambda;
                        d[k] = -g[k];
                }
                if (cal_solve(A, d, N_PARAMS) < 0)
                        continue;
                for (int k = 0; k < N_PARAMS; k++)
                        q[k] = p[k] + d[k];
                if ((e = tt_residuals(m, q, r2)) < 0)
                        return e;
                double c = sumsq(r2, m->n_res);
                if (c < *cost) {
                        int better = c < *cost * (1 - 1e-12);
                        memcpy(p, q, sizeof(q));
                        memcpy(r, r2, m->n_res * sizeof(double));
                        *cost = c;
                        *lambda = fmax(*lambda / 10, 1e-9);
                        return better;
                }
        }
        return 0;
}

/* Levenberg-Marquardt from p = 0; *rms the final reprojection RMS (px). */
static int tt_refine(const struct tt_model *m, double p[N_PARAMS], double *rms)
{
        _cleanup_free_ double *r = malloc(m->n_res * sizeof(double));
        _cleanup_free_ double *J = malloc(N_PARAMS * m->n_res * sizeof(double));
        double cost, lambda = 1e-3;
        int e;

        if (!r || !J)
                return -ENOMEM;
        memset(p, 0, N_PARAMS * sizeof(double));
        if ((e = tt_residuals(m, p, r)) < 0)
                return e;
        cost = sumsq(r, m->n_res);
        e = 1;
        for (int it = 0; it < 100 && e > 0; it++)
                e = tt_step(m, p, r, J, &cost, &lambda);
        e = e < 0 ? e : 0;
        *rms = sqrt(cost / (m->n_res / 2));
        return e;
}

int cal_board_pose(const struct cal_board *b, const struct cal_intrinsics *k,
                   const struct cal_image *im, double *uv, double *obj, int max, double R[9],
                   double t[3])
{
        _cleanup_free_ int *ids = malloc(max * sizeof(int));
        double xy[2], rv[3];
        int n, e;

        if (!ids)
                return -ENOMEM;
        n = cal_cv_find_corners(b, im, uv, ids, max);
        if (n < 4)
                return n < 0 ? n : 0;
        for (int j = 0; j < n; j++) {
                cal_board_corner_xy(b, ids[j], xy);
                obj[3 * j] = xy[0];
                obj[3 * j + 1] = xy[1];
                obj[3 * j + 2] = 0;
        }
        if ((e = cal_cv_solve_pnp(obj, uv, n, k, rv, t)) < 0)
                return e;
        cal_rodrigues(rv, R);
        return n;
}

/* Finds the board in view v and its pose into o. Returns the corners found (0: not found)
 * or -errno. */
static int tt_detect(const struct cal_tt_view *v, const struct cal_tt_opts *opt, struct tt_obs *o)
{
        int n = cal_board_pose(&opt->board, &opt->k, &v->im, o->uv, o->obj, MAX_CORNERS, o->R,
                               o->t);

        o->n = n > 0 ? n : 0;
        o->angle = v->angle_deg * DEG;
        return n;
}

/* Trajectory point of board corner j (all corners of the board, found or not) in view o. */
static void tt_traj(const struct cal_board *b, const struct tt_obs *o, int j, double P[3])
{
        double xy[2], X[3];

        cal_board_corner_xy(b, j, xy);
        X[0] = xy[0];
        X[1] = xy[1];
        X[2] = 0;
        cal_mat_vec(o->R, X, P);
        for (int i = 0; i < 3; i++)
                P[i] += o->t[i];
}

/* The axis direction: the normal shared by the planes of every corner's trajectory. */
static void tt_axis_dir(const struct cal_board *b, const struct tt_obs *obs, size_t m, double n[3])
{
        double C[9] = {0}, w[3], V[9], P[3];
        int lo = 0;

        for (int j = 0; j < cal_board_corners(b); j++) {
                double c[3] = {0};
                for (size_t v = 0; v < m; v++) {
                        tt_traj(b, &obs[v], j, P);
                        for (int i = 0; i < 3; i++)
                                c[i] += P[i] / m;
                }
                for (size_t v = 0; v < m; v++) {
                        tt_traj(b, &obs[v], j, P);
                        for (int r = 0; r < 3; r++)
                                for (int k = 0; k < 3; k++)
                                        C[r * 3 + k] += (P[r] - c[r]) * (P[k] - c[k]);
                }
        }
        cal_eig3(C, w, V);
        for (int k = 1; k < 3; k++)
                lo = w[k] < w[lo] ? k : lo;
        for (int k = 0; k < 3; k++)
                n[k] = V[k * 3 + lo];
}

/* Turns n to point up: the way that makes the turntable's angles counterclockwise about it. */
static void tt_axis_sign(const struct tt_obs *obs, size_t m, double n[3])
{
        size_t best = 0;
        double M[9], Rt[9], v[3];

        for (size_t i = 1; i < m; i++)
                if (fabs(sin(obs[i].angle - obs[0].angle)) >
                    fabs(sin(obs[best].angle - obs[0].angle)))
                        best = i;
        for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                        Rt[i * 3 + j] = obs[0].R[j * 3 + i];
        cal_mat_mul(obs[best].R, Rt, M);
        v[0] = M[7] - M[5];
        v[1] = M[2] - M[6];
        v[2] = M[3] - M[1];
        if (cal_dot(v, n) * sin(obs[best].angle - obs[0].angle) < 0)
                for (int i = 0; i < 3; i++)
                        n[i] = -n[i];
}

/* A point a of the axis (n) from a circle fit to every corner's trajectory; *rms the RMS
 * distance of the trajectories from their circles (in and out of their planes). */
static int tt_axis_point(const struct cal_board *b, const struct tt_obs *obs, size_t m,
                         const double n[3], double a[3], double *rms)
{
        _cleanup_free_ double *q = malloc(2 * m * sizeof(double));
        double e1[3], e2[3], P[3], c[2], r, s2 = 0;
        int nc = cal_board_corners(b);

        if (!q)
                return -ENOMEM;
        cal_basis(n, e1, e2);
        memset(a, 0, 3 * sizeof(double));
        for (int j = 0; j < nc; j++) {
                double h = 0;
                for (size_t v = 0; v < m; v++) {
                        tt_traj(b, &obs[v], j, P);
                        q[2 * v] = cal_dot(P, e1);
                        q[2 * v + 1] = cal_dot(P, e2);
                        h += cal_dot(P, n) / m;
                }
                if (cal_circle_fit(q, m, c, &r) < 0)
                        return -EDOM;
                for (size_t v = 0; v < m; v++) {
                        tt_traj(b, &obs[v], j, P);
                        double dr = hypot(q[2 * v] - c[0], q[2 * v + 1] - c[1]) - r;
                        double dh = cal_dot(P, n) - h;
                        s2 += dr * dr + dh * dh;
                }
                for (int i = 0; i < 3; i++)
                        a[i] += (c[0] * e1[i] + c[1] * e2[i] + h * n[i]) / nc;
        }
        *rms = sqrt(s2 / (nc * m));
        return 0;
}

/* The model's fixed part from the first axis (n, a) and view 0's pose turned back to 0. */
static void tt_model_init(struct tt_model *m, const struct tt_obs *obs, size_t n_obs,
                          const double n[3], const double a[3])
{
        m->obs = obs;
        m->n_obs = n_obs;
        m->n_res = 0;
        for (size_t v = 0; v < n_obs; v++)
                m->n_res += 2 * obs[v].n;
        memcpy(m->n0, n, sizeof(m->n0));
        memcpy(m->a0, a, sizeof(m->a0));
        cal_basis(n, m->e1, m->e2);
        tt_turn(n, a, -obs[0].angle, obs[0].R, obs[0].t, m->RB, m->tB);
}

/* The result from the refined parameters p. */
static void tt_output(const struct tt_model *m, const double *p, struct cal_turntable *out)
{
        double n[3], a[3], RB[9], tB[3], bn[3], x[3], y[3], d[3];

        tt_axis(m, p, n, a);
        tt_board(m, p, RB, tB);
        for (int i = 0; i < 3; i++) {
                bn[i] = RB[i * 3 + 2];
                d[i] = tB[i] - a[i];
        }
        double s = cal_dot(d, bn) / cal_dot(n, bn), xn = 0;
        for (int i = 0; i < 3; i++)
                out->origin[i] = a[i] + s * n[i];
        for (int i = 0; i < 3; i++)
                xn += RB[i * 3] * n[i];
        for (int i = 0; i < 3; i++)
                x[i] = RB[i * 3] - xn * n[i];
        cal_normalize(x);
        cal_cross(n, x, y);
        for (int i = 0; i < 3; i++) {
                out->axis[i] = n[i];
                out->R[i * 3] = x[i];
                out->R[i * 3 + 1] = y[i];
                out->R[i * 3 + 2] = n[i];
                out->t[i] = out->origin[i];
        }
        out->tilt_deg = acos(fmin(fabs(cal_dot(n, bn)), 1)) / DEG;
}

/* Detects the board in every view; fills obs, *n_obs and the angle span. */
static int tt_detect_all(const struct cal_tt_view *v, size_t n, const struct cal_tt_opts *o,
                         struct tt_obs *obs, size_t *n_obs, double *span, char *err, size_t errlen)
{
        double lo = INFINITY, hi = -INFINITY;

        *n_obs = 0;
        for (size_t i = 0; i < n; i++) {
                int e = tt_detect(&v[i], o, &obs[*n_obs]);
                if (e < 0) {
                        snprintf(err, errlen, "view %zu: %s", i, cal_cv_last_error());
                        return e;
                }
                if (e == 0)
                        continue;
                lo = fmin(lo, v[i].angle_deg);
                hi = fmax(hi, v[i].angle_deg);
                (*n_obs)++;
        }
        *span = *n_obs ? hi - lo : 0;
        return 0;
}

/* Refuses a board whose pose is ambiguous, or that cannot be detected. */
static int tt_check_board(const struct cal_board *b, char *err, size_t errlen)
{
        if (!cal_board_valid(b)) {
                snprintf(err, errlen, "bad board: %dx%d squares of %g mm", b->squares_x,
                         b->squares_y, b->square_mm);
                return -EINVAL;
        }
        if (b->type == CAL_BOARD_CHESSBOARD && b->squares_x % 2 == b->squares_y % 2) {
                snprintf(err, errlen,
                         "a chessboard of %dx%d squares looks the same turned by 180 deg, so its "
                         "pose jumps between views: use one of an odd and an even number of "
                         "squares, or a ChArUco board",
                         b->squares_x, b->squares_y);
                return -EINVAL;
        }
        return 0;
}

int cal_turntable_solve(const struct cal_tt_view *v, size_t n, const struct cal_tt_opts *o,
                        struct cal_turntable *out, char *err, size_t errlen)
{
        int min_views = o->min_views > 0 ? o->min_views : CAL_TT_MIN_VIEWS;
        double min_span = o->min_span_deg > 0 ? o->min_span_deg : CAL_TT_MIN_SPAN_DEG;
        double ax[3], pt[3], p[N_PARAMS];
        struct tt_model m = {.k = &o->k};
        size_t n_obs;
        int e;

        memset(out, 0, sizeof(*out));
        if (!v || (e = tt_check_board(&o->board, err, errlen)) < 0)
                return v ? e : -EINVAL;
        _cleanup_free_ struct tt_obs *obs = calloc(n ? n : 1, sizeof(*obs));
        if (!obs)
                return -ENOMEM;
        if ((e = tt_detect_all(v, n, o, obs, &n_obs, &out->span_deg, err, errlen)) < 0)
                return e;
        out->n_views = n;
        out->n_used = n_obs;
        if (n_obs < (size_t)min_views) {
                snprintf(err, errlen,
                         "board (%dx%d squares) found in only %zu of %zu views, need at least %d: "
                         "lay the whole board flat on the turntable, in view at every angle",
                         o->board.squares_x, o->board.squares_y, n_obs, n, min_views);
                return -ENODATA;
        }
        if (out->span_deg < min_span) {
                snprintf(err, errlen,
                         "the turntable did not turn: the %zu views with the board span %.1f deg "
                         "of turntable angle, need at least %.0f: turn it between views",
                         n_obs, out->span_deg, min_span);
                return -ENODATA;
        }
        tt_axis_dir(&o->board, obs, n_obs, ax);
        tt_axis_sign(obs, n_obs, ax);
        if ((e = tt_axis_point(&o->board, obs, n_obs, ax, pt, &out->circle_rms_mm)) < 0 ||
            (tt_model_init(&m, obs, n_obs, ax, pt), e = tt_refine(&m, p, &out->rms_px)) < 0) {
                snprintf(err, errlen, "the axis fit failed (%s): %s", strerror(-e),
                         cal_cv_last_error());
                return e == -EIO ? e : -EDOM;
        }
        tt_output(&m, p, out);
        return 0;
}
