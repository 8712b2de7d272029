/* brdf_solve.c - one texel of the BRDF fit (brdf_internal.h): nonlinear least squares with
 * GSL's multifit_nlinear (Levenberg-Marquardt, finite-difference Jacobian) over the log
 * roughness along and across the tangent, the tangent's angle about the normal and the
 * normal's tilt towards the base tangent and bitangent (where too few samples are near the
 * highlight to tell the two roughnesses apart: the tilt alone, the lobe's shape given along
 * the base tangent, or one log roughness and the tilt); for each such point the diffuse
 * weights (1 - ks) albedo per channel and ks are linear and solved in closed form, clamped
 * non-negative (variable projection). Started from the best of a few isotropic roughnesses,
 * then reweighted twice with a Cauchy loss (scale from the median residual) so that shadowed
 * or glinting samples the masks missed do not pull the fit. */
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/brdf_internal.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define NP           5 /* log ax, log ay, tangent angle, normal tilt (2) */
#define NP_ISO       3 /* log a, normal tilt (2) */
#define NP_FIXED     2 /* normal tilt (2): the lobe's shape given */
#define MAX_ITER     20
#define IRLS_ROUNDS  1
#define N_STARTS     1     /* Levenberg-Marquardt runs from the best points of a grid */
#define CAUCHY_C     2.385 /* 95% efficiency under Gaussian noise */
#define CAUCHY_FLOOR 0.002 /* the residual scale at least (full scale 1) */
#define LOG_A_MIN    (-6.0)
#define LOG_A_MAX    0.0  /* alpha 1: beyond, a lobe imitates the diffuse term */
#define RIDGE        1e-6 /* on ks, relative to the diffuse basis's energy */
#define KS_MAX       0.99

struct problem {
        const struct brdf_sample *s;
        size_t n;
        const float *w;            /* per sample, NULL: 1 */
        float n0[3], t0[3], b0[3]; /* the texel's base frame */
        float f0;
        bool lobe;                       /* false: diffuse only (ks 0) */
        enum { FREE, ISO, FIXED } shape; /* of the lobe: NP, NP_ISO or NP_FIXED parameters */
        size_t np;
        double la, lb;  /* FIXED: log ax, log ay */
        double *D, *S;  /* per sample: the bases at the last parameters (basis()) */
        double a[3], k; /* the last linear solve */
};

static void normalize3(float v[3])
{
        float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);

        for (int i = 0; i < 3 && l > 0; i++)
                v[i] /= l;
}

/* The texel of parameters p (q->np of them; albedo 0, ks 1: ap_brdf_eval gives the lobe
 * alone). */
static void texel_at(const struct problem *q, const double *pp, struct ap_brdf_texel *x)
{
        double full[NP] = {0}; /* NP values from pp's q->np: read no further */
        const double *p = q->shape == FREE ? pp : full;
        float c, s, t[3], b[3], tn;

        if (q->shape == ISO)
                full[0] = full[1] = pp[0], full[3] = pp[1], full[4] = pp[2];
        else if (q->shape == FIXED)
                full[0] = q->la, full[1] = q->lb, full[3] = pp[0], full[4] = pp[1];
        c = (float)cos(p[2]);
        s = (float)sin(p[2]);
        *x = (struct ap_brdf_texel){.ks = 1, .f0 = q->f0};
        x->ax = (float)exp(fmin(fmax(p[0], LOG_A_MIN), LOG_A_MAX));
        x->ay = (float)exp(fmin(fmax(p[1], LOG_A_MIN), LOG_A_MAX));
        for (int i = 0; i < 3; i++)
                x->normal[i] = q->n0[i] + (float)p[3] * q->t0[i] + (float)p[4] * q->b0[i];
        normalize3(x->normal);
        tn = q->t0[0] * x->normal[0] + q->t0[1] * x->normal[1] + q->t0[2] * x->normal[2];
        for (int i = 0; i < 3; i++)
                t[i] = q->t0[i] - tn * x->normal[i];
        normalize3(t);
        b[0] = x->normal[1] * t[2] - x->normal[2] * t[1];
        b[1] = x->normal[2] * t[0] - x->normal[0] * t[2];
        b[2] = x->normal[0] * t[1] - x->normal[1] * t[0];
        for (int i = 0; i < 3; i++)
                x->tangent[i] = c * t[i] + s * b[i];
}

/* Diffuse and specular basis of sample s (D = e cos_l / pi, S = e lobe) for texel x: 0 where
 * l or v is below its horizon. */
static void basis(const struct ap_brdf_texel *x, const struct brdf_sample *s, double *D, double *S)
{
        const float *n = x->normal;
        float f[3], nl = n[0] * s->l[0] + n[1] * s->l[1] + n[2] * s->l[2];
        float nv = n[0] * s->v[0] + n[1] * s->v[1] + n[2] * s->v[2];

        if (nl <= 0 || nv <= 0) {
                *D = *S = 0;
                return;
        }
        ap_brdf_eval(x, s->l, s->v, f);
        *S = s->e * f[0];
        *D = s->e * nl * M_1_PI;
}

/* The bases of every sample for texel x into q->D, q->S, then the weighted least-squares a (3)
 * and k of y ~ a_c D + k S, k >= 0 and a >= 0 (k 0 when q->lobe is false). */
static void solve_linear(struct problem *q, const struct ap_brdf_texel *x)
{
        double dd = 0, ds = 0, ss = 0, dy[3] = {0}, sy[3] = {0}, num, den;

        for (size_t i = 0; i < q->n; i++) {
                double w = q->w ? q->w[i] : 1, D, S;
                basis(x, &q->s[i], &q->D[i], &q->S[i]);
                D = q->D[i], S = q->S[i];
                dd += w * D * D, ds += w * D * S, ss += w * S * S;
                for (int c = 0; c < 3; c++)
                        dy[c] += w * D * q->s[i].y[c], sy[c] += w * S * q->s[i].y[c];
        }
        num = sy[0] + sy[1] + sy[2] - (dd > 0 ? ds * (dy[0] + dy[1] + dy[2]) / dd : 0);
        den = 3 * (ss - (dd > 0 ? ds * ds / dd : 0) + RIDGE * dd); /* k 0 where S explains none */
        q->k = q->lobe && den > 0 ? fmin(fmax(num / den, 0), KS_MAX) : 0;
        for (int c = 0; c < 3; c++)
                q->a[c] = dd > 0 ? fmax((dy[c] - q->k * ds) / dd, 0) : 0;
}

static int residuals(const gsl_vector *p, void *data, gsl_vector *f)
{
        struct problem *q = data;
        struct ap_brdf_texel x;

        texel_at(q, p->data, &x);
        solve_linear(q, &x);
        for (size_t i = 0; i < q->n; i++) {
                double w = sqrt(q->w ? q->w[i] : 1);
                for (int c = 0; c < 3; c++)
                        gsl_vector_set(f, 3 * i + c,
                                       w * (q->s[i].y[c] - q->a[c] * q->D[i] - q->k * q->S[i]));
        }
        return GSL_SUCCESS;
}

static double cost(struct problem *q, const double *p, gsl_vector *f)
{
        gsl_vector_const_view v = gsl_vector_const_view_array(p, q->np);
        double c2 = 0;

        residuals(&v.vector, q, f);
        for (size_t i = 0; i < f->size; i++)
                c2 += f->data[i] * f->data[i];
        return c2;
}

/* Levenberg-Marquardt from p (updated) on q's current weights. */
static void minimise(struct problem *q, double *p, gsl_multifit_nlinear_workspace *ws)
{
        gsl_multifit_nlinear_fdf fdf = {.f = residuals, .n = 3 * q->n, .p = q->np, .params = q};
        gsl_vector_view v = gsl_vector_view_array(p, q->np);
        int info;

        if (gsl_multifit_nlinear_init(&v.vector, &fdf, ws) != GSL_SUCCESS)
                return;
        gsl_multifit_nlinear_driver(MAX_ITER, 1e-7, 1e-9, 0, NULL, NULL, &info, ws);
        memcpy(p, gsl_multifit_nlinear_position(ws)->data, q->np * sizeof(double));
}

/* Cauchy weights of the residuals f (3 per sample) into w; the unweighted sum of squares. */
static double reweight(const struct problem *q, const gsl_vector *f, float *w, double *tmp)
{
        double ss = 0, scale;

        for (size_t i = 0; i < q->n; i++) {
                double r2 = 0, wi = q->w ? q->w[i] : 1;
                for (int c = 0; c < 3; c++)
                        r2 += f->data[3 * i + c] * f->data[3 * i + c];
                r2 = wi > 0 ? r2 / wi : 0;
                ss += r2;
                tmp[i] = sqrt(r2 / 3);
        }
        qsort(tmp, q->n, sizeof(double), gn_cmp_double);
        scale = fmax(1.4826 * tmp[q->n / 2], CAUCHY_FLOOR) * CAUCHY_C;
        for (size_t i = 0; i < q->n; i++) {
                double r2 = 0;
                for (int c = 0; c < 3; c++)
                        r2 += f->data[3 * i + c] * f->data[3 * i + c];
                r2 = (q->w && q->w[i] > 0 ? r2 / q->w[i] : r2) / 3;
                w[i] = (float)(1 / (1 + r2 / (scale * scale)));
        }
        return ss;
}

/* The starts: the N_STARTS best of a grid of roughnesses along and across the base tangent
 * and at 45 degrees to it (isotropic: its diagonal; the shape given: the base normal), best
 * first, in q's parameters. */
static void starts(struct problem *q, double p[N_STARTS][NP], gsl_vector *f)
{
        static const double alpha[] = {0.05, 0.1, 0.2, 0.4};
        double best[N_STARTS];

        for (int k = 0; k < N_STARTS; k++)
                best[k] = INFINITY;
        for (int i = 0; i < 32; i++) {
                double t[NP] = {log(alpha[i % 4]), log(alpha[i / 4 % 4]), i < 16 ? 0 : M_PI_4, 0,
                                0};
                double c2;
                int k = N_STARTS;
                if ((q->shape == ISO && (i >= 16 || i % 4 != i / 4 % 4)) ||
                    (q->shape == FIXED && i > 0))
                        continue;
                if (q->shape == ISO) /* log a, no tilt */
                        t[1] = t[2] = 0;
                if (q->shape == FIXED) /* no tilt */
                        t[0] = t[1] = 0;
                c2 = cost(q, t, f);
                while (k > 0 && c2 < best[k - 1])
                        k--;
                if (k == N_STARTS)
                        continue;
                memmove(&best[k + 1], &best[k], (N_STARTS - 1 - k) * sizeof(double));
                memmove(p[k + 1], p[k], (N_STARTS - 1 - k) * sizeof(p[0]));
                best[k] = c2;
                memcpy(p[k], t, sizeof(t));
        }
}

/* The texel's parameters from p and the last linear solve. */
static void finish(struct problem *q, const double *p, struct ap_brdf_texel *x)
{
        texel_at(q, p, x);
        solve_linear(q, x);
        x->ks = (float)q->k;
        for (int c = 0; c < 3; c++)
                x->albedo[c] = (float)(q->a[c] / (1 - q->k));
        x->flags = !q->lobe            ? AP_BRDF_DIFFUSE_ONLY
                   : q->shape == ISO   ? AP_BRDF_FITTED | AP_BRDF_ISOTROPIC
                   : q->shape == FIXED ? AP_BRDF_FITTED | AP_BRDF_LOBE_VIEW
                                       : AP_BRDF_FITTED;
        if (!q->lobe)
                x->ax = x->ay = 1;
}

/* Whether sample s is near a highlight of normal n: tan(h, n) below AP_BRDF_NEAR_TAN. */
static bool is_near(const struct brdf_sample *s, const float n[3])
{
        const float *l = s->l, *v = s->v;
        float h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]}, c, hl;

        hl = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        c = hl > 0 ? (h[0] * n[0] + h[1] * n[1] + h[2] * n[2]) / hl : 0;
        return c > 0 && sqrtf(fmaxf(1 - c * c, 0)) < AP_BRDF_NEAR_TAN * c;
}

size_t brdf_near_highlight(const struct brdf_sample *s, size_t n, const float n0[3])
{
        size_t k = 0;

        for (size_t i = 0; i < n; i++)
                k += is_near(&s[i], n0);
        return k;
}

/* At most AP_BRDF_MAX_SAMPLES of the n samples s into out: every one near a highlight of
 * normal n0 (the lobe's), an even stride of the others (the diffuse part); each group
 * strided down if it alone is over the cap. Returns how many. */
static size_t thin_samples(const struct brdf_sample *s, size_t n, const float n0[3],
                           struct brdf_sample *out)
{
        size_t near = 0, m = 0, cap = AP_BRDF_MAX_SAMPLES, keep_near, keep_far, seen[2] = {0};

        for (size_t i = 0; i < n; i++)
                near += is_near(&s[i], n0);
        keep_near = MIN(near, cap / 2 + (n - near < cap / 2 ? cap / 2 - (n - near) : 0));
        keep_far = cap - keep_near;
        for (size_t i = 0; i < n; i++) {
                bool k = is_near(&s[i], n0);
                size_t have = k ? near : n - near, want = k ? keep_near : keep_far;
                /* the j-th of its group is kept when it crosses a multiple of have / want */
                if (want && (seen[k] * want) / have != ((seen[k] + 1) * want) / have)
                        out[m++] = s[i];
                seen[k]++;
        }
        return m;
}

/* The fit proper: Levenberg-Marquardt from each start, the best reweighted and minimised
 * again; the unweighted rms. */
static double fit(struct problem *q, double *p, float *w, double *tmp)
{
        gsl_multifit_nlinear_parameters par = gsl_multifit_nlinear_default_parameters();
        gsl_multifit_nlinear_workspace *ws;
        gsl_vector *f = gsl_vector_alloc(3 * q->n);
        double ss = NAN, st[N_STARTS][NP], best = INFINITY;

        par.h_df = 1e-4; /* the model is evaluated in float */
        ws = f ? gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &par, 3 * q->n, q->np)
               : NULL;
        if (ws) {
                starts(q, st, f);
                for (int k = 0; k < (q->lobe ? N_STARTS : 1); k++) {
                        double c2;
                        minimise(q, st[k], ws);
                        c2 = cost(q, st[k], f);
                        if (c2 < best)
                                best = c2, memcpy(p, st[k], sizeof(st[k]));
                }
                for (int round = 0; round < IRLS_ROUNDS; round++) {
                        cost(q, p, f);
                        reweight(q, f, w, tmp);
                        q->w = w;
                        minimise(q, p, ws);
                }
                cost(q, p, f);
                ss = reweight(q, f, w, tmp);
                gsl_multifit_nlinear_free(ws);
        }
        gsl_vector_free(f);
        return sqrt(ss / (3.0 * q->n));
}

const struct brdf_limits brdf_texel_limits = {AP_BRDF_MIN_SAMPLES, AP_BRDF_MIN_NEAR, 0};

void brdf_solve_texel(const struct brdf_sample *s, size_t n, const struct brdf_limits *lim,
                      struct ap_brdf_texel *x)
{
        size_t near;
        _cleanup_free_ struct brdf_sample *few =
                n > AP_BRDF_MAX_SAMPLES ? malloc(AP_BRDF_MAX_SAMPLES * sizeof(*few)) : NULL;
        struct problem q;
        double p[NP] = {0}, *tmp;
        float *w;

        if (few) {
                n = thin_samples(s, n, x->normal, few);
                s = few;
        }
        q = (struct problem){.s = s, .n = n, .f0 = x->f0};
        tmp = malloc(3 * (n + 1) * sizeof(double));
        w = malloc((n + 1) * sizeof(float));

        memcpy(q.n0, x->normal, sizeof(q.n0));
        memcpy(q.t0, x->tangent, sizeof(q.t0));
        q.b0[0] = q.n0[1] * q.t0[2] - q.n0[2] * q.t0[1];
        q.b0[1] = q.n0[2] * q.t0[0] - q.n0[0] * q.t0[2];
        q.b0[2] = q.n0[0] * q.t0[1] - q.n0[1] * q.t0[0];
        near = brdf_near_highlight(q.s, q.n, q.n0);
        q.lobe = near >= lim->min_near;
        q.shape = near >= lim->min_aniso ? FREE : lim->ax > 0 ? FIXED : ISO;
        q.np = q.shape == FREE ? NP : q.shape == ISO ? NP_ISO : NP_FIXED;
        q.la = log(lim->ax > 0 ? lim->ax : 1), q.lb = log(lim->ay > 0 ? lim->ay : 1);
        if (n < lim->min_samples || !w || !tmp) {
                *x = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
        } else {
                double rms;
                q.D = tmp + n + 1, q.S = tmp + 2 * (n + 1);
                rms = fit(&q, p, w, tmp);
                finish(&q, p, x);
                x->rms = (float)rms;
        }
        x->n_samples = (uint32_t)n;
        free(w);
        free(tmp);
}
