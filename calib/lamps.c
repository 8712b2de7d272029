/* lamps.c - lamp positions from highlights on a mirror sphere (see lamps.h): the sphere's
 * centre triangulated from the silhouettes' axes, each highlight's ray reflected on the
 * sphere, each lamp the point closest to its reflected rays. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/lamps_internal.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"
#include "common/riggeom.h"
#include "common/sortx.h"

#define DEG                   CAL_LAMPS_DEG
#define SPHERE_MIN_SPREAD_DEG 1.0 /* silhouette axes spread less: the diameter gives depth */
#define SPHERE_OUTLIER_MM     0.5 /* floor of the outlier test of the silhouette axes */
#define CONSENSUS_FACTOR      5.0 /* lines this many outlier floors from a pair's point agree */
#define CONSENSUS_LINES       64  /* lines whose pairs are tried, at most (about) */

/* A line o + s d (|d| = 1) of one view. */
struct line {
        double o[3], d[3];
        size_t view;
        bool used;
};

/* A least-squares point of lines with its figures. */
struct point_fit {
        double p[3], rms, spread_deg;
        int used;
};

static double line_dist(const struct line *l, const double p[3])
{
        double v[3] = {p[0] - l->o[0], p[1] - l->o[1], p[2] - l->o[2]}, s = cal_dot(v, l->d);

        for (int k = 0; k < 3; k++)
                v[k] -= s * l->d[k];
        return sqrt(cal_dot(v, v));
}

/* The point closest to the used lines (sum of (I - d d^T)), and the lines' angular spread
 * (from the smallest eigenvalue of the mean of I - d d^T). Returns 0 or -EDOM (parallel). */
static int fit_point(const struct line *l, size_t n, struct point_fit *f)
{
        double A[9] = {0}, b[3] = {0}, w[3], V[9], ss = 0;

        f->used = 0;
        for (size_t i = 0; i < n; i++) {
                if (!l[i].used)
                        continue;
                for (int r = 0; r < 3; r++)
                        for (int c = 0; c < 3; c++) {
                                double m = (r == c) - l[i].d[r] * l[i].d[c];
                                A[3 * r + c] += m;
                                b[r] += m * l[i].o[c];
                        }
                f->used++;
        }
        if (f->used < 2)
                return -EDOM;
        cal_eig3(A, w, V);
        f->spread_deg = asin(sqrt(fmin(fmax(fmin(w[0], fmin(w[1], w[2])) / f->used, 0), 1))) / DEG;
        memcpy(f->p, b, sizeof(b));
        if (cal_solve(A, f->p, 3) < 0)
                return -EDOM;
        for (size_t i = 0; i < n; i++)
                if (l[i].used)
                        ss += pow(line_dist(&l[i], f->p), 2);
        f->rms = sqrt(ss / f->used);
        return 0;
}

/* The middle of the common perpendicular of lines a and b into p. Returns 0 or -EDOM
 * (nearly parallel). */
static int pair_point(const struct line *a, const struct line *b, double p[3])
{
        double w[3], ab = cal_dot(a->d, b->d), den = 1 - ab * ab, s, t;

        if (den < 1e-6)
                return -EDOM;
        for (int k = 0; k < 3; k++)
                w[k] = a->o[k] - b->o[k];
        s = (ab * cal_dot(b->d, w) - cal_dot(a->d, w)) / den;
        t = (cal_dot(b->d, w) - ab * cal_dot(a->d, w)) / den;
        for (int k = 0; k < 3; k++)
                p[k] = (a->o[k] + s * a->d[k] + b->o[k] + t * b->d[k]) / 2;
        return 0;
}

/* Keeps as used the lines within thr_mm of the point of the pair of lines that most lines
 * pass near (every pair of up to CONSENSUS_LINES lines spread over them), so that one wild line
 * cannot drag the least-squares point away from the others; leaves them all used when no pair has 3
 * lines near it. */
static void consensus(struct line *l, size_t n, double thr_mm)
{
        double p[3], best_p[3] = {0};
        size_t best = 0, step = n / CONSENSUS_LINES + 1; /* at most about 64 x 64 / 2 pairs */

        for (size_t i = 0; i < n; i += step)
                for (size_t j = i + 1; j < n; j += step) {
                        size_t m = 0;
                        if (pair_point(&l[i], &l[j], p) < 0)
                                continue;
                        for (size_t k = 0; k < n; k++)
                                m += line_dist(&l[k], p) <= thr_mm;
                        if (m > best) {
                                best = m;
                                memcpy(best_p, p, sizeof(p));
                        }
                }
        for (size_t k = 0; best >= 3 && k < n; k++)
                l[k].used = line_dist(&l[k], best_p) <= thr_mm;
}

/* The lines that agree (consensus within CONSENSUS_FACTOR x floor_mm), fit_point, then drops
 * the farthest line while it is farther than CAL_LAMPS_OUTLIER_FACTOR times the median
 * distance and floor_mm, and more than min_used lines remain. */
static int fit_robust(struct line *l, size_t n, int min_used, double floor_mm, struct point_fit *f)
{
        _cleanup_free_ double *d = calloc(n ? n : 1, sizeof(*d));
        int r;

        if (!d)
                return -ENOMEM;
        consensus(l, n, CONSENSUS_FACTOR * floor_mm);
        while ((r = fit_point(l, n, f)) == 0 && f->used > min_used) {
                size_t worst = n, m = 0;
                double far = -1;
                for (size_t i = 0; i < n; i++) {
                        double di = line_dist(&l[i], f->p);
                        if (!l[i].used)
                                continue;
                        d[m++] = di;
                        if (di > far) {
                                far = di;
                                worst = i;
                        }
                }
                qsort(d, m, sizeof(*d), gn_cmp_double);
                if (far <= fmax(CAL_LAMPS_OUTLIER_FACTOR * d[m / 2], floor_mm))
                        break;
                l[worst].used = false;
        }
        return r;
}

/* Camera centre c (world) and the world direction d (unit) of camera-frame ray x. */
static void camera_ray(const struct sec_camera *cam, const double x[3], double c[3], double d[3])
{
        const double *R = cam->R;

        cal_lamps_camera_centre(cam, c);
        for (int i = 0; i < 3; i++)
                d[i] = R[i] * x[0] + R[3 + i] * x[1] + R[6 + i] * x[2];
        cal_normalize(d);
}

/* Finds view v's sphere and highlight. Returns 0 (v->reason says what was missing) or
 * -errno (OpenCV, memory). */
static int view_measure(struct cal_lamp_view *v, const struct cal_lamps_opts *o)
{
        const struct sec_camera *cam = &o->cams[v->camera].cal;
        int r;

        v->highlight[0] = v->highlight[1] = v->miss_mm = NAN;
        v->offset[0] = v->offset[1] = 0;
        v->used = v->sphere_used = false;
        v->reason[0] = 0;
        r = cal_lamps_find_sphere(&v->im, cam, o->sphere_mm, o->reach_mm, &v->sphere);
        if (r == -ENOENT) {
                snprintf(v->reason, sizeof(v->reason), "mirror sphere not found");
                return 0;
        }
        if (r < 0 || (r = cal_lamps_find_highlight(&v->im, &v->sphere, v->highlight)) < 0)
                return r;
        if (r == 0)
                snprintf(v->reason, sizeof(v->reason),
                         "no highlight on the sphere (lamp off, or hidden from the sphere)");
        else if (r > 1)
                snprintf(v->reason, sizeof(v->reason),
                         "%d highlights on the sphere (light one lamp at a time, with nothing else "
                         "bright reflected)",
                         r);
        if (r != 1)
                v->highlight[0] = v->highlight[1] = NAN;
        return 0;
}

/* The axis of view i's silhouette as a line in the object frame. */
static void sphere_line(const struct cal_lamp_view *v, size_t i, const struct cal_lamps_opts *o,
                        struct line *l)
{
        double c[3], d[3], tt = -cal_lamps_angle(v[i].turntable_deg);

        camera_ray(&o->cams[v[i].camera].cal, v[i].sphere.axis, c, d);
        cal_lamps_rot_z(c, tt, l->o);
        cal_lamps_rot_z(d, tt, l->d);
        l->view = i;
        l->used = true;
}

/* The sphere's centre from the silhouettes' distances along their axes (known diameter). */
static void sphere_from_size(const struct line *l, size_t m, const struct cal_lamp_view *v,
                             double rs, struct point_fit *f)
{
        memset(f, 0, sizeof(*f));
        for (size_t i = 0; i < m; i++)
                for (int k = 0; k < 3; k++)
                        f->p[k] += (l[i].o[k] +
                                    l[i].d[k] * rs / sin(v[l[i].view].sphere.half_deg * DEG)) /
                                   m;
}

/* Triangulates the sphere's centre (object frame) from the views where it was found into
 * out->sphere; views whose axis is an outlier get a reason. Returns 0 or -ENODATA. */
static int sphere_centre(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                         struct cal_lamps *out, char *err, size_t errlen)
{
        _cleanup_free_ struct line *l = calloc(n ? n : 1, sizeof(*l));
        double rs = o->sphere_mm / 2;
        struct point_fit f;
        size_t m = 0;
        int r;

        if (!l)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                if (v[i].sphere.n_edges)
                        sphere_line(v, i, o, &l[m++]);
        if (!m) {
                snprintf(err, errlen,
                         "the mirror sphere (%g mm) was found in none of the %zu views: put it on "
                         "the turntable in view of the cameras, in front of a bright even "
                         "background, and check its diameter",
                         o->sphere_mm, n);
                return -ENODATA;
        }
        if (m < 2 || fit_point(l, m, &f) < 0 || f.spread_deg < SPHERE_MIN_SPREAD_DEG)
                sphere_from_size(l, m, v, rs, &f);
        else if ((r = fit_robust(l, m, 2, SPHERE_OUTLIER_MM, &f)) < 0)
                return r;
        for (size_t i = 0; i < m; i++) {
                v[l[i].view].sphere_used = l[i].used;
                if (!l[i].used)
                        snprintf(v[l[i].view].reason, sizeof(v->reason),
                                 "the sphere's silhouette points %.1f mm off the other views' "
                                 "(the sphere moved, or another circle was taken for it)",
                                 line_dist(&l[i], f.p));
        }
        memcpy(out->sphere, f.p, sizeof(f.p));
        return 0;
}

/* The sphere's figures: the RMS distance of the silhouettes' axes used from its centre, and
 * the diameter their half-angles give at that distance. */
static void sphere_stats(const struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                         struct cal_lamps *out)
{
        double ss = 0, diam = 0, dz[3];
        size_t m = 0;
        struct line l;

        for (size_t i = 0; i < n; i++) {
                if (!v[i].sphere_used)
                        continue;
                sphere_line(v, i, o, &l);
                for (int k = 0; k < 3; k++)
                        dz[k] = out->sphere[k] - l.o[k];
                ss += pow(line_dist(&l, out->sphere), 2);
                diam += 2 * sqrt(cal_dot(dz, dz)) * sin(v[i].sphere.half_deg * DEG);
                m++;
        }
        out->sphere_rms_mm = m ? sqrt(ss / m) : NAN;
        out->sphere_diam_mm = m ? diam / m : NAN;
}

/* View v's highlight ray reflected on the sphere (object-frame centre sphere), in the frame
 * of the light arm at 0. Returns 0, or -EDOM with v->reason (the ray misses the sphere). */
static int reflected_ray(struct cal_lamp_view *v, const struct cal_lamps_opts *o,
                         const double sphere[3], struct line *l)
{
        const struct sec_camera *cam = &o->cams[v->camera].cal;
        double xy[2], c[3], d[3], s[3], oc[3], p[3], n[3], r[3], rs = o->sphere_mm / 2, b, disc;

        if (sec_undistort(&cam->k, v->highlight[0] - v->offset[0], v->highlight[1] - v->offset[1],
                          xy) < 0) {
                snprintf(v->reason, sizeof(v->reason), "the highlight cannot be undistorted");
                return -EDOM;
        }
        camera_ray(cam, (double[3]){xy[0], xy[1], 1}, c, d);
        cal_lamps_rot_z(sphere, cal_lamps_angle(v->turntable_deg), s);
        for (int k = 0; k < 3; k++)
                oc[k] = c[k] - s[k];
        b = cal_dot(d, oc);
        disc = b * b - (cal_dot(oc, oc) - rs * rs);
        if (disc < 0) {
                snprintf(v->reason, sizeof(v->reason),
                         "the highlight's ray misses the sphere by %.1f mm",
                         sqrt(cal_dot(oc, oc) - b * b) - rs);
                return -EDOM;
        }
        for (int k = 0; k < 3; k++) {
                p[k] = c[k] + (-b - sqrt(disc)) * d[k];
                n[k] = (p[k] - s[k]) / rs;
        }
        for (int k = 0; k < 3; k++)
                r[k] = d[k] - 2 * cal_dot(d, n) * n[k];
        cal_lamps_rot_z(p, -cal_lamps_angle(v->light_arm_deg), l->o);
        cal_lamps_rot_z(r, -cal_lamps_angle(v->light_arm_deg), l->d);
        cal_normalize(l->d);
        l->used = true;
        return 0;
}

/* The reflected rays of lamp `lamp` from the views that light it into l; *lit gets the number
 * of those views and *why the reason of the first one without a ray (or that the sphere was
 * found in none of them). Returns the rays. */
static size_t lamp_rays(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                        const double sphere[3], int lamp, struct line *l, size_t *lit,
                        const char **why)
{
        size_t m = 0, seen = 0;

        *lit = 0;
        *why = NULL;
        for (size_t i = 0; i < n; i++) {
                if (v[i].lamp != lamp)
                        continue;
                (*lit)++;
                seen += v[i].sphere.n_edges > 0;
                if (!v[i].reason[0] && reflected_ray(&v[i], o, sphere, &l[m]) == 0) {
                        l[m++].view = i;
                        continue;
                }
                if (!*why)
                        *why = v[i].reason;
        }
        if (*lit && !seen) /* while other lamps' views show it: the frames are dark */
                *why = "the sphere found in none of them: dark frames, is the lamp off?";
        return m;
}

/* Records the fit of lamp `lamp` in lp and its rays' distances in their views. */
static void lamp_record(struct cal_lamp_view *v, const struct line *l, size_t m,
                        const struct point_fit *f, const struct cal_lamps_opts *o, int lamp,
                        struct cal_lamp_pos *lp)
{
        double nom[3], dn[3];

        for (size_t i = 0; i < m; i++) {
                struct cal_lamp_view *w = &v[l[i].view];
                w->miss_mm = line_dist(&l[i], f->p);
                w->used = l[i].used;
                if (!w->used)
                        snprintf(w->reason, sizeof(w->reason),
                                 "its reflected ray passes %.1f mm from the lamp's fit (outlier)",
                                 w->miss_mm);
        }
        riggeom_lamp_position(&o->rc->lamps[lamp], 0, nom);
        for (int k = 0; k < 3; k++)
                dn[k] = f->p[k] - nom[k];
        memcpy(lp->pos, f->p, sizeof(lp->pos));
        lp->rms_mm = f->rms;
        lp->n_obs = f->used;
        lp->nominal_dist_mm = sqrt(cal_dot(dn, dn));
}

/* Solves lamp `lamp` into lp (name set, pos NAN when not solved). Returns 0 or -ENODATA
 * with a sentence in err. */
static int solve_lamp(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                      const double sphere[3], int lamp, struct cal_lamp_pos *lp, char *err,
                      size_t errlen)
{
        _cleanup_free_ struct line *l = calloc(n, sizeof(*l));
        int min = o->min_views > 0 ? o->min_views : CAL_LAMPS_MIN_VIEWS;
        double spread = o->min_spread_deg > 0 ? o->min_spread_deg : CAL_LAMPS_MIN_SPREAD_DEG;
        const char *name = o->rc->lamps[lamp].name, *why;
        struct point_fit f = {0};
        size_t lit, m;

        if (!l)
                return -ENOMEM;
        *lp = (struct cal_lamp_pos){.pos = {NAN, NAN, NAN}, .rms_mm = NAN, .nominal_dist_mm = NAN};
        snprintf(lp->name, sizeof(lp->name), "%s", name);
        m = lamp_rays(v, n, o, sphere, lamp, l, &lit, &why);
        if ((int)m < min) {
                snprintf(err, errlen,
                         "lamp '%s' gave a reflected ray in %zu of the %zu views that light it, %d "
                         "needed (%s): capture more turntable angles or add a camera, and check "
                         "that the lamp lights",
                         name, m, lit, min, why ? why : "too few views");
                return -ENODATA;
        }
        if (fit_robust(l, m, min, CAL_LAMPS_OUTLIER_FLOOR_MM, &f) < 0 || f.spread_deg < spread) {
                snprintf(err, errlen,
                         "lamp '%s': its %zu reflected rays are nearly parallel (spread %.1f deg, "
                         "%.1f needed), so its distance along them is undetermined: capture more "
                         "turntable angles with the sphere away from the axis, or add a camera at "
                         "another azimuth",
                         name, m, f.spread_deg, spread);
                return -ENODATA;
        }
        lamp_record(v, l, m, &f, o, lamp, lp);
        return 0;
}

/* Refines the sphere and the solved lamps jointly (cal_lamps_refine; kept as they were if
 * it diverges), then each solved lamp's figures from its rays on the refined sphere. */
static int refine(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                  struct cal_lamps *out)
{
        _cleanup_free_ struct line *l = calloc(n, sizeof(*l));
        int r = cal_lamps_refine(v, n, o, out);

        if (!l || r == -ENOMEM)
                return -ENOMEM;
        for (size_t k = 0; k < out->n_lamps; k++) {
                struct point_fit f = {.used = 0};
                const char *why;
                size_t lit, m;
                double ss = 0;
                if (!(out->lamps[k].n_obs > 0))
                        continue;
                memcpy(f.p, out->lamps[k].pos, sizeof(f.p));
                m = lamp_rays(v, n, o, out->sphere, out->index[k], l, &lit, &why);
                for (size_t i = 0; i < m; i++)
                        ss += pow(line_dist(&l[i], f.p), 2);
                f.used = (int)m;
                f.rms = m ? sqrt(ss / m) : NAN;
                lamp_record(v, l, m, &f, o, out->index[k], &out->lamps[k]);
        }
        return 0;
}

/* Checks o and the views' indices. Returns 0 or -EINVAL with err. */
static int check_args(const struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                      char *err, size_t errlen)
{
        if (!o || !o->rc || !o->cams || !o->n_cams || !(o->sphere_mm > 0) || (n && !v)) {
                snprintf(err, errlen,
                         "lamps: need the rig, at least one calibrated camera and the sphere's "
                         "diameter");
                return -EINVAL;
        }
        for (size_t i = 0; i < n; i++)
                if (v[i].camera < 0 || (size_t)v[i].camera >= o->n_cams || v[i].lamp < 0 ||
                    (size_t)v[i].lamp >= o->rc->n_lamps) {
                        snprintf(err, errlen, "lamps: view %zu names camera %d and lamp %d", i,
                                 v[i].camera, v[i].lamp);
                        return -EINVAL;
                }
        return 0;
}

/* The geometry once every view is measured: the sphere, then each lamp lit in a view. */
static int solve_views(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                       struct cal_lamps *out, char *err, size_t errlen)
{
        char other[CAL_REASON_MAX * 2];
        int r, failed = 0, n_failed = 0;

        out->n_views = n;
        if ((r = sphere_centre(v, n, o, out, err, errlen)) < 0)
                return r;
        for (size_t lamp = 0; lamp < o->rc->n_lamps; lamp++) {
                bool lit = false;
                for (size_t i = 0; i < n; i++)
                        lit |= v[i].lamp == (int)lamp;
                if (!lit)
                        continue;
                out->index[out->n_lamps] = (int)lamp;
                r = solve_lamp(v, n, o, out->sphere, (int)lamp, &out->lamps[out->n_lamps++],
                               failed ? other : err, failed ? sizeof(other) : errlen);
                if (r == -ENOMEM)
                        return r;
                n_failed += r < 0;
                failed = failed ? failed : r;
        }
        if ((size_t)n_failed < out->n_lamps && (r = refine(v, n, o, out)) < 0)
                return r;
        sphere_stats(v, n, o, out);
        for (size_t i = 0; i < n; i++)
                out->n_used += v[i].used;
        if (n_failed > 1) {
                size_t len = strlen(err);
                snprintf(err + len, errlen - len, " (and %d more lamps failed)", n_failed - 1);
        }
        return failed;
}

int cal_lamps_solve(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                    struct cal_lamps *out, char *err, size_t errlen)
{
        int r;

        memset(out, 0, sizeof(*out));
        if ((r = check_args(v, n, o, err, errlen)) < 0)
                return r;
        for (size_t i = 0; i < n; i++)
                if ((r = view_measure(&v[i], o)) < 0) {
                        snprintf(err, errlen, "lamps: view %zu: %s", i,
                                 r == -EIO ? cal_cv_last_error() : strerror(-r));
                        return r;
                }
        return solve_views(v, n, o, out, err, errlen);
}

void cal_lamps_clear(struct cal_lamps *l)
{
        free(l->views);
        memset(l, 0, sizeof(*l));
}

/* The rows cal_lamps_solve_ds reads: one view and its file per row. */
struct ds_views {
        const struct cal_lamps_opts *o;
        struct cal_lamp_view *v;
        char (*file)[256];
        size_t n, cap;
};

/* The index of camera name in o, or -1. */
static int camera_index(const struct cal_lamps_opts *o, const char *name)
{
        for (size_t i = 0; i < o->n_cams; i++)
                if (!strcmp(o->cams[i].name, name))
                        return (int)i;
        return -1;
}

static int add_row(const struct ds_capture *c, void *userdata)
{
        struct ds_views *r = userdata;
        int cam = camera_index(r->o, c->camera), lamp = __builtin_ffs((int)c->pose.lamps) - 1;

        if ((c->kind[0] && strcmp(c->kind, "image")) || c->bracket != 0 || c->pose.lasers ||
            cam < 0 || __builtin_popcount(c->pose.lamps) != 1 || lamp >= (int)r->o->rc->n_lamps)
                return 0;
        if (r->n == r->cap) {
                size_t cap = r->cap ? 2 * r->cap : 32;
                struct cal_lamp_view *v = reallocarray(r->v, cap, sizeof(*v));
                if (v)
                        r->v = v;
                char(*f)[256] = reallocarray(r->file, cap, sizeof(*f));
                if (!v || !f)
                        return -ENOMEM;
                r->file = f;
                r->cap = cap;
        }
        r->v[r->n] = (struct cal_lamp_view){.camera = cam,
                                            .lamp = lamp,
                                            .turntable_deg = c->pose.deg[GN_ROLE_TURNTABLE],
                                            .light_arm_deg = c->pose.deg[GN_ROLE_LIGHT_ARM],
                                            .row_id = c->id};
        snprintf(r->file[r->n++], sizeof(*r->file), "%s", c->file);
        return 0;
}

/* Loads and measures the image of each row, one at a time. */
static int measure_rows(struct ds *d, struct ds_views *r, char *err, size_t errlen)
{
        for (size_t i = 0; i < r->n; i++) {
                struct gn_frame f;
                int e = ds_load_image(d, r->file[i], &f);
                if (e < 0) {
                        snprintf(err, errlen, "cannot read %s: %s", r->file[i], strerror(-e));
                        return e;
                }
                r->v[i].im =
                        (struct cal_image){f.data, f.width, f.height, f.channels, f.bits, f.stride};
                e = view_measure(&r->v[i], r->o);
                gn_frame_free_data(&f);
                r->v[i].im = (struct cal_image){0};
                if (e < 0) {
                        snprintf(err, errlen, "lamps: %s: %s", r->file[i],
                                 e == -EIO ? cal_cv_last_error() : strerror(-e));
                        return e;
                }
        }
        return 0;
}

int cal_lamps_solve_ds(struct ds *d, const struct cal_lamps_opts *o, struct cal_lamps *out,
                       char *err, size_t errlen)
{
        _cleanup_free_ char(*file)[256] = NULL;
        struct ds_views r = {.o = o};
        int e;

        memset(out, 0, sizeof(*out));
        if (!d) {
                snprintf(err, errlen, "lamps: no dataset");
                return -EINVAL;
        }
        if ((e = check_args(NULL, 0, o, err, errlen)) < 0)
                return e;
        e = ds_rows(d, 0, -1, add_row, &r);
        file = r.file;
        out->views = r.v;
        if (e < 0) {
                snprintf(err, errlen, "cannot read dataset %s: %s", ds_name(d),
                         e == -ENOMEM ? strerror(ENOMEM) : ds_last_error(d));
                return e;
        }
        if (!r.n) {
                snprintf(err, errlen,
                         "dataset %s has no images of these cameras with exactly one lamp lit "
                         "and the laser off: capture the sphere with each lamp alone",
                         ds_name(d));
                return -ENOENT;
        }
        if ((e = measure_rows(d, &r, err, errlen)) < 0)
                return e;
        return solve_views(r.v, r.n, o, out, err, errlen);
}
