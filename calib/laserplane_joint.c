/* laserplane_joint.c - several lasers' planes refined jointly on one scan so that their
 * surfaces agree, and a scan moved onto a new plane (laserplane.h, docs/calibration.md).
 *
 * DESIGN: every point of the cloud is kept as its camera ray (the line's eye and the point),
 * so a plane change moves it along that ray exactly as triangulation would have. Each point of
 * a laser with a normal is matched to the nearest point of every other laser within match_mm
 * (a uniform grid per laser) whose normal agrees; the residual is the symmetric point-to-plane
 * distance along the mean of the two normals, which cancels the bias of a curved surface
 * between two sampled points. Gauss-Newton on three parameters per laser (its normal turned
 * in two directions, its offset) but the reference laser's: a scan tells how the surfaces
 * disagree, not which is right, and letting every plane move lets them drift together (in
 * the tests, both surfaces about 0.04 mm outwards) towards whatever the matching's own small
 * biases prefer. A weak damping towards the calibrated planes settles what the scan cannot tell.
 * Matches are redone every iteration; residuals beyond 3 robust sigmas are left out. */
#include <errno.h>
#include <stdbool.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/laserplane.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define DEG         (M_PI / 180)
#define LR_MAX_P    (3 * SEC_MAX_LASERS)
#define LR_LEVER_MM 50.0 /* length that turns an angle (rad) into mm in the damping */
#define LR_DAMPING  1e-3 /* weight of the damping, per match */
#define LR_NORMAL   0.8  /* least cosine between matched normals */
#define LR_MIN_PAIR 100  /* matches needed */
#define LR_MAX_DEG  1.0  /* a larger change is no calibration error: refused */
#define LR_MAX_MM   2.0
#define LR_CELLS    (1 << 22)
/* converged when a step moves no point (at the lever) by more: finer steps cycle as the
 * matches change */
#define LR_DONE_MM 1e-3

/* One point as its ray: X = e + s d, in the world at its turntable angle (ew, dw) and in the
 * object frame (eo, dob); x its current object-frame point, nrm its normal. */
struct lr_ray {
        double ew[3], dw[3], eo[3], dob[3], x[3], nrm[3];
        int laser;
        size_t pt; /* index in the context */
};

/* The lasers' planes: initial normal n0 with its basis e1, e2 and offset d0; q the changes,
 * those marked fixed stay 0 (the reference laser's; with the axis constraint, all but the
 * turn about the axis). */
struct lr_planes {
        int n;
        bool fixed[LR_MAX_P];
        double n0[SEC_MAX_LASERS][3], e1[SEC_MAX_LASERS][3], e2[SEC_MAX_LASERS][3];
        double d0[SEC_MAX_LASERS], q[LR_MAX_P];
};

/* A uniform grid over one laser's rays: the rays of cell k are idx[start[k] .. start[k+1]). */
struct lr_grid {
        double lo[3], h;
        int dim[3];
        size_t *start, *idx;
};

/* A match: ray i of one laser, ray j of another, the mean normal m and the residual. */
struct lr_pair {
        size_t i, j;
        double m[3], r;
};

static void lr_plane(const struct lr_planes *P, int l, double n[3], double *d)
{
        const double *q = P->q + 3 * l;

        for (int k = 0; k < 3; k++)
                n[k] = P->n0[l][k] + q[0] * P->e1[l][k] + q[1] * P->e2[l][k];
        cal_normalize(n);
        *d = P->d0[l] + q[2];
}

/* Ray a on plane (n, d): its object-frame point X and, when J is not NULL, dX/dq (J[k] the
 * column of parameter k: the normal along e1, e2 and the offset). Returns 0 or -EDOM. */
static int lr_point(const struct lr_ray *a, const double n[3], double d, const double e1[3],
                    const double e2[3], double X[3], double J[3][3])
{
        double den = cal_dot(n, a->dw), s, Xw[3], ds[3];

        if (fabs(den) < 1e-9)
                return -EDOM;
        s = -(cal_dot(n, a->ew) + d) / den;
        for (int k = 0; k < 3; k++) {
                Xw[k] = a->ew[k] + s * a->dw[k];
                X[k] = a->eo[k] + s * a->dob[k];
        }
        if (!J)
                return 0;
        ds[0] = -cal_dot(Xw, e1) / den;
        ds[1] = -cal_dot(Xw, e2) / den;
        ds[2] = -1 / den;
        for (int p = 0; p < 3; p++)
                for (int k = 0; k < 3; k++)
                        J[p][k] = ds[p] * a->dob[k];
        return 0;
}

/* z rotation by deg of v into out. */
static void lr_rot(const double v[3], double deg, double out[3])
{
        double c = cos(deg * DEG), s = sin(deg * DEG);

        out[0] = c * v[0] - s * v[1];
        out[1] = s * v[0] + c * v[1];
        out[2] = v[2];
}

/* The rays of c's points of laser `only` (every laser when -1). Returns their number. */
static size_t lr_rays(const struct sec_ctx *c, int only, struct lr_ray *rays)
{
        size_t n = 0;

        for (size_t li = 0; li < c->n_lines; li++) {
                const struct sec_line *ln = &c->lines[li];
                if (only >= 0 && ln->laser != only)
                        continue;
                for (size_t i = ln->first; i < ln->first + ln->count; i++) {
                        struct lr_ray *a = &rays[n++];
                        const struct sec_point *p = &c->pts[i];
                        for (int k = 0; k < 3; k++) {
                                a->eo[k] = ln->eye[k];
                                a->x[k] = p->x[k];
                                a->dob[k] = p->x[k] - ln->eye[k];
                                a->nrm[k] = p->n[k];
                        }
                        lr_rot(a->eo, ln->turntable_deg, a->ew);
                        lr_rot(a->dob, ln->turntable_deg, a->dw);
                        a->laser = ln->laser;
                        a->pt = i;
                }
        }
        return n;
}

/* Moves every ray's point onto the planes P. Returns 0 or -EDOM. */
static int lr_place(const struct lr_planes *P, struct lr_ray *rays, size_t n)
{
        for (size_t i = 0; i < n; i++) {
                struct lr_ray *a = &rays[i];
                double nv[3], d;
                lr_plane(P, a->laser, nv, &d);
                if (lr_point(a, nv, d, P->e1[a->laser], P->e2[a->laser], a->x, NULL) < 0)
                        return -EDOM;
        }
        return 0;
}

static void lr_grid_free(struct lr_grid *g)
{
        free(g->start);
        free(g->idx);
        memset(g, 0, sizeof(*g));
}

static long lr_cell(const struct lr_grid *g, const double x[3], int off[3])
{
        long c[3];

        for (int k = 0; k < 3; k++) {
                c[k] = (long)floor((x[k] - g->lo[k]) / g->h) + (off ? off[k] : 0);
                if (c[k] < 0 || c[k] >= g->dim[k])
                        return -1;
        }
        return (c[2] * g->dim[1] + c[1]) * g->dim[0] + c[0];
}

/* The grid of the rays of laser l with a normal, cells h mm (larger when there would be
 * too many). Returns 0 or -ENOMEM. */
static int lr_grid_build(const struct lr_ray *rays, size_t n, int l, double h, struct lr_grid *g)
{
        double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        size_t cells;

        memset(g, 0, sizeof(*g));
        g->lo[0] = g->lo[1] = g->lo[2] = INFINITY;
        for (size_t i = 0; i < n; i++)
                for (int k = 0; k < 3 && rays[i].laser == l; k++) {
                        g->lo[k] = fmin(g->lo[k], rays[i].x[k]);
                        hi[k] = fmax(hi[k], rays[i].x[k]);
                }
        if (!isfinite(g->lo[0]))
                hi[0] = hi[1] = hi[2] = g->lo[0] = g->lo[1] = g->lo[2] = 0;
        for (g->h = h;; g->h *= 2) {
                for (int k = 0; k < 3; k++)
                        g->dim[k] = (int)((hi[k] - g->lo[k]) / g->h) + 1;
                cells = (size_t)g->dim[0] * g->dim[1] * g->dim[2];
                if (cells <= LR_CELLS)
                        break;
        }
        g->start = calloc(cells + 1, sizeof(size_t));
        g->idx = malloc((n ? n : 1) * sizeof(size_t));
        if (!g->start || !g->idx)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                if (rays[i].laser == l)
                        g->start[lr_cell(g, rays[i].x, NULL) + 1]++;
        for (size_t k = 0; k < cells; k++)
                g->start[k + 1] += g->start[k];
        for (size_t i = 0; i < n; i++) /* start[k] runs to the end of cell k - 1 ... */
                if (rays[i].laser == l)
                        g->idx[g->start[lr_cell(g, rays[i].x, NULL)]++] = i;
        for (size_t k = cells; k > 0; k--) /* ... and back */
                g->start[k] = g->start[k - 1];
        g->start[0] = 0;
        return 0;
}

/* The nearest ray of grid g to ray a within h with a normal agreeing with a's, or -1. */
static long lr_nearest(const struct lr_grid *g, const struct lr_ray *rays, const struct lr_ray *a,
                       double h)
{
        double best = h * h;
        long j = -1;

        for (int o = 0; o < 27; o++) {
                int off[3] = {o % 3 - 1, o / 3 % 3 - 1, o / 9 - 1};
                long c = lr_cell(g, a->x, off);
                for (size_t k = c < 0 ? 0 : g->start[c]; c >= 0 && k < g->start[c + 1]; k++) {
                        const struct lr_ray *b = &rays[g->idx[k]];
                        double d[3] = {b->x[0] - a->x[0], b->x[1] - a->x[1], b->x[2] - a->x[2]};
                        double d2 = cal_dot(d, d);
                        if (d2 < best && cal_dot(a->nrm, b->nrm) > LR_NORMAL) {
                                best = d2;
                                j = (long)g->idx[k];
                        }
                }
        }
        return j;
}

/* Matches every ray with a normal to the nearest ray of each other laser (grids g) within h;
 * keeps the pairs within 3 robust sigmas (and at least 0.01 mm). Returns the number kept. */
static size_t lr_match(const struct lr_ray *rays, size_t n, const struct lr_grid *g, int lasers,
                       double h, struct lr_pair *pairs, double *abs_r)
{
        size_t np = 0, kept = 0;

        for (size_t i = 0; i < n; i++)
                for (int m = 0; m < lasers; m++) {
                        const struct lr_ray *a = &rays[i];
                        long j = m == a->laser ? -1 : lr_nearest(&g[m], rays, a, h);
                        if (j < 0)
                                continue;
                        struct lr_pair *p = &pairs[np];
                        for (int k = 0; k < 3; k++)
                                p->m[k] = a->nrm[k] + rays[j].nrm[k];
                        cal_normalize(p->m);
                        p->i = i;
                        p->j = (size_t)j;
                        p->r = p->m[0] * (a->x[0] - rays[j].x[0]) +
                               p->m[1] * (a->x[1] - rays[j].x[1]) +
                               p->m[2] * (a->x[2] - rays[j].x[2]);
                        abs_r[np++] = fabs(p->r);
                }
        if (np == 0)
                return 0;
        qsort(abs_r, np, sizeof(double), gn_cmp_double);
        double lim = fmax(3 * 1.4826 * abs_r[np / 2], 0.01);
        for (size_t k = 0; k < np; k++)
                if (fabs(pairs[k].r) <= lim)
                        pairs[kept++] = pairs[k];
        return kept;
}

/* Matches the rays as they are now: the grids, then lr_match. Returns the pairs or -ENOMEM. */
static long lr_match_all(const struct lr_ray *rays, size_t n, int lasers, double h,
                         struct lr_pair *pairs, double *abs_r)
{
        struct lr_grid g[SEC_MAX_LASERS] = {0};
        long np = 0;

        for (int l = 0; l < lasers && np == 0; l++)
                if (lr_grid_build(rays, n, l, h, &g[l]) < 0)
                        np = -ENOMEM;
        if (np == 0)
                np = (long)lr_match(rays, n, g, lasers, h, pairs, abs_r);
        for (int l = 0; l < lasers; l++)
                lr_grid_free(&g[l]);
        return np;
}

/* The agreement of the pairs: their RMS and each laser's mean signed distance from the
 * others' surfaces (positive: outside). */
static void lr_stats(const struct lr_ray *rays, const struct lr_pair *pairs, size_t np, int lasers,
                     double *rms, double *offset)
{
        double s2 = 0, sum[SEC_MAX_LASERS] = {0};
        size_t cnt[SEC_MAX_LASERS] = {0};

        for (size_t k = 0; k < np; k++) {
                int l = rays[pairs[k].i].laser;
                s2 += pairs[k].r * pairs[k].r;
                sum[l] += pairs[k].r;
                cnt[l]++;
        }
        *rms = np ? sqrt(s2 / np) : NAN;
        for (int l = 0; l < lasers; l++)
                offset[l] = cnt[l] ? sum[l] / cnt[l] : NAN;
}

/* Adds the pair's row (dr/dq) to the normal equations H, g. */
static void lr_accumulate(const struct lr_planes *P, const struct lr_ray *rays,
                          const struct lr_pair *pr, double *H, double *g)
{
        double row[LR_MAX_P] = {0}, n[3], d, X[3], J[3][3];
        int np = 3 * P->n;

        for (int side = 0; side < 2; side++) {
                const struct lr_ray *a = &rays[side ? pr->j : pr->i];
                int l = a->laser;
                lr_plane(P, l, n, &d);
                if (lr_point(a, n, d, P->e1[l], P->e2[l], X, J) < 0)
                        return;
                for (int p = 0; p < 3; p++)
                        row[3 * l + p] += (side ? -1 : 1) * cal_dot(pr->m, J[p]);
        }
        for (int a = 0; a < np; a++) {
                g[a] += row[a] * pr->r;
                for (int b = 0; b < np; b++)
                        H[a * np + b] += row[a] * row[b];
        }
}

/* One Gauss-Newton step on the pairs, damped towards the calibrated planes; *step the
 * largest change of a point it makes (mm, at the lever). Returns 0 or -EDOM. */
static int lr_step(struct lr_planes *P, const struct lr_ray *rays, const struct lr_pair *pairs,
                   size_t np, double *step)
{
        int n = 3 * P->n;
        double H[LR_MAX_P * LR_MAX_P] = {0}, g[LR_MAX_P] = {0};
        double lambda = LR_DAMPING * (double)np;

        for (size_t k = 0; k < np; k++)
                lr_accumulate(P, rays, &pairs[k], H, g);
        for (int a = 0; a < n; a++) {
                double w = lambda * (a % 3 == 2 ? 1 : LR_LEVER_MM * LR_LEVER_MM);
                H[a * n + a] += w;
                g[a] = -(g[a] + w * P->q[a]);
        }
        for (int a = 0; a < n; a++) {
                if (!P->fixed[a])
                        continue;
                for (int b = 0; b < n; b++)
                        H[a * n + b] = H[b * n + a] = 0;
                H[a * n + a] = 1;
                g[a] = 0;
        }
        if (cal_solve(H, g, n) < 0)
                return -EDOM;
        *step = 0;
        for (int a = 0; a < n; a++) {
                P->q[a] += g[a];
                *step = fmax(*step, fabs(g[a]) * (a % 3 == 2 ? 1 : LR_LEVER_MM));
        }
        return 0;
}

/* The planes of c's lasers as the starting point, no change yet. */
static void lr_init(const struct sec_ctx *c, struct lr_planes *P)
{
        memset(P, 0, sizeof(*P));
        P->n = c->n_lasers;
        for (int l = 0; l < c->n_lasers; l++) {
                memcpy(P->n0[l], c->plane_n[l], sizeof(P->n0[l]));
                cal_normalize(P->n0[l]);
                P->d0[l] = -cal_dot(P->n0[l], c->plane_p[l]);
                cal_basis(P->n0[l], P->e1[l], P->e2[l]);
        }
}

/* Constrains the planes P: laser ref stays; with through_axis every plane is first moved to
 * the nearest plane containing the turntable axis (z) and may then only turn about it.
 * Returns 0, or -EINVAL for a plane that cannot contain the axis (its normal along it). */
static int lr_constrain(struct lr_planes *P, int ref, bool through_axis)
{
        for (int p = 0; p < 3; p++)
                P->fixed[3 * ref + p] = true;
        for (int l = 0; l < P->n && through_axis; l++) {
                double *n = P->n0[l], h = hypot(n[0], n[1]);
                if (h < 0.5)
                        return -EINVAL;
                n[0] /= h;
                n[1] /= h;
                n[2] = 0;
                P->d0[l] = 0;
                P->e1[l][0] = -n[1];
                P->e1[l][1] = n[0];
                P->e1[l][2] = 0;
                P->e2[l][0] = P->e2[l][1] = 0;
                P->e2[l][2] = 1;
                P->fixed[3 * l + 1] = P->fixed[3 * l + 2] = true;
        }
        return 0;
}

/* Writes the planes P and the rays' points into c. */
static void lr_commit(struct sec_ctx *c, const struct lr_planes *P, const struct lr_ray *rays,
                      size_t n)
{
        for (int l = 0; l < P->n; l++) {
                double nv[3], d;
                lr_plane(P, l, nv, &d);
                for (int k = 0; k < 3; k++) {
                        c->plane_n[l][k] = nv[k];
                        c->plane_p[l][k] = -d * nv[k];
                }
        }
        for (size_t i = 0; i < n; i++)
                for (int k = 0; k < 3; k++)
                        c->pts[rays[i].pt].x[k] = (float)rays[i].x[k];
}

/* Each plane's change from c's: the angle its normal turned, and how far it moved at the
 * centre of its points (world, as captured: ew + dw, on c's plane). */
static void lr_changes(const struct lr_planes *P, const struct sec_ctx *c,
                       const struct lr_ray *rays, size_t n, struct cal_lr_result *out)
{
        double ctr[SEC_MAX_LASERS][3] = {{0}};
        size_t cnt[SEC_MAX_LASERS] = {0};

        for (size_t i = 0; i < n; i++) {
                for (int k = 0; k < 3; k++)
                        ctr[rays[i].laser][k] += rays[i].ew[k] + rays[i].dw[k];
                cnt[rays[i].laser]++;
        }
        for (int l = 0; l < P->n; l++) {
                double nv[3], d;
                lr_plane(P, l, nv, &d);
                for (int k = 0; k < 3 && cnt[l]; k++)
                        ctr[l][k] /= (double)cnt[l];
                out->angle_deg[l] = acos(fmin(cal_dot(nv, c->plane_n[l]), 1)) / DEG;
                out->shift_mm[l] = -(cal_dot(nv, ctr[l]) + d); /* the old plane's point */
        }
}

/* Gauss-Newton iterations from the calibrated planes (constrained first); the agreement
 * before (as the points were) and after in out. Returns the final number of pairs or
 * -errno. */
static long lr_iterate(struct lr_planes *P, struct lr_ray *rays, size_t n, double h, int iters,
                       struct lr_pair *pairs, double *abs_r, struct cal_lr_result *out)
{
        long np = lr_match_all(rays, n, P->n, h, pairs, abs_r);
        double step = INFINITY;
        int e;

        if (np < LR_MIN_PAIR)
                return np < 0 ? np : -ENODATA;
        out->pairs_before = (size_t)np;
        lr_stats(rays, pairs, (size_t)np, P->n, &out->rms_before, out->offset_before);
        if ((e = lr_place(P, rays, n)) < 0) /* onto the constrained planes */
                return e;
        if ((np = lr_match_all(rays, n, P->n, h, pairs, abs_r)) < LR_MIN_PAIR)
                return np < 0 ? np : -ENODATA;
        for (out->iterations = 0; out->iterations < iters && step > LR_DONE_MM; out->iterations++) {
                if ((e = lr_step(P, rays, pairs, (size_t)np, &step)) < 0 ||
                    (e = lr_place(P, rays, n)) < 0)
                        return e;
                if ((np = lr_match_all(rays, n, P->n, h, pairs, abs_r)) < LR_MIN_PAIR)
                        return np < 0 ? np : -ENODATA;
        }
        out->pairs_after = (size_t)np;
        lr_stats(rays, pairs, (size_t)np, P->n, &out->rms_after, out->offset_after);
        return np;
}

/* Refuses a change larger than a calibration error, with the reason in err. */
static int lr_check(const struct cal_lr_result *r, char *err, size_t errlen)
{
        for (int l = 0; l < r->n_lasers; l++)
                if (r->angle_deg[l] > LR_MAX_DEG || fabs(r->shift_mm[l]) > LR_MAX_MM) {
                        snprintf(err, errlen,
                                 "laser %d's plane would turn by %.2f deg and move by %.2f mm to "
                                 "agree with the others (more than %.0f deg or %.0f mm): its "
                                 "calibration is wrong, or it moved; calibrate it again",
                                 l, r->angle_deg[l], r->shift_mm[l], LR_MAX_DEG, LR_MAX_MM);
                        return -EDOM;
                }
        return 0;
}

int cal_lasers_refine(struct sec_ctx *c, const struct cal_lr_opts *o, struct cal_lr_result *out,
                      char *err, size_t errlen)
{
        double h = o && o->match_mm > 0 ? o->match_mm : CAL_LR_MATCH_MM;
        int iters = o && o->iterations > 0 ? o->iterations : CAL_LR_ITERATIONS;
        int ref = o ? o->reference : 0;
        struct lr_planes P;
        long np;
        int e;

        memset(out, 0, sizeof(*out));
        if (!c || c->n_lasers < 2 || ref < 0 || ref >= c->n_lasers) {
                snprintf(err, errlen,
                         "joint refinement needs two or more lasers, and the "
                         "reference one of them");
                return -EINVAL;
        }
        lr_init(c, &P);
        if (lr_constrain(&P, ref, o && o->through_axis) < 0) {
                snprintf(err, errlen,
                         "a laser's plane is across the turntable axis: it cannot "
                         "be made to contain it");
                return -EINVAL;
        }
        out->n_lasers = c->n_lasers;
        size_t cap = c->n_pts * (size_t)(c->n_lasers - 1) + 1;
        _cleanup_free_ struct lr_ray *rays = malloc((c->n_pts + 1) * sizeof(*rays));
        _cleanup_free_ struct lr_pair *pairs = malloc(cap * sizeof(*pairs));
        _cleanup_free_ double *abs_r = malloc(cap * sizeof(double));
        if (!rays || !pairs || !abs_r)
                return -ENOMEM;
        size_t n = lr_rays(c, -1, rays);
        if ((np = lr_iterate(&P, rays, n, h, iters, pairs, abs_r, out)) == -ENODATA)
                snprintf(err, errlen,
                         "the lasers' clouds overlap in fewer than %d points within %.1f mm: "
                         "scan the same surface with each laser, and compute the normals "
                         "(sec_normals) first",
                         LR_MIN_PAIR, h);
        else if (np < 0)
                snprintf(err, errlen, "the refinement failed: %s", strerror((int)-np));
        if (np < 0)
                return (int)np;
        lr_changes(&P, c, rays, n, out);
        if ((e = lr_check(out, err, errlen)) < 0)
                return e;
        lr_commit(c, &P, rays, n);
        return 0;
}

int cal_lasers_agreement(const struct sec_ctx *c, double match_mm, double *rms, size_t *pairs,
                         double offset[SEC_MAX_LASERS])
{
        double h = match_mm > 0 ? match_mm : CAL_LR_MATCH_MM, off[SEC_MAX_LASERS];
        long np;

        if (!c || c->n_lasers < 2)
                return -EINVAL;
        size_t cap = c->n_pts * (size_t)(c->n_lasers - 1) + 1;
        _cleanup_free_ struct lr_ray *rays = malloc((c->n_pts + 1) * sizeof(*rays));
        _cleanup_free_ struct lr_pair *pr = malloc(cap * sizeof(*pr));
        _cleanup_free_ double *abs_r = malloc(cap * sizeof(double));
        if (!rays || !pr || !abs_r)
                return -ENOMEM;
        size_t n = lr_rays(c, -1, rays);
        if ((np = lr_match_all(rays, n, c->n_lasers, h, pr, abs_r)) < LR_MIN_PAIR)
                return np < 0 ? (int)np : -ENODATA;
        lr_stats(rays, pr, (size_t)np, c->n_lasers, rms, offset ? offset : off);
        *pairs = (size_t)np;
        return 0;
}

int cal_laser_replane(struct sec_ctx *c, int laser, const struct cal_plane *p)
{
        struct lr_planes P;
        size_t n = 0;

        if (!c || laser < 0 || laser >= c->n_lasers || !p || cal_dot(p->n, p->n) == 0)
                return -EINVAL;
        _cleanup_free_ struct lr_ray *rays = malloc((c->n_pts + 1) * sizeof(*rays));
        if (!rays)
                return -ENOMEM;
        n = lr_rays(c, laser, rays);
        lr_init(c, &P);
        memcpy(P.n0[laser], p->n, sizeof(P.n0[laser]));
        P.d0[laser] = p->d / sqrt(cal_dot(p->n, p->n));
        cal_normalize(P.n0[laser]);
        if (lr_place(&P, rays, n) < 0)
                return -EDOM;
        lr_commit(c, &P, rays, n);
        return 0;
}
