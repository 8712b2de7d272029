/* fit_view.c - one view of the fit (fit_internal.h): its lights' images read (brackets
 * merged, dark frames subtracted, values normalised to the reference exposure) into an
 * L x 3N matrix whose columns are grouped by tile; per tile the light matrix of SH values at
 * the directions from the tile's surface point (scaled by intensity and distance), its
 * regularised pseudo-inverse, and one product with the tile's columns; pixels masked where
 * the object is not or a sample saturated; a pilot view's residuals for the model's figures;
 * the vectors projected on the basis with one product per view. */
#include <cblas.h>
#include <errno.h>
#include <float.h>
#include <fcntl.h>
#include <lapacke.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "appearance/fit_internal.h"
#include "appearance/sh.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds_png.h"

#define PNG_MAX         ((size_t)1 << 30)
#define HUGE_PAGE_BYTES ((size_t)2 << 20)

/* A view's images in memory, columns by tile: a worker's buffers (struct fit_scratch), kept
 * from one view to the next so that the hundreds of MB of samples are not faulted in (and
 * zeroed by the kernel) again for each view. */
struct vdata {
        int W, H, T, tw, th;
        size_t N;          /* 3 x pixels: the columns */
        int L;             /* lights: the rows */
        float *D;          /* L x N */
        uint32_t *col;     /* pixel (image order) -> its first column */
        float *maxv;       /* per pixel: the largest sample over lights and channels */
        uint8_t *sat;      /* per pixel: a sample saturated in some light */
        uint8_t *in;       /* per pixel: takes part (mask_pixels) */
        float *acc, *wsum; /* 3 per pixel: the merge of one light's brackets */
        float *lut;        /* a raw sample's value (direct), 2^16 */
        size_t cap_D, cap_px;
        int lay[3]; /* the W, H and T col is laid out for */
};

/* The coefficient vectors of a view's masked pixels, compact: vector i is pixel pix[i]. */
struct vcoef {
        float *coef; /* n x 3M */
        uint32_t *pix;
        size_t n;
        double sse; /* squared residuals of the sampled pixels (a pilot view) */
        size_t n_sse;
        double cond; /* the worst tile's condition number */
};

struct fit_scratch {
        struct vdata d;
        struct vcoef vc; /* the last view solved, until kept or projected */
        size_t cap;      /* vectors vc has room for */
};

static void vdata_free_px(struct vdata *d)
{
        free(d->col);
        free(d->maxv);
        free(d->sat);
        free(d->in);
        free(d->acc);
        free(d->wsum);
}

void fit_scratch_free(struct fit_scratch *s)
{
        if (s) {
                vdata_free_px(&s->d);
                free(s->d.D);
                free(s->d.lut);
                free(s->vc.coef);
                free(s->vc.pix);
                free(s);
        }
}

/* A view's L x N samples (hundreds of MB at seed scale) on transparent huge pages where the
 * kernel has them: 512 times fewer page faults (bench/fit). */
static float *alloc_samples(size_t n)
{
        void *p = NULL;

        if (posix_memalign(&p, HUGE_PAGE_BYTES, n * sizeof(float)) != 0)
                return NULL;
        (void)madvise(p, n * sizeof(float), MADV_HUGEPAGE);
        return p;
}

/* The per-pixel buffers of d for n pixels, grown when the view has more than the last. */
static int vdata_grow(struct vdata *d, size_t n)
{
        if (n <= d->cap_px)
                return 0;
        vdata_free_px(d);
        d->cap_px = 0;
        d->lay[0] = 0; /* col to be laid out again */
        d->col = malloc(n * sizeof(uint32_t));
        d->maxv = malloc(n * sizeof(float));
        d->sat = malloc(n);
        d->in = malloc(n);
        d->acc = malloc(3 * n * sizeof(float));
        d->wsum = malloc(3 * n * sizeof(float));
        if (!d->col || !d->maxv || !d->sat || !d->in || !d->acc || !d->wsum)
                return -ENOMEM;
        d->cap_px = n;
        return 0;
}

/* The columns of each pixel of a W x H view in tiles of T (skipped when d has them). */
static void vdata_layout(struct vdata *d)
{
        size_t base = 0;

        if (d->lay[0] == d->W && d->lay[1] == d->H && d->lay[2] == d->T)
                return;
        for (int ty = 0; ty < d->th; ty++)
                for (int tx = 0; tx < d->tw; tx++) {
                        int x0 = tx * d->T, y0 = ty * d->T, w = MIN(d->T, d->W - x0);
                        for (int y = y0; y < MIN(y0 + d->T, d->H); y++)
                                for (int x = x0; x < x0 + w; x++, base += 3)
                                        d->col[(size_t)y * d->W + x] = (uint32_t)base;
                }
        d->lay[0] = d->W, d->lay[1] = d->H, d->lay[2] = d->T;
}

/* d sized and laid out for view v (every row of D is written by load_light). */
static int vdata_init(struct vdata *d, const struct fit_ctx *c, const struct fit_view *v)
{
        size_t n = (size_t)v->geom.width * v->geom.height;

        d->W = v->geom.width, d->H = v->geom.height, d->T = c->o->tile;
        d->N = 3 * n, d->L = (int)v->n_lights;
        d->tw = (d->W + d->T - 1) / d->T;
        d->th = (d->H + d->T - 1) / d->T;
        if ((size_t)d->L * d->N > d->cap_D) {
                free(d->D);
                d->cap_D = 0;
                if (!(d->D = alloc_samples((size_t)d->L * d->N)))
                        return -ENOMEM;
                d->cap_D = (size_t)d->L * d->N;
        }
        if (!d->lut && !(d->lut = malloc((1 << 16) * sizeof(float))))
                return -ENOMEM;
        if (vdata_grow(d, n) < 0)
                return -ENOMEM;
        memset(d->maxv, 0, n * sizeof(float));
        memset(d->sat, 0, n);
        vdata_layout(d);
        return 0;
}

int fit_read_image(const char *dir, const struct ds_capture *r, struct gn_frame *f, char *err,
                   size_t errlen)
{
        _cleanup_free_ void *buf = NULL;
        char path[4400];
        size_t len;
        int e;

        snprintf(path, sizeof(path), "%s/%s", dir, r->file);
        e = gn_read_file_at(AT_FDCWD, path, PNG_MAX, &buf, &len);
        if (e == 0)
                e = ds_png_decode(buf, len, f);
        if (e < 0)
                snprintf(err, errlen, "%s: %s", path, strerror(-e));
        return e;
}

/* Decodes the image of row r (its file in the dataset). */
static int load(struct fit_ctx *c, const struct ds_capture *r, struct gn_frame *f)
{
        char err[512];
        int e = fit_read_image(c->dir, r, f, err, sizeof(err));

        return e < 0 ? fit_fail(c, e, "%s", err) : 0;
}

/* The dark frame of row r (a row of c->all), or NULL. */
static const struct ds_capture *dark_of(const struct fit_ctx *c, const struct ds_capture *r)
{
        size_t lo = 0, hi = c->n_all;

        while (r->dark_id > 0 && lo < hi) { /* c->all is in id order */
                size_t mid = (lo + hi) / 2;
                if (c->all[mid].id == r->dark_id)
                        return &c->all[mid];
                if (c->all[mid].id < r->dark_id)
                        lo = mid + 1;
                else
                        hi = mid;
        }
        return NULL;
}

/* Sample i of row of frame f, full scale 1. */
static inline float sample(const struct gn_frame *f, const uint8_t *row, size_t i)
{
        return f->bits == 8 ? row[i] * (1 / 255.0f) : ((const uint16_t *)row)[i] * (1 / 65535.0f);
}

/* Adds bracket r (image f, dark frame dk or NULL) to the merge sums acc/wsum (per sample). */
static void merge_bracket(const struct fit_ctx *c, const struct ds_capture *r,
                          const struct gn_frame *f, const struct gn_frame *dk, float *acc,
                          float *wsum)
{
        double gain = r->gain > 0 ? r->gain : 1;
        float w = (float)(r->exposure_us > 0 ? r->exposure_us : c->exposure_ref);
        float k = (float)(c->exposure_ref / w * c->gain_ref / gain), sat = (float)c->o->saturation;
        int step = f->channels == 3 ? 1 : 0;

        for (int y = 0; y < f->height; y++) {
                const uint8_t *row = f->data + (size_t)y * f->stride;
                const uint8_t *drow = dk ? dk->data + (size_t)y * dk->stride : NULL;
                float *a = acc + (size_t)y * f->width * 3, *ws = wsum + (size_t)y * f->width * 3;
                for (int x = 0; x < f->width; x++)
                        for (int ch = 0; ch < 3; ch++) {
                                size_t i = (size_t)x * f->channels + ch * step;
                                float v = sample(f, row, i);
                                if (v >= sat)
                                        continue;
                                if (drow)
                                        v -= sample(dk, drow, (size_t)x * dk->channels + ch * step);
                                a[3 * x + ch] += w * v * k;
                                ws[3 * x + ch] += w;
                        }
        }
}

/* Image row src (n pixels of nc channels of bits bits; step 0: grey) through lut into out
 * (3 floats a pixel); sat and maxv of its pixels updated (raw values from qsat saturate). */
static inline void direct_run(const uint8_t *restrict src, int bits, int nc, int step, int n,
                              const float *restrict lut, unsigned qsat, float *restrict out,
                              uint8_t *restrict sat, float *restrict maxv)
{
        for (int x = 0; x < n; x++, out += 3) {
                uint8_t s = sat[x];
                float m = maxv[x];
                for (int ch = 0; ch < 3; ch++) {
                        size_t i = (size_t)x * nc + ch * step;
                        unsigned q = bits == 8 ? src[i] : ((const uint16_t *)src)[i];
                        out[ch] = lut[q];
                        s |= q >= qsat;
                        m = out[ch] > m ? out[ch] : m;
                }
                sat[x] = s, maxv[x] = m;
        }
}

/* One image f without dark frame nor other brackets straight into row (the layout of d):
 * each raw value's sample through d->lut, a tile's part of an image row at a time. */
static void direct(const struct fit_ctx *c, const struct ds_capture *r, const struct gn_frame *f,
                   struct vdata *d, float *row)
{
        double gain = r->gain > 0 ? r->gain : 1, e = r->exposure_us > 0 ? r->exposure_us : 0;
        float k = (float)((e > 0 ? c->exposure_ref / e : 1) * c->gain_ref / gain);
        float sat = (float)c->o->saturation;
        unsigned nv = 1u << f->bits, qsat = nv;
        int step = f->channels == 3 ? 1 : 0, nc = f->channels, W = f->width, T = d->T;

        for (unsigned q = nv; q-- > 0;) { /* sample() of q, and the first saturated q */
                uint16_t q16 = (uint16_t)q;
                uint8_t q8 = (uint8_t)q;
                float v = sample(f, f->bits == 8 ? &q8 : (const uint8_t *)&q16, 0);
                d->lut[q] = v * k;
                qsat = v >= sat ? q : qsat;
        }
        for (int y = 0; y < f->height; y++)
                for (int x0 = 0; x0 < W; x0 += T) {
                        size_t p = (size_t)y * W + x0;
                        const uint8_t *src =
                                f->data + (size_t)y * f->stride + (size_t)x0 * nc * (f->bits / 8);
                        if (f->bits == 8 && nc == 3)
                                direct_run(src, 8, 3, 1, MIN(T, W - x0), d->lut, qsat,
                                           row + d->col[p], d->sat + p, d->maxv + p);
                        else
                                direct_run(src, f->bits, nc, step, MIN(T, W - x0), d->lut, qsat,
                                           row + d->col[p], d->sat + p, d->maxv + p);
                }
}

/* Reads light j of view v (its brackets, each minus its dark frame) into row j of d. */
static int load_light(struct fit_ctx *c, const struct fit_view *v, int j, struct vdata *d)
{
        const struct fit_light *l = &v->lights[j];
        size_t n = (size_t)d->W * d->H;
        float *row = d->D + (size_t)j * d->N, *acc = d->acc, *wsum = d->wsum;
        int r = 0;

        if (l->n > 1 || dark_of(c, v->rows[l->first])) { /* else direct() */
                memset(acc, 0, 3 * n * sizeof(float));
                memset(wsum, 0, 3 * n * sizeof(float));
        }
        for (size_t b = 0; r == 0 && b < l->n; b++) {
                const struct ds_capture *cap = v->rows[l->first + b], *dc = dark_of(c, cap);
                struct gn_frame f = {0}, dk = {0};
                r = load(c, cap, &f);
                if (r == 0 && dc)
                        r = load(c, dc, &dk);
                if (r == 0 && (f.width != d->W || f.height != d->H ||
                               (dc && (dk.width != d->W || dk.height != d->H)))) {
                        r = fit_fail(c, -EBADMSG, "%s: %dx%d, the camera's images are %dx%d",
                                     cap->file, f.width, f.height, d->W, d->H);
                }
                if (r == 0 && l->n == 1 && !dc) {
                        direct(c, cap, &f, d, row);
                        gn_frame_free_data(&f);
                        return 0;
                }
                if (r == 0)
                        merge_bracket(c, cap, &f, dc ? &dk : NULL, acc, wsum);
                gn_frame_free_data(&f);
                gn_frame_free_data(&dk);
        }
        for (size_t p = 0; r == 0 && p < n; p++)
                for (int ch = 0; ch < 3; ch++) {
                        float x = wsum[3 * p + ch] > 0 ? acc[3 * p + ch] / wsum[3 * p + ch] : 0;
                        d->sat[p] |= wsum[3 * p + ch] == 0;
                        d->maxv[p] = x > d->maxv[p] ? x : d->maxv[p];
                        row[d->col[p] + ch] = x;
                }
        return r;
}

/* The L x M light matrix of tile t: SH at the direction from its point to each lamp, times
 * the lamp's intensity and inverse-square distance relative to the reference. */
static void light_matrix(const struct fit_ctx *c, const struct fit_view *v, size_t t, double *A)
{
        const float *X = &v->points[3 * t];

        for (size_t j = 0; j < v->n_lights; j++) {
                const struct fit_light *l = &v->lights[j];
                double d[3] = {l->pos[0] - X[0], l->pos[1] - X[1], l->pos[2] - X[2]};
                double r = hypot(hypot(d[0], d[1]), d[2]),
                       s = l->scale * c->d_ref * c->d_ref / (r * r);
                for (int k = 0; k < 3; k++)
                        d[k] /= r;
                ap_sh_eval(c->order, d, &A[j * c->M]);
                for (int m = 0; m < c->M; m++)
                        A[j * c->M + m] *= s;
        }
}

/* d->in: each pixel takes part or not: the object seen (some light above the background), no
 * saturated sample, a surface point for its tile. */
static void mask_pixels(const struct fit_ctx *c, const struct fit_view *v, struct vdata *d)
{
        float bg = (float)c->o->background;

        for (int y = 0; y < d->H; y++)
                for (int x = 0; x < d->W; x++) {
                        size_t p = (size_t)y * d->W + x, t = (size_t)(y / d->T) * d->tw + x / d->T;
                        d->in[p] = !d->sat[p] && d->maxv[p] >= bg && !isnan(v->points[3 * t]);
                }
}

/* Residual of pixel p's vector x (3M) against its data: adds to vc->sse. */
static void residual(const struct fit_ctx *c, const struct vdata *d, const double *A, size_t p,
                     const float *x, struct vcoef *vc)
{
        for (int j = 0; j < d->L; j++)
                for (int ch = 0; ch < 3; ch++) {
                        double e = d->D[(size_t)j * d->N + d->col[p] + ch];
                        for (int m = 0; m < c->M; m++)
                                e -= A[j * c->M + m] * x[m * 3 + ch];
                        vc->sse += e * e;
                        vc->n_sse++;
                }
}

/* Solves tile (tx, ty): the coefficient vectors of its masked pixels appended to vc. */
static int solve_tile(const struct fit_ctx *c, const struct fit_view *v, const struct vdata *d,
                      int tx, int ty, double *A, float *P, float *Ct, struct vcoef *vc)
{
        int x0 = tx * d->T, y0 = ty * d->T, w = MIN(d->T, d->W - x0), h = MIN(d->T, d->H - y0);
        size_t first = (size_t)y0 * d->W + x0, ncols = 3 * (size_t)w * h, M3 = 3 * (size_t)c->M;
        double cond;
        bool any = false;
        int r;

        for (int y = y0; y < y0 + h && !any; y++)
                for (int x = x0; x < x0 + w && !any; x++)
                        any = d->in[(size_t)y * d->W + x];
        if (!any)
                return 0;
        light_matrix(c, v, (size_t)ty * d->tw + tx, A);
        r = ap_fit_pinv(A, d->L, c->M, c->o->reg, c->o->reg_param, P, &cond);
        if (r < 0)
                return r;
        vc->cond = fmax(vc->cond, cond);
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, c->M, (int)ncols, d->L, 1, P, d->L,
                    d->D + d->col[first], (int)d->N, 0, Ct, (int)ncols);
        for (int y = y0; y < y0 + h; y++)
                for (int x = x0; x < x0 + w; x++) {
                        size_t p = (size_t)y * d->W + x, lp = (size_t)(y - y0) * w + (x - x0);
                        float *out = vc->coef + vc->n * M3;
                        if (!d->in[p])
                                continue;
                        for (int m = 0; m < c->M; m++)
                                for (int ch = 0; ch < 3; ch++)
                                        out[m * 3 + ch] = Ct[m * ncols + lp * 3 + ch];
                        vc->pix[vc->n++] = (uint32_t)p;
                }
        return 0;
}

/* Solves every tile of view v into vc (room for cap vectors, grown to the view's pixels). */
static int solve_view(const struct fit_ctx *c, const struct fit_view *v, const struct vdata *d,
                      struct vcoef *vc, size_t *cap)
{
        size_t n = (size_t)d->W * d->H, T2 = (size_t)d->T * d->T;
        _cleanup_free_ double *A = malloc((size_t)d->L * c->M * sizeof(double));
        _cleanup_free_ float *P = malloc((size_t)d->L * c->M * sizeof(float));
        _cleanup_free_ float *Ct = malloc(3 * T2 * c->M * sizeof(float));
        int r = 0;

        if (n > *cap || !vc->coef) {
                free(vc->coef), free(vc->pix);
                *cap = 0;
                vc->coef = malloc(n * 3 * c->M * sizeof(float));
                vc->pix = malloc(n * sizeof(uint32_t));
                if (!vc->coef || !vc->pix)
                        return -ENOMEM;
                *cap = n;
        }
        *vc = (struct vcoef){.coef = vc->coef, .pix = vc->pix};
        if (!A || !P || !Ct)
                return -ENOMEM;
        for (int ty = 0; r == 0 && ty < d->th; ty++)
                for (int tx = 0; r == 0 && tx < d->tw; tx++)
                        r = solve_tile(c, v, d, tx, ty, A, P, Ct, vc);
        return r;
}

/* A pilot view: the residuals of every stride-th vector (those fit_pca samples) into c. */
static int add_residuals(struct fit_ctx *c, const struct fit_view *v, const struct vdata *d,
                         struct vcoef *vc)
{
        size_t M3 = 3 * (size_t)c->M;
        _cleanup_free_ double *A = malloc((size_t)d->L * c->M * sizeof(double));

        if (!A)
                return -ENOMEM;
        for (size_t i = 0; i < vc->n; i += c->stride) {
                size_t p = vc->pix[i];
                light_matrix(c, v, (p / d->W) / d->T * d->tw + (p % d->W) / d->T, A);
                residual(c, d, A, p, vc->coef + i * M3, vc);
        }
        pthread_mutex_lock(&c->lock);
        c->sse_sh += vc->sse;
        c->n_sse += vc->n_sse;
        pthread_mutex_unlock(&c->lock);
        return 0;
}

/* The weights and mask of model view mv from the vectors. */
static int project(struct fit_ctx *c, struct ap_view *mv, const struct fit_view *v,
                   const struct vcoef *vc)
{
        const struct ap_model *m = c->model;
        _cleanup_free_ float *w = malloc((vc->n + 1) * m->k * sizeof(float));
        int r = ap_view_alloc(mv, m->k);

        if (r < 0 || !w)
                return -ENOMEM;
        fit_pca_project(m, vc->coef, vc->n, w);
        for (size_t i = 0; i < vc->n; i++) {
                mv->mask[vc->pix[i]] = 1;
                memcpy(mv->weights + (size_t)vc->pix[i] * m->k, w + i * m->k, m->k * sizeof(float));
        }
        pthread_mutex_lock(&c->lock);
        c->masked_saturated += v->n_sat;
        pthread_mutex_unlock(&c->lock);
        return 0;
}

void fit_view_keep(struct fit_ctx *c, size_t i, struct fit_scratch *s)
{
        struct fit_view *v = &c->views[i];
        float *coef = realloc(s->vc.coef, (s->vc.n + 1) * 3 * c->M * sizeof(float));

        v->kept = coef ?: s->vc.coef;
        v->kept_pix = s->vc.pix;
        v->n_kept = s->vc.n;
        s->vc = (struct vcoef){0};
        s->cap = 0;
}

int fit_view_solve(struct fit_ctx *c, size_t i, struct fit_scratch **sp)
{
        struct fit_view *v = &c->views[i];
        struct fit_scratch *s = *sp ?: (*sp = calloc(1, sizeof(**sp)));
        struct vdata *d = s ? &s->d : NULL;
        int r = s ? vdata_init(d, c, v) : -ENOMEM;

        for (int j = 0; r == 0 && j < d->L; j++)
                r = load_light(c, v, j, d);
        if (r == 0) {
                mask_pixels(c, v, d);
                r = solve_view(c, v, d, &s->vc, &s->cap);
        }
        for (size_t p = 0; r == 0 && p < (size_t)d->W * d->H; p++)
                v->n_sat += d->sat[p] && d->maxv[p] >= c->o->background;
        if (r == 0 && v->pilot)
                r = add_residuals(c, v, d, &s->vc);
        if (r == 0) {
                pthread_mutex_lock(&c->lock);
                c->cond_max = fmax(c->cond_max, s->vc.cond);
                pthread_mutex_unlock(&c->lock);
        }
        return r;
}

int fit_view_project(struct fit_ctx *c, size_t i, struct fit_scratch *s)
{
        struct fit_view *v = &c->views[i];
        struct vcoef kept = {.coef = v->kept, .pix = v->kept_pix, .n = v->n_kept};
        int r = project(c, &c->model->views[i], v, v->kept ? &kept : &s->vc);

        free(v->kept), free(v->kept_pix);
        v->kept = NULL, v->kept_pix = NULL;
        return r;
}

int ap_fit_pinv(const double *A, int L, int M, enum ap_reg reg, double param, float *pinv,
                double *cond)
{
        enum { MM = AP_ORDER_MAX * AP_ORDER_MAX };
        double N[MM * MM], NF[MM * MM], ev[MM], G[MM * MM], top;

        if (L < 1 || M < 1 || M > MM || param < 0)
                return -EINVAL;
        /* the normal matrix A^T A = V diag(ev) V^T (ascending) */
        cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, M, L, 1, A, M, 0, N, M);
        if (LAPACKE_dsyevd(LAPACK_ROW_MAJOR, 'V', 'U', M, N, M, ev) != 0)
                return -EDOM;
        top = fmax(ev[M - 1], DBL_MIN);
        /* G = V diag(f) V^T, f the regularised inverse of each eigenvalue (sigma^2) */
        for (int i = 0; i < M; i++) {
                double e = fmax(ev[i], 0);
                double f = reg == AP_REG_TSVD ? (e > param * param * top ? 1 / e : 0)
                                              : 1 / (e + param * param * top);
                for (int a = 0; a < M; a++)
                        NF[a * M + i] = N[a * M + i] * f;
        }
        for (int a = 0; a < M; a++)
                for (int b = a; b < M; b++) {
                        double x = 0;
                        for (int i = 0; i < M; i++)
                                x += NF[a * M + i] * N[b * M + i];
                        G[a * M + b] = G[b * M + a] = x;
                }
        for (int m = 0; m < M; m++) /* pinv = G A^T */
                for (int j = 0; j < L; j++) {
                        double x = 0;
                        for (int i = 0; i < M; i++)
                                x += G[m * M + i] * A[j * M + i];
                        pinv[m * L + j] = (float)x;
                }
        if (cond) /* eigenvalues below 1e-16 of the largest are rounding: 1e8 at most */
                *cond = sqrt(top / fmax(ev[0], 1e-16 * top));
        return 0;
}
