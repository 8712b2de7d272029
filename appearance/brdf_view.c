/* brdf_view.c - the BRDF model without a mesh (brdf_internal.h; docs/appearance.md, "The
 * view-kind BRDF model"): per view, its lamp-lit images read once (brdf_image_read), the
 * object where some image is above the background; per pixel of it, its samples that pixel
 * under every lamp of the view (one view direction), the lights placed from its surface point:
 * the depth on its ray, about the point nearest the object's centre (fit_nominal_point, where
 * the SH fit puts its tiles without a mesh), that a Lambertian fit explains best; a base normal
 * by photometric stereo (that fit, without the highlights and the unlit); then the texels'
 * solver (brdf_solve.c) with the view kind's limits. With one view direction the highlight is
 * sampled only where the lamps put it: the pixels with enough samples near it are fitted in
 * full first, and the medians of their roughnesses (the view's lobe shape) are given to the
 * others (AP_BRDF_LOBE_VIEW), or, where a view has too few such pixels, one roughness is fitted
 * (AP_BRDF_ISOTROPIC). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/brdf_internal.h"
#include "appearance/fit_internal.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define PS_ROUNDS       4
#define PS_MIN_VALUE    0.005 /* a sample below this (full scale 1) is left out of the first round */
#define PS_CUT          3.0   /* a sample this many robust sigmas above the fit is a highlight */
#define PS_TRUNC        0.02  /* a residual counts this much at most in a depth's cost */
#define DEPTH_STEPS     8     /* depths tried each side of the nominal point */
#define VIEW_MIN_SHAPES 16    /* pixels with the lobe's shape fitted for the view's medians */

static const struct brdf_limits view_limits = {AP_BRDF_VIEW_MIN_SAMPLES, AP_BRDF_MIN_NEAR,
                                               AP_BRDF_VIEW_MIN_ANISO, 0, 0};

/* One view being fitted: its images and what the pixels share. */
struct vfit {
        const struct brdf_ctx *c;
        const struct ap_shot *shots; /* its lamp-lit images */
        size_t L, npx;
        struct ap_brdf_view *v;
        double C[3];  /* the camera's centre */
        double depth; /* the surface searched this far (mm) each side of the nominal points */
        struct brdf_limits lim;
        bool again;   /* the second pass: the pixels left for it (AP_BRDF_ISOTROPIC on entry) */
        float *y;     /* L x npx x 3 */
        uint8_t *sat; /* L x npx */
        uint8_t *in;  /* npx: the object */
};

struct worker {
        struct vfit *f;
        int k, n; /* pixels k, k + n, ... */
        size_t n_sat, invalid;
};

static double gray(const float y[3])
{
        return (y[0] + y[1] + y[2]) / 3.0;
}

/* The solution of the 3 x 3 system A x = r (Cramer); false when singular. */
static bool solve3(const double A[9], const double r[3], double x[3])
{
        double d = A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
                   A[2] * (A[3] * A[7] - A[4] * A[6]);

        if (!(fabs(d) > 1e-30))
                return false;
        for (int k = 0; k < 3; k++) {
                double M[9];
                memcpy(M, A, sizeof(M));
                for (int i = 0; i < 3; i++)
                        M[3 * i + k] = r[i];
                x[k] = (M[0] * (M[4] * M[8] - M[5] * M[7]) - M[1] * (M[3] * M[8] - M[5] * M[6]) +
                        M[2] * (M[3] * M[7] - M[4] * M[6])) /
                       d;
        }
        return true;
}

/* Sample s's residual against the Lambertian b (albedo times normal), or NAN where b puts it
 * in shadow. */
static double ps_residual(const struct brdf_sample *s, const double b[3])
{
        double bl = b[0] * s->l[0] + b[1] * s->l[1] + b[2] * s->l[2];

        return bl > 0 ? gray(s->y) - s->e * M_1_PI * bl : NAN;
}

/* A Lambertian fit to the gray values of samples s (y ~ e / pi b . l), each round without the
 * samples the last one put in shadow or far above it (highlights): the unit normal into nrm
 * and the fit's cost (squared residuals truncated at PS_TRUNC, over the samples it lights or
 * that are bright); INFINITY when it is degenerate. tmp holds n doubles. */
static double ps_fit(const struct brdf_sample *s, size_t n, double *tmp, float nrm[3])
{
        double b[3] = {0}, cut = INFINITY, len, cost = 0;

        for (int round = 0; round < PS_ROUNDS; round++) {
                double A[9] = {0}, r[3] = {0};
                size_t k = 0;
                for (size_t i = 0; i < n; i++) {
                        double res = round ? ps_residual(&s[i], b) : 0, g = gray(s[i].y);
                        if (round ? !(fabs(res) <= cut) : g < PS_MIN_VALUE)
                                continue;
                        for (int p = 0; p < 3; p++) {
                                r[p] += s[i].e * M_1_PI * s[i].l[p] * g;
                                for (int q = 0; q < 3; q++)
                                        A[3 * p + q] += s[i].e * s[i].e * M_1_PI * M_1_PI *
                                                        s[i].l[p] * s[i].l[q];
                        }
                }
                if (!solve3(A, r, b))
                        return INFINITY;
                for (size_t i = 0; i < n; i++)
                        if (!isnan(tmp[k] = fabs(ps_residual(&s[i], b))))
                                k++;
                if (k < 3)
                        return INFINITY;
                cut = fmax(PS_CUT * 1.4826 * gn_median(tmp, k), PS_MIN_VALUE);
        }
        len = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        for (int p = 0; p < 3 && len > 0; p++)
                nrm[p] = (float)(b[p] / len);
        for (size_t i = 0; i < n; i++) {
                double res = ps_residual(&s[i], b);
                if (isnan(res))
                        res = gray(s[i].y) >= PS_MIN_VALUE ? PS_TRUNC : 0;
                cost += fmin(res * res, PS_TRUNC * PS_TRUNC);
        }
        return len > 0 ? cost : INFINITY;
}

/* The samples of pixel p into s (L at most), its surface point at X: every unsaturated image
 * (the saturated counted into *n_sat when not NULL). Returns how many. */
static size_t pixel_samples(const struct vfit *f, size_t p, const double X[3],
                            struct brdf_sample *s, size_t *n_sat)
{
        double d[3], len = 0;
        size_t n = 0;

        for (int k = 0; k < 3; k++)
                d[k] = f->C[k] - X[k], len += d[k] * d[k];
        for (size_t j = 0; j < f->L; j++) {
                const struct ap_shot *sh = &f->shots[j];
                double l[3], r2 = 0;
                if (f->sat[j * f->npx + p]) {
                        *(n_sat ? n_sat : &(size_t){0}) += 1;
                        continue;
                }
                for (int k = 0; k < 3; k++)
                        l[k] = sh->lamp[k] - X[k], r2 += l[k] * l[k];
                for (int k = 0; k < 3; k++) {
                        s[n].l[k] = (float)(l[k] / sqrt(r2));
                        s[n].v[k] = (float)(d[k] / sqrt(len));
                        s[n].y[k] = f->y[3 * (j * f->npx + p) + k];
                }
                s[n++].e = (float)(f->c->response * sh->intensity / r2);
        }
        return n;
}

/* The point at depth t (mm, away from the camera) from pixel p's nominal point into X. */
static void point_at(const struct vfit *f, size_t p, double t, double X[3])
{
        const float *X0 = &f->v->points[3 * p];
        double d[3], len = 0;

        for (int k = 0; k < 3; k++)
                d[k] = X0[k] - f->C[k], len += d[k] * d[k];
        for (int k = 0; k < 3; k++)
                X[k] = X0[k] + t * d[k] / sqrt(len);
}

/* Pixel p's surface point on its ray (without a mesh its depth is unknown): of the depths
 * within f->depth of its nominal point, the one whose lights' directions and distances the
 * Lambertian fit explains best (a parabola through the best of a grid and its neighbours),
 * into X and the pixel's point. */
static void pixel_point(const struct vfit *f, size_t p, struct brdf_sample *s, double *tmp,
                        double X[3])
{
        double c[2 * DEPTH_STEPS + 1], h = f->depth / DEPTH_STEPS, t;
        float nrm[3];
        int best = DEPTH_STEPS;

        for (int i = 0; i <= 2 * DEPTH_STEPS; i++) {
                point_at(f, p, h * (i - DEPTH_STEPS), X);
                c[i] = ps_fit(s, pixel_samples(f, p, X, s, NULL), tmp, nrm);
                if (c[i] < c[best])
                        best = i;
        }
        t = h * (best - DEPTH_STEPS);
        if (best > 0 && best < 2 * DEPTH_STEPS && isfinite(c[best - 1]) && isfinite(c[best + 1]) &&
            c[best - 1] - 2 * c[best] + c[best + 1] > 0)
                t += h * (c[best - 1] - c[best + 1]) /
                     (2 * (c[best - 1] - 2 * c[best] + c[best + 1]));
        point_at(f, p, t, X);
        for (int k = 0; k < 3; k++)
                f->v->points[3 * p + k] = (float)X[k];
}

/* Fits pixel p (its samples in s, L of room; tmp L doubles) into f->v->px[p]. */
static void fit_pixel(struct worker *w, size_t p, struct brdf_sample *s, double *tmp)
{
        struct ap_brdf_texel *x = &w->f->v->px[p];
        double X[3];
        size_t n, k = 0;

        if (w->f->again)
                for (int q = 0; q < 3; q++)
                        X[q] = w->f->v->points[3 * p + q];
        else
                pixel_point(w->f, p, s, tmp, X);
        n = pixel_samples(w->f, p, X, s, w->f->again ? NULL : &w->n_sat);
        if (!isfinite(ps_fit(s, n, tmp, x->normal))) {
                *x = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
                return;
        }
        for (size_t i = 0; i < n; i++) /* those below the base normal's horizon: unlit */
                if (s[i].l[0] * x->normal[0] + s[i].l[1] * x->normal[1] + s[i].l[2] * x->normal[2] >
                    0)
                        s[k++] = s[i];
        brdf_base_tangent(x->normal, x->tangent);
        x->f0 = (float)w->f->c->f0;
        if (!w->f->again && k >= w->f->lim.min_samples &&
            brdf_near_highlight(s, k, x->normal) < w->f->lim.min_aniso) {
                x->flags = AP_BRDF_ISOTROPIC; /* for the second pass, the lobe's shape known */
                return;
        }
        brdf_solve_texel(s, k, &w->f->lim, x);
        if (!ap_brdf_texel_valid(x)) {
                *x = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
                w->invalid++;
        }
}

static void *work(void *arg)
{
        struct worker *w = arg;
        struct vfit *f = w->f;
        _cleanup_free_ struct brdf_sample *s = malloc((f->L + 1) * sizeof(*s));
        _cleanup_free_ double *tmp = malloc((f->L + 1) * sizeof(double));

        for (size_t p = (size_t)w->k; p < f->npx; p += (size_t)w->n) {
                if (f->again && f->v->px[p].flags != AP_BRDF_ISOTROPIC)
                        continue;
                if (!f->in[p] || !s || !tmp) {
                        f->v->px[p] = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
                        continue;
                }
                fit_pixel(w, p, s, tmp);
        }
        return NULL;
}

/* View i's camera, direction and each pixel's point; its centre into c0. */
static int view_setup(const struct brdf_ctx *c, size_t i, struct vfit *f, double c0[3])
{
        const struct ap_camera *g = &c->g->cameras[i];
        double len = 0;

        f->v->cam = *g;
        f->npx = (size_t)g->width * g->height;
        f->v->px = calloc(f->npx, sizeof(*f->v->px));
        f->v->points = malloc(3 * f->npx * sizeof(float));
        f->y = malloc(3 * f->L * f->npx * sizeof(float));
        f->sat = malloc(f->L * f->npx);
        f->in = calloc(f->npx, 1);
        if (!f->v->px || !f->v->points || !f->y || !f->sat || !f->in)
                return -ENOMEM;
        fit_camera_centre(g, c0);
        for (int k = 0; k < 3; k++) {
                f->C[k] = -(g->R[k] * g->t[0] + g->R[3 + k] * g->t[1] + g->R[6 + k] * g->t[2]);
                len += (f->C[k] - c0[k]) * (f->C[k] - c0[k]);
        }
        for (int k = 0; k < 3; k++)
                f->v->dir[k] = (f->C[k] - c0[k]) / sqrt(len);
        for (size_t p = 0; p < f->npx; p++) {
                double uv[2] = {(double)(p % g->width), (double)(p / g->width)}, X[3];
                fit_nominal_point(g, c0, uv, X);
                for (int k = 0; k < 3; k++)
                        f->v->points[3 * p + k] = (float)X[k];
        }
        return 0;
}

/* Reads the view's images; the object where some sample is above the background. */
static int view_read(const struct brdf_ctx *c, struct vfit *f)
{
        for (size_t j = 0; j < f->L; j++) {
                struct brdf_image im = {f->v->cam.width, f->v->cam.height, f->y + 3 * j * f->npx,
                                        f->sat + j * f->npx};
                int r = brdf_image_read(c, f->shots[j].row, &im);
                if (r < 0)
                        return r;
                for (size_t p = 0; p < f->npx; p++)
                        f->in[p] |= gray(&im.px[3 * p]) >= c->o->background;
        }
        return 0;
}

/* The object's radius about the centre c0: the farthest nominal point of the object's pixels
 * (those of its silhouette lie on it). */
static double view_radius(const struct vfit *f, const double c0[3])
{
        double r2 = 0;

        for (size_t p = 0; p < f->npx; p++) {
                const float *X = &f->v->points[3 * p];
                if (f->in[p])
                        r2 = fmax(r2, (X[0] - c0[0]) * (X[0] - c0[0]) +
                                              (X[1] - c0[1]) * (X[1] - c0[1]) +
                                              (X[2] - c0[2]) * (X[2] - c0[2]));
        }
        return sqrt(r2);
}

/* The medians of the roughnesses of v's pixels whose lobe's shape was fitted, ax along the
 * base tangent (their tangent's nearer axis), into v->ax, v->ay; 0 when fewer than
 * VIEW_MIN_SHAPES. Returns 0 or -ENOMEM. */
static int view_shape(const struct vfit *f)
{
        _cleanup_free_ float *a = malloc(2 * (f->npx + 1) * sizeof(float));
        size_t k = 0;

        if (!a)
                return -ENOMEM;
        for (size_t p = 0; p < f->npx; p++) {
                const struct ap_brdf_texel *x = &f->v->px[p];
                float t[3], c;
                if (x->flags != AP_BRDF_FITTED)
                        continue;
                brdf_base_tangent(x->normal, t);
                c = t[0] * x->tangent[0] + t[1] * x->tangent[1] + t[2] * x->tangent[2];
                a[k] = fabsf(c) > (float)M_SQRT1_2 ? x->ax : x->ay;
                a[f->npx + 1 + k++] = fabsf(c) > (float)M_SQRT1_2 ? x->ay : x->ax;
        }
        if (k < VIEW_MIN_SHAPES)
                return 0;
        qsort(a, k, sizeof(float), gn_cmp_float);
        qsort(a + f->npx + 1, k, sizeof(float), gn_cmp_float);
        f->v->ax = a[k / 2], f->v->ay = a[f->npx + 1 + k / 2];
        return 0;
}

/* The pixels of f on threads, in f's pass; the counts into tot. */
static void run(struct vfit *f, int threads, struct worker *tot)
{
        struct worker w[16];

        for (int k = 0; k < threads; k++)
                w[k] = (struct worker){.f = f, .k = k, .n = threads};
        brdf_run_threads(threads, work, w, sizeof(w[0]));
        for (int k = 0; k < threads; k++) {
                tot->n_sat += w[k].n_sat;
                tot->invalid += w[k].invalid;
        }
}

/* Fits view i (shots [first, last) of c->g) into v, the counts into tot: the pixels with
 * enough samples near their highlight for the lobe's shape, then the others with the view's
 * shape (their medians) where it has one, else isotropic. */
static int fit_one(const struct brdf_ctx *c, size_t i, size_t first, size_t last,
                   struct ap_brdf_view *v, double c0[3], struct worker *tot)
{
        struct vfit f = {.c = c,
                         .shots = &c->g->shots[first],
                         .L = last - first,
                         .v = v,
                         .lim = view_limits};
        int r = view_setup(c, i, &f, c0);

        if (r == 0)
                r = view_read(c, &f);
        if (r == 0) {
                f.depth = view_radius(&f, c0);
                run(&f, c->o->threads, tot);
                r = view_shape(&f);
        }
        if (r == 0) {
                f.again = true;
                f.lim.ax = v->ax, f.lim.ay = v->ay, f.lim.min_near = v->ax > 0 ? 1 : f.lim.min_near;
                run(&f, c->o->threads, tot);
        }
        free(f.y);
        free(f.sat);
        free(f.in);
        return r;
}

/* The pixels by outcome and the samples left out, into m's notes. */
static void summarise(struct ap_brdf_model *m, const struct worker *tot)
{
        size_t k[5] = {0}, shaped = 0;

        for (size_t i = 0; i < m->n_views; i++) {
                const struct ap_brdf_view *v = &m->views[i];
                shaped += v->ax > 0;
                for (size_t p = 0; p < (size_t)v->cam.width * v->cam.height; p++) {
                        uint32_t fl = v->px[p].flags;
                        k[fl & AP_BRDF_MASKED ? 0 : fl & AP_BRDF_DIFFUSE_ONLY ? 1 : 2]++;
                        k[3] += (fl & AP_BRDF_ISOTROPIC) != 0;
                        k[4] += (fl & AP_BRDF_LOBE_VIEW) != 0;
                }
        }
        brdf_note(m->notes, sizeof(m->notes),
                  "per pixel of %zu views: %zu fitted, of them with fewer than %d samples near "
                  "the highlight %zu given their view's lobe shape (%zu views had one) and %zu "
                  "isotropic; %zu diffuse only (too few samples near the highlight), %zu "
                  "masked (background, or fewer than %d lit unsaturated samples)",
                  m->n_views, k[2], AP_BRDF_VIEW_MIN_ANISO, k[4], shaped, k[3], k[1], k[0],
                  AP_BRDF_VIEW_MIN_SAMPLES);
        if (tot->invalid)
                brdf_note(m->notes, sizeof(m->notes),
                          "%zu pixels masked: their solve gave no valid parameters", tot->invalid);
        if (tot->n_sat)
                brdf_note(m->notes, sizeof(m->notes), "%zu saturated samples left out", tot->n_sat);
}

int brdf_view_fit(struct brdf_ctx *c, struct ap_brdf_model *m)
{
        struct worker tot = {0};
        size_t n = 0;
        int r = 0;

        for (size_t k = 0; k < c->g->n_shots; k++)
                n += k == 0 || c->g->shots[k].view != c->g->shots[k - 1].view;
        m->kind = AP_BRDF_KIND_VIEW;
        m->views = calloc(n, sizeof(*m->views));
        if (!m->views)
                return -ENOMEM;
        for (size_t k = 0, j; r == 0 && k < c->g->n_shots; k = j) { /* shots grouped by view */
                double c0[3] = {0};
                for (j = k + 1; j < c->g->n_shots && c->g->shots[j].view == c->g->shots[k].view;)
                        j++;
                r = fit_one(c, c->g->shots[k].view, k, j, &m->views[m->n_views++], c0, &tot);
                for (int q = 0; q < 3; q++)
                        m->centre[q] += c0[q] / (double)n;
        }
        if (r == 0)
                summarise(m, &tot);
        return r;
}
