/* lamps_ba.c - the joint refinement of the mirror sphere's centre and the lamps' positions
 * (see lamps_internal.h): Levenberg-Marquardt with a numerical Jacobian on the highlights,
 * each predicted as the specular point of its lamp's centre on the sphere, and on the
 * silhouettes' axes. The rays' least-squares point (lamps.c) has the sphere's centre from the
 * silhouettes alone, whose error of a tenth of a pixel across the view turns the normals; the
 * highlights pin the centre where the lamps' reflections put it. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "calib/lamps_internal.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"

#define BA_ITER          50
#define BA_STEP_MM       1e-5 /* numerical derivative step */
#define BA_TRIES         8    /* damping increases per iteration before giving up */
#define SIL_WEIGHT       0.1  /* a silhouette's axis against a highlight (their px errors) */
#define SPECULAR_ITER    60
#define SPECULAR_TOL     1e-12
#define REFLECTION_EDGES 32 /* points on the outline of a lamp's reflection */

/* The problem: views, per view the lamp's parameter slot (-1: no highlight term) and the
 * highlight undistorted; parameters: the sphere's centre, then each solved lamp's position. */
struct ba {
        const struct cal_lamp_view *v;
        size_t n;
        const struct cal_lamps_opts *o;
        int *slot;
        double (*h)[2];   /* the highlights, undistorted */
        double (*off)[2]; /* the centroids' offsets (update_offsets) */
        int np, nr;
};

/* The point q of the sphere (centre s, radius rs) reflecting l towards c: its normal
 * bisects the directions to c and l (fixed-point iteration from the centre's bisector). */
static void specular(const double s[3], double rs, const double c[3], const double l[3],
                     double q[3])
{
        double n[3] = {0}, a[3], b[3];

        memcpy(q, s, 3 * sizeof(double));
        for (int it = 0; it < SPECULAR_ITER; it++) {
                double prev[3] = {n[0], n[1], n[2]};
                for (int k = 0; k < 3; k++) {
                        a[k] = c[k] - q[k];
                        b[k] = l[k] - q[k];
                }
                cal_normalize(a);
                cal_normalize(b);
                for (int k = 0; k < 3; k++)
                        n[k] = a[k] + b[k];
                cal_normalize(n);
                for (int k = 0; k < 3; k++)
                        q[k] = s[k] + rs * n[k];
                if (fabs(n[0] - prev[0]) + fabs(n[1] - prev[1]) + fabs(n[2] - prev[2]) <
                    SPECULAR_TOL)
                        break;
        }
}

/* True when the ray (x, y, 1) of the camera (camera frame, the sphere at s and the lamp at
 * l there) is reflected by the sphere into the lamp's ball of radius rl. */
static bool sees_lamp(const double s[3], double rs, const double l[3], double rl, double x,
                      double y)
{
        double d[3] = {x, y, 1}, b, disc, p[3], n[3], r[3], lp[3], t;

        cal_normalize(d);
        b = cal_dot(d, s);
        disc = b * b - (cal_dot(s, s) - rs * rs);
        if (disc < 0)
                return false;
        for (int k = 0; k < 3; k++) {
                p[k] = (b - sqrt(disc)) * d[k];
                n[k] = (p[k] - s[k]) / rs;
        }
        for (int k = 0; k < 3; k++) {
                r[k] = d[k] - 2 * cal_dot(d, n) * n[k];
                lp[k] = l[k] - p[k];
        }
        t = cal_dot(lp, r);
        return t > 0 && cal_dot(lp, lp) - t * t <= rl * rl;
}

/* The edge of the lamp's reflection from x0 along direction a (normalised coordinates), by
 * doubling then bisection. */
static double reflection_edge(const double s[3], double rs, const double l[3], double rl,
                              const double x0[2], double a)
{
        double c = cos(a), sn = sin(a), lo = 0, hi = 1e-4;

        for (int i = 0; i < 30 && sees_lamp(s, rs, l, rl, x0[0] + hi * c, x0[1] + hi * sn); i++) {
                lo = hi;
                hi *= 2;
        }
        for (int i = 0; i < 40; i++) {
                double mid = (lo + hi) / 2;
                if (sees_lamp(s, rs, l, rl, x0[0] + mid * c, x0[1] + mid * sn))
                        lo = mid;
                else
                        hi = mid;
        }
        return lo;
}

/* The centroid's offset from x0 (the specular point of the lamp's centre, normalised
 * coordinates) of the whole reflection of a lamp of radius rl: the mirror squeezes it
 * towards the rim, so its centroid is not x0 (the polygon of REFLECTION_EDGES edge points). */
static void reflection_offset(const double s[3], double rs, const double l[3], double rl,
                              const double x0[2], double off[2])
{
        double e[REFLECTION_EDGES][2], area = 0, cx = 0, cy = 0;

        off[0] = off[1] = 0;
        if (!(rl > 0))
                return;
        for (int k = 0; k < REFLECTION_EDGES; k++) {
                double a = 2 * M_PI * k / REFLECTION_EDGES;
                double t = reflection_edge(s, rs, l, rl, x0, a);
                e[k][0] = t * cos(a);
                e[k][1] = t * sin(a);
        }
        for (int k = 0; k < REFLECTION_EDGES; k++) {
                const double *p = e[k], *q = e[(k + 1) % REFLECTION_EDGES];
                double cr = p[0] * q[1] - q[0] * p[1];
                area += cr / 2;
                cx += (p[0] + q[0]) * cr / 6;
                cy += (p[1] + q[1]) * cr / 6;
        }
        if (area > 0) {
                off[0] = cx / area;
                off[1] = cy / area;
        }
}

/* World point x in camera cam's frame into y. */
static void to_camera(const struct sec_camera *cam, const double x[3], double y[3])
{
        cal_mat_vec(cam->R, x, y);
        for (int k = 0; k < 3; k++)
                y[k] += cam->t[k];
}

/* The residuals of view i for parameters p into r; returns how many (0, 2 or 4). */
static int view_residuals(const struct ba *b, size_t i, const double *p, double *r)
{
        const struct cal_lamp_view *v = &b->v[i];
        const struct sec_camera *cam = &b->o->cams[v->camera].cal;
        double s[3], x[3], e1[3], e2[3], l[3], c[3], q[3];
        int k = 0;

        cal_lamps_rot_z(p, cal_lamps_angle(v->turntable_deg), s);
        if (v->sphere_used) {
                to_camera(cam, s, x);
                cal_normalize(x);
                cal_basis(v->sphere.axis, e1, e2);
                r[k++] = SIL_WEIGHT * cam->k.fx * cal_dot(x, e1);
                r[k++] = SIL_WEIGHT * cam->k.fy * cal_dot(x, e2);
        }
        if (b->slot[i] < 0)
                return k;
        cal_lamps_rot_z(p + 3 + 3 * b->slot[i], cal_lamps_angle(v->light_arm_deg), l);
        cal_lamps_camera_centre(cam, c);
        specular(s, b->o->sphere_mm / 2, c, l, q);
        to_camera(cam, q, x);
        r[k++] = cam->k.fx * (x[0] / x[2] + b->off[i][0] - b->h[i][0]);
        r[k++] = cam->k.fy * (x[1] / x[2] + b->off[i][1] - b->h[i][1]);
        return k;
}

/* The offsets of the highlights' centroids from the specular points of the lamps' centres
 * (reflection_offset) at parameters p. */
static void update_offsets(const struct ba *b, const double *p)
{
        for (size_t i = 0; i < b->n; i++) {
                const struct cal_lamp_view *v = &b->v[i];
                const struct sec_camera *cam = &b->o->cams[v->camera].cal;
                double s[3], l[3], sc[3], lc[3], r[4], x0[2];
                b->off[i][0] = b->off[i][1] = 0;
                if (b->slot[i] < 0 || view_residuals(b, i, p, r) < 2)
                        continue;
                x0[0] = b->h[i][0] + r[v->sphere_used ? 2 : 0] / cam->k.fx;
                x0[1] = b->h[i][1] + r[v->sphere_used ? 3 : 1] / cam->k.fy;
                cal_lamps_rot_z(p, cal_lamps_angle(v->turntable_deg), s);
                cal_lamps_rot_z(p + 3 + 3 * b->slot[i], cal_lamps_angle(v->light_arm_deg), l);
                to_camera(cam, s, sc);
                to_camera(cam, l, lc);
                reflection_offset(sc, b->o->sphere_mm / 2, lc, b->o->lamp_radius_mm, x0, b->off[i]);
        }
}

/* All residuals for p into r; returns their sum of squares. */
static double residuals(const struct ba *b, const double *p, double *r)
{
        double ss = 0;
        int k = 0;

        for (size_t i = 0; i < b->n; i++)
                k += view_residuals(b, i, p, r + k);
        for (int j = 0; j < k; j++)
                ss += r[j] * r[j];
        return ss;
}

/* The normal equations J^T J (A) and J^T r (g) at p, J by forward differences; J and r2
 * are scratch arrays of nr * np and nr. */
static void normal_equations(const struct ba *b, double *p, const double *r, double *J, double *r2,
                             double *A, double *g)
{
        for (int j = 0; j < b->np; j++) {
                double keep = p[j];
                p[j] += BA_STEP_MM;
                residuals(b, p, r2);
                p[j] = keep;
                for (int i = 0; i < b->nr; i++)
                        J[(size_t)i * b->np + j] = (r2[i] - r[i]) / BA_STEP_MM;
        }
        for (int a = 0; a < b->np; a++) {
                g[a] = 0;
                for (int i = 0; i < b->nr; i++)
                        g[a] += J[(size_t)i * b->np + a] * r[i];
                for (int c = 0; c < b->np; c++) {
                        double s = 0;
                        for (int i = 0; i < b->nr; i++)
                                s += J[(size_t)i * b->np + a] * J[(size_t)i * b->np + c];
                        A[a * b->np + c] = s;
                }
        }
}

/* One damped step from p (cost *cost, residuals r) into p, increasing *lambda until the cost
 * drops. Returns 1 (a step taken), 0 (no damping helped: converged) or -ENOMEM. */
static int lm_step(const struct ba *b, double *p, double *r, double *cost, double *lambda,
                   const double *A, const double *g)
{
        int np = b->np;
        _cleanup_free_ double *M = malloc(sizeof(double) * np * np);
        _cleanup_free_ double *d = malloc(sizeof(double) * np);
        _cleanup_free_ double *q = malloc(sizeof(double) * np);
        _cleanup_free_ double *rq = malloc(sizeof(double) * b->nr);

        if (!M || !d || !q || !rq)
                return -ENOMEM;
        for (int t = 0; t < BA_TRIES; t++, *lambda *= 10) {
                memcpy(M, A, sizeof(double) * np * np);
                for (int j = 0; j < np; j++) {
                        M[j * np + j] *= 1 + *lambda;
                        d[j] = -g[j];
                }
                if (cal_solve(M, d, np) < 0)
                        continue;
                for (int j = 0; j < np; j++)
                        q[j] = p[j] + d[j];
                double c = residuals(b, q, rq);
                if (c < *cost) {
                        memcpy(p, q, sizeof(double) * np);
                        memcpy(r, rq, sizeof(double) * b->nr);
                        double gain = *cost - c;
                        *lambda /= 10;
                        *cost = c;
                        return gain > 1e-12 * (c + gain);
                }
        }
        return 0;
}

/* Levenberg-Marquardt from p. Returns 0, -ENOMEM or -EDOM (not finite). */
static int lm(const struct ba *b, double *p)
{
        size_t np = b->np, nr = b->nr;
        _cleanup_free_ double *J = malloc(sizeof(double) * nr * np);
        _cleanup_free_ double *r = malloc(sizeof(double) * nr);
        _cleanup_free_ double *r2 = malloc(sizeof(double) * nr);
        _cleanup_free_ double *A = malloc(sizeof(double) * np * np);
        _cleanup_free_ double *g = malloc(sizeof(double) * np);
        double lambda = 1e-3, cost;
        int e = 1;

        if (!J || !r || !r2 || !A || !g)
                return -ENOMEM;
        cost = residuals(b, p, r);
        for (int it = 0; it < BA_ITER && e == 1; it++) {
                normal_equations(b, p, r, J, r2, A, g);
                e = lm_step(b, p, r, &cost, &lambda, A, g);
        }
        return e < 0 ? e : isfinite(cost) ? 0 : -EDOM;
}

/* The parameter slot of each view's lamp (-1: not used, or the lamp not solved) and its
 * highlight undistorted; the counts. */
static int ba_setup(struct ba *b, const struct cal_lamps *out)
{
        b->np = 3;
        b->nr = 0;
        for (size_t i = 0; i < b->n; i++) {
                const struct cal_lamp_view *v = &b->v[i];
                b->slot[i] = -1;
                b->nr += v->sphere_used ? 2 : 0;
                for (size_t k = 0, s = 0; v->used && k < out->n_lamps; k++) {
                        if (!(out->lamps[k].n_obs > 0))
                                continue;
                        if (out->index[k] == v->lamp &&
                            sec_undistort(&b->o->cams[v->camera].cal.k, v->highlight[0],
                                          v->highlight[1], b->h[i]) == 0) {
                                b->slot[i] = (int)s;
                                b->nr += 2;
                        }
                        s++;
                }
        }
        for (size_t k = 0; k < out->n_lamps; k++)
                b->np += out->lamps[k].n_obs > 0 ? 3 : 0;
        return b->nr >= b->np ? 0 : -EDOM;
}

int cal_lamps_refine(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                     struct cal_lamps *out)
{
        _cleanup_free_ int *slot = calloc(n ? n : 1, sizeof(*slot));
        _cleanup_free_ double(*h)[2] = calloc(n ? n : 1, sizeof(*h));
        _cleanup_free_ double(*off)[2] = calloc(n ? n : 1, sizeof(*off));
        double p[3 + 3 * RIG_MAX_LAMPS];
        struct ba b = {v, n, o, slot, h, off, 0, 0};
        int e;

        if (!slot || !h || !off)
                return -ENOMEM;
        if ((e = ba_setup(&b, out)) < 0)
                return e;
        memcpy(p, out->sphere, sizeof(out->sphere));
        for (size_t k = 0, s = 0; k < out->n_lamps; k++)
                if (out->lamps[k].n_obs > 0)
                        memcpy(p + 3 + 3 * s++, out->lamps[k].pos, sizeof(out->lamps[k].pos));
        for (int pass = 0; pass < 2; pass++) { /* the offsets move little with p */
                update_offsets(&b, p);
                if ((e = lm(&b, p)) < 0)
                        return e;
        }
        memcpy(out->sphere, p, sizeof(out->sphere));
        for (size_t i = 0; i < n; i++) {
                v[i].offset[0] = off[i][0] * o->cams[v[i].camera].cal.k.fx;
                v[i].offset[1] = off[i][1] * o->cams[v[i].camera].cal.k.fy;
        }
        for (size_t k = 0, s = 0; k < out->n_lamps; k++)
                if (out->lamps[k].n_obs > 0)
                        memcpy(out->lamps[k].pos, p + 3 + 3 * s++, sizeof(out->lamps[k].pos));
        return 0;
}
