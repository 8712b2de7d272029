/* lamps_image.c - the mirror sphere and the lamp's highlight in one image (see lamps.h):
 * Hough candidates for the silhouette, refined on radial edge profiles and fitted as the
 * cone of rays tangent to the sphere; the highlight as the excess-weighted centroid of the one
 * bright blob inside the disc. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calib/lamps_internal.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define DEG            CAL_LAMPS_DEG
#define MAX_CANDIDATES 8
#define SCAN_STEP      0.5   /* px between the samples of a radial profile */
#define SCAN_PAD       3     /* samples each side of an edge: inside and outside levels */
#define SCAN_MAX       512   /* samples of a profile */
#define EDGE_CONTRAST  0.15  /* the rim at most this much darker than what lies behind it... */
#define EDGE_MIN       0.015 /* ...and at least this fraction of full scale */
#define MIN_EDGES      (CAL_SPHERE_DIRS / 3) /* a third of the rim, at least */
#define RANSAC_PX      1.0  /* an edge point this close to a hypothesis agrees with it */
#define FIT_ROUNDS     4    /* cone fits, dropping edge points beyond 3 sigma each time */
#define FIT_FLOOR_PX   0.3  /* residuals below this are never dropped */
#define FIT_MAX_PX     1.0  /* a silhouette fitting worse is not the sphere */
#define DISC_INNER     0.95 /* highlights are looked for within this fraction of the radius */

/* Luminance of pixel (x, y) in [0, 1]: the channels' mean over full scale. */
static double lum(const struct cal_image *im, int x, int y)
{
        const uint8_t *row = im->data + (size_t)y * im->stride;
        double s = 0, full = im->bits == 16 ? 65535.0 : 255.0;

        for (int c = 0; c < im->channels; c++)
                s += im->bits == 16 ? ((const uint16_t *)row)[x * im->channels + c]
                                    : row[x * im->channels + c];
        return s / (im->channels * full);
}

/* Bilinear luminance at (x, y); NAN outside the image. */
static double lum_at(const struct cal_image *im, double x, double y)
{
        int x0 = (int)floor(x), y0 = (int)floor(y);
        double fx = x - x0, fy = y - y0;

        if (x0 < 0 || y0 < 0 || x0 + 1 >= im->width || y0 + 1 >= im->height)
                return NAN;
        return (1 - fy) * ((1 - fx) * lum(im, x0, y0) + fx * lum(im, x0 + 1, y0)) +
               fy * ((1 - fx) * lum(im, x0, y0 + 1) + fx * lum(im, x0 + 1, y0 + 1));
}

/* The rim along direction (c, s) from (u, v) between radii r0 and r1: the outward rise with
 * the largest step, where the inside is at least EDGE_CONTRAST darker than the outside; its
 * radius where the profile crosses half-way. NAN when there is none. */
static double scan_edge(const struct cal_image *im, double u, double v, double c, double s,
                        double r0, double r1)
{
        double p[SCAN_MAX], start = r0 - SCAN_PAD * SCAN_STEP, best = 0, in, out, level;
        int n = (int)((r1 - r0) / SCAN_STEP) + 2 * SCAN_PAD + 1, j = -1;

        if (n > SCAN_MAX || r0 < 1)
                return NAN;
        for (int k = 0; k < n; k++)
                if (isnan(p[k] = lum_at(im, u + (start + k * SCAN_STEP) * c,
                                        v + (start + k * SCAN_STEP) * s)))
                        return NAN;
        for (int k = SCAN_PAD; k < n - SCAN_PAD; k++)
                if (p[k + 2] - p[k - 2] > best) {
                        best = p[k + 2] - p[k - 2];
                        j = k;
                }
        if (j < 0)
                return NAN;
        in = p[j - SCAN_PAD];
        out = p[j + SCAN_PAD];
        if (out - in < EDGE_CONTRAST * out || out - in < EDGE_MIN)
                return NAN;
        level = (in + out) / 2;
        for (int k = j - SCAN_PAD; k < j + SCAN_PAD; k++)
                if (p[k] < level && p[k + 1] >= level)
                        return start + SCAN_STEP * (k + (level - p[k]) / (p[k + 1] - p[k]));
        return NAN;
}

/* Edge points of one silhouette: pixels, unit rays in the camera frame, inlier marks. */
struct edges {
        int n;
        double px[CAL_SPHERE_DIRS][2];
        double ray[CAL_SPHERE_DIRS][3];
        bool in[CAL_SPHERE_DIRS];
};

/* The cone u.w = 1 through the inlier rays (axis w/|w|, cos half-angle 1/|w|). */
static int cone_fit(const struct edges *e, double w[3])
{
        double A[9] = {0}, b[3] = {0};

        for (int i = 0; i < e->n; i++)
                if (e->in[i])
                        for (int r = 0; r < 3; r++) {
                                b[r] += e->ray[i][r];
                                for (int c = 0; c < 3; c++)
                                        A[3 * r + c] += e->ray[i][r] * e->ray[i][c];
                        }
        memcpy(w, b, sizeof(b));
        return cal_solve(A, w, 3);
}

/* Residuals res (px at focal length f) of every edge point from cone w; *half its
 * half-angle. Returns 0 or -ENOENT (not a cone: |w| <= 1). */
static int cone_residuals(const struct edges *e, const double w[3], double f, double *res,
                          double *half)
{
        double len = sqrt(cal_dot(w, w));

        if (!(len > 1))
                return -ENOENT;
        *half = acos(1 / len);
        for (int i = 0; i < e->n; i++)
                res[i] = f * fabs(acos(fmin(cal_dot(e->ray[i], w) / len, 1)) - *half);
        return 0;
}

/* The cone w through edge points i, i + d and i + 2d (modulo the count). Returns 0 or
 * -EDOM. */
static int cone3(const struct edges *e, int i, int d, double w[3])
{
        double A[9];

        for (int k = 0; k < 3; k++) {
                memcpy(A + 3 * k, e->ray[(i + k * d) % e->n], 3 * sizeof(double));
                w[k] = 1;
        }
        return cal_solve(A, w, 3);
}

/* Marks as inliers the edge points within RANSAC_PX of the best cone through three of them:
 * triplets of every start and several spacings, so that a contiguous arc of wrong edges (a
 * shadow beside the sphere) cannot spoil every hypothesis. */
static void cone_ransac(struct edges *e, double f)
{
        static const int spacing[] = {6, 12, 24, 40, 60}; /* of CAL_SPHERE_DIRS directions */
        double res[CAL_SPHERE_DIRS], w[3], best_w[3] = {0}, half;
        int best = -1;

        for (size_t s = 0; s < ELEMENTSOF(spacing); s++) {
                int d = e->n * spacing[s] / CAL_SPHERE_DIRS;
                for (int i = 0; d >= 1 && i < e->n; i++) {
                        int n = 0;
                        if (cone3(e, i, d, w) < 0 || cone_residuals(e, w, f, res, &half) < 0)
                                continue;
                        for (int j = 0; j < e->n; j++)
                                n += res[j] <= RANSAC_PX;
                        if (n > best) {
                                best = n;
                                memcpy(best_w, w, sizeof(w));
                        }
                }
        }
        if (best < 0 || cone_residuals(e, best_w, f, res, &half) < 0)
                best = -1;
        for (int j = 0; j < e->n; j++)
                e->in[j] = best >= 0 && res[j] <= RANSAC_PX;
}

/* Fits the cone to e: RANSAC, then least squares dropping edge points beyond 3 sigma (MAD)
 * of the residual; fills out's axis, half-angle, rms and count. Returns 0 or -ENOENT (too
 * few points agree). */
static int cone_robust(struct edges *e, double f, struct cal_sphere_image *out)
{
        double w[3], res[CAL_SPHERE_DIRS], sorted[CAL_SPHERE_DIRS], half = 0, ss = 0;
        int m = 0;

        cone_ransac(e, f);
        for (int round = 0; round < FIT_ROUNDS; round++) {
                if (cone_fit(e, w) < 0 || cone_residuals(e, w, f, res, &half) < 0)
                        return -ENOENT;
                m = 0;
                for (int i = 0; i < e->n; i++)
                        if (e->in[i])
                                sorted[m++] = res[i];
                if (m < MIN_EDGES)
                        return -ENOENT;
                qsort(sorted, m, sizeof(*sorted), gn_cmp_double);
                double thr = fmax(3 * 1.4826 * sorted[m / 2], FIT_FLOOR_PX);
                for (int i = 0; i < e->n; i++)
                        e->in[i] = res[i] <= thr;
        }
        m = 0;
        for (int i = 0; i < e->n; i++)
                if (e->in[i]) {
                        ss += res[i] * res[i];
                        m++;
                }
        if (m < MIN_EDGES)
                return -ENOENT;
        for (int k = 0; k < 3; k++)
                out->axis[k] = w[k] / sqrt(cal_dot(w, w));
        out->half_deg = half / DEG;
        out->rms_px = sqrt(ss / m);
        out->n_edges = m;
        return 0;
}

/* The image circle (Kasa's algebraic fit) of the inlier edge pixels into out->u, v, r. */
static int circle_fit(const struct edges *e, struct cal_sphere_image *out)
{
        double xy[2 * CAL_SPHERE_DIRS], c[2];
        size_t n = 0;

        for (int i = 0; i < e->n; i++)
                if (e->in[i]) {
                        xy[2 * n] = e->px[i][0];
                        xy[2 * n + 1] = e->px[i][1];
                        n++;
                }
        if (cal_circle_fit(xy, n, c, &out->r) < 0)
                return -ENOENT;
        out->u = c[0];
        out->v = c[1];
        return 0;
}

/* Collects the rim's edge points around circle (u, v, r) within +-window px. */
static void collect_edges(const struct cal_image *im, const struct cal_intrinsics *k, double u,
                          double v, double r, double window, struct edges *e)
{
        e->n = 0;
        for (int i = 0; i < CAL_SPHERE_DIRS; i++) {
                double a = 2 * M_PI * i / CAL_SPHERE_DIRS, c = cos(a), s = sin(a), xy[2];
                double re = scan_edge(im, u, v, c, s, r - window, r + window);
                double *px = e->px[e->n], *ray = e->ray[e->n];
                if (isnan(re))
                        continue;
                px[0] = u + re * c;
                px[1] = v + re * s;
                if (sec_undistort(k, px[0], px[1], xy) < 0)
                        continue;
                double len = sqrt(xy[0] * xy[0] + xy[1] * xy[1] + 1);
                ray[0] = xy[0] / len;
                ray[1] = xy[1] / len;
                ray[2] = 1 / len;
                e->in[e->n++] = true;
        }
}

/* Refines Hough candidate (u, v, r) in two passes (a wide window, then +-3 px around the
 * first fit) into out. Returns 0 or -ENOENT (not a sphere's silhouette). */
static int refine(const struct cal_image *im, const struct cal_intrinsics *k, double u, double v,
                  double r, struct cal_sphere_image *out)
{
        _cleanup_free_ struct edges *e = malloc(sizeof(*e));
        double window = fmax(4, 0.15 * r);

        if (!e)
                return -ENOMEM;
        for (int pass = 0; pass < 2; pass++) {
                collect_edges(im, k, u, v, r, window, e);
                if (e->n < MIN_EDGES || cone_robust(e, k->fx, out) < 0 || circle_fit(e, out) < 0)
                        return -ENOENT;
                u = out->u;
                v = out->v;
                r = out->r;
                window = 3;
        }
        return out->rms_px <= FIT_MAX_PX ? 0 : -ENOENT;
}

int cal_lamps_find_sphere(const struct cal_image *im, const struct sec_camera *cam,
                          double sphere_mm, double reach_mm, struct cal_sphere_image *out)
{
        double xyr[3 * MAX_CANDIDATES], c[3], dist, rmin, rmax, rs = sphere_mm / 2;
        int n;

        if (!im || !im->data || !cam || !(sphere_mm > 0) || !(cam->k.fx > 0))
                return -EINVAL;
        reach_mm = reach_mm > 0 ? reach_mm : CAL_LAMPS_REACH_MM;
        cal_lamps_camera_centre(cam, c);
        dist = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        rmin = fmax(4, cam->k.fx * rs / (dist + reach_mm));
        rmax = fmin(0.5 * fmin(im->width, im->height),
                    cam->k.fx * rs / fmax(dist - reach_mm, 2 * rs));
        memset(out, 0, sizeof(*out));
        if (rmax < rmin)
                return -ENOENT;
        if ((n = cal_cv_find_circles(im, rmin, rmax, xyr, MAX_CANDIDATES)) < 0)
                return n;
        for (int i = 0; i < n; i++) {
                int r = refine(im, &cam->k, xyr[3 * i], xyr[3 * i + 1], xyr[3 * i + 2], out);
                if (r == 0 && fabs(rs / sin(out->half_deg * DEG) - dist) > reach_mm)
                        r = -ENOENT; /* a circle of another size: not the sphere */
                if (r != -ENOENT)
                        return r;
        }
        memset(out, 0, sizeof(*out));
        return -ENOENT;
}

/* A bright blob: its peak and the sums of its excess-weighted centroid. */
struct blob {
        double peak, sw, swx, swy;
};

/* The part of the image searched for highlights: the disc's bounding box, with a mark
 * (1) for each pixel inside DISC_INNER of the radius and its luminance. */
struct region {
        int x0, y0, w, h;
        double *lum;
        int *mark; /* 0 outside, 1 inside, 2 + blob number once labelled */
};

static int region_load(const struct cal_image *im, const struct cal_sphere_image *s,
                       struct region *g, double *median, double *max)
{
        double rr = DISC_INNER * s->r;
        _cleanup_free_ double *vals = NULL;
        size_t n = 0;

        g->x0 = (int)fmax(0, floor(s->u - rr));
        g->y0 = (int)fmax(0, floor(s->v - rr));
        g->w = (int)fmin(im->width, ceil(s->u + rr) + 1) - g->x0;
        g->h = (int)fmin(im->height, ceil(s->v + rr) + 1) - g->y0;
        if (g->w <= 0 || g->h <= 0)
                return -ENOENT;
        g->lum = calloc((size_t)g->w * g->h, sizeof(*g->lum));
        g->mark = calloc((size_t)g->w * g->h, sizeof(*g->mark));
        vals = calloc((size_t)g->w * g->h, sizeof(*vals));
        if (!g->lum || !g->mark || !vals)
                return -ENOMEM;
        *max = 0;
        for (int y = 0; y < g->h; y++)
                for (int x = 0; x < g->w; x++) {
                        size_t i = (size_t)y * g->w + x;
                        if (hypot(g->x0 + x - s->u, g->y0 + y - s->v) > rr)
                                continue;
                        g->mark[i] = 1;
                        vals[n++] = g->lum[i] = lum(im, g->x0 + x, g->y0 + y);
                        *max = fmax(*max, g->lum[i]);
                }
        if (!n)
                return -ENOENT;
        qsort(vals, n, sizeof(*vals), gn_cmp_double);
        *median = vals[n / 2];
        return 0;
}

static void region_free(struct region *g)
{
        free(g->lum);
        free(g->mark);
}

/* Labels the blob of pixels >= thr connected (8-neighbours) to pixel i as number id. */
static void flood(struct region *g, size_t i, double thr, int id, struct blob *b, int *stack)
{
        size_t top = 0;

        g->mark[i] = 2 + id;
        stack[top++] = (int)i;
        *b = (struct blob){0};
        while (top) {
                int p = stack[--top], x = p % g->w, y = p / g->w;
                double w = g->lum[p] - thr + 1e-9; /* > 0 on a flat saturated blob */
                b->peak = fmax(b->peak, g->lum[p]);
                b->sw += w;
                b->swx += w * (g->x0 + x);
                b->swy += w * (g->y0 + y);
                for (int dy = -1; dy <= 1; dy++)
                        for (int dx = -1; dx <= 1; dx++) {
                                int nx = x + dx, ny = y + dy;
                                size_t q = (size_t)ny * g->w + nx;
                                if (nx < 0 || ny < 0 || nx >= g->w || ny >= g->h ||
                                    g->mark[q] != 1 || g->lum[q] < thr)
                                        continue;
                                g->mark[q] = 2 + id;
                                stack[top++] = (int)q;
                        }
        }
}

int cal_lamps_find_highlight(const struct cal_image *im, const struct cal_sphere_image *s,
                             double uv[2])
{
        _cleanup_(region_free) struct region g = {0};
        _cleanup_free_ int *stack = NULL;
        double med, max, thr, best = 0;
        int r, n = 0;

        uv[0] = uv[1] = NAN;
        if (!im || !im->data || !s || !(s->r > 0))
                return -EINVAL;
        if ((r = region_load(im, s, &g, &med, &max)) < 0)
                return r == -ENOENT ? 0 : r;
        if (!(max > 2 * med) || max <= 0)
                return 0;
        thr = (med + max) / 2;
        if (!(stack = calloc((size_t)g.w * g.h, sizeof(*stack))))
                return -ENOMEM;
        for (size_t i = 0; i < (size_t)g.w * g.h; i++) {
                struct blob b;
                if (g.mark[i] != 1 || g.lum[i] < thr)
                        continue;
                flood(&g, i, thr, n, &b, stack);
                if (b.peak < med + 0.9 * (max - med))
                        continue;
                n++;
                if (b.peak > best) {
                        best = b.peak;
                        uv[0] = b.swx / b.sw;
                        uv[1] = b.swy / b.sw;
                }
        }
        return n;
}
