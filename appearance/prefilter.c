/* prefilter.c - environment maps prefiltered per representative normal (prefilter.h): the
 * map box-filtered down to twice the output size, then for every output texel a weighted sum
 * over the input texels inside the lobe's cone (pairs of normals shared out to threads); SH
 * irradiance and the light lobes for the shadows. The specular lobe is gonio-sim's own
 * (sim/render/material.c), the model brdf.h describes. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/prefilter.h"
#include "appearance/sh.h"
#include "common/cleanup.h"
#include "sim/render/internal.h"

#define MAX_THREADS 16
#define NDF_TAIL    1e-4f /* samples whose NDF is below this share of its peak are left out */

/* The input map: directions, solid angles and radiance of its texels. */
struct src {
        int w, h;
        float *dir, *dw, *rgb; /* 3, 1, 3 per texel */
};

struct job {
        const struct ap_prefilter *f;
        const struct src *s;
        int k0, k1;
};

static void lat_long_dir(int w, int h, float x, float y, float d[3])
{
        double dd[3];

        ap_envmap_dir(w, h, x, y, dd);
        for (int k = 0; k < 3; k++)
                d[k] = (float)dd[k];
}

/* env box-filtered to w x h (w divides env's width or not: nearest texels averaged). */
static int downsample(const struct ap_envmap *env, int w, int h, struct src *s)
{
        s->w = w;
        s->h = h;
        s->dir = malloc(3 * sizeof(float) * w * h);
        s->dw = malloc(sizeof(float) * w * h);
        s->rgb = calloc(3 * (size_t)w * h, sizeof(float));
        if (!s->dir || !s->dw || !s->rgb)
                return -ENOMEM;
        for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                        size_t i = (size_t)y * w + x;
                        int x0 = x * env->width / w, x1 = MAX((x + 1) * env->width / w, x0 + 1);
                        int y0 = y * env->height / h, y1 = MAX((y + 1) * env->height / h, y0 + 1);
                        double acc[3] = {0}, wsum = 0;
                        for (int yy = y0; yy < y1; yy++)
                                for (int xx = x0; xx < x1; xx++) {
                                        double sw = sin(M_PI * (yy + 0.5) / env->height);
                                        for (int c = 0; c < 3; c++)
                                                acc[c] += sw * env->rgb[((size_t)yy * env->width +
                                                                         xx) * 3 +
                                                                        c];
                                        wsum += sw;
                                }
                        for (int c = 0; c < 3; c++)
                                s->rgb[3 * i + c] = (float)(acc[c] / wsum);
                        lat_long_dir(w, h, x + 0.5f, y + 0.5f, s->dir + 3 * i);
                        s->dw[i] = (float)((cos(M_PI * y / h) - cos(M_PI * (y + 1) / h)) * 2 *
                                           M_PI / w);
                }
        return 0;
}

static void src_free(struct src *s)
{
        free(s->dir);
        free(s->dw);
        free(s->rgb);
}

/* The tangent of normal n: the axis projected on its plane (any, where they are parallel). */
static struct v3 tangent_of(const struct ap_prefilter *f, struct v3 n)
{
        struct v3 ax = v3(f->p.axis[0], f->p.axis[1], f->p.axis[2]);
        struct v3 t = v3_madd(ax, n, -v3_dot(ax, n));

        if (v3_dot(t, t) < 1e-8f)
                t = v3_cross(n, fabsf(n.x) < 0.9f ? v3(1, 0, 0) : v3(0, 1, 0));
        return v3_norm(t);
}

/* One output texel (direction w) of the map for normal n: L' and A into out[4]. */
static void texel(const struct ap_prefilter *f, const struct src *s, struct v3 n, struct v3 w,
                  float cone_rad, float out[4])
{
        struct surf sf = {
                .model = SPEC_BECKMANN, .ks = 1, .ax = f->p.ax, .ay = f->p.ay, .f0 = f->p.f0};
        struct v3 t = tangent_of(f, n), b = v3_cross(n, t);
        struct v3 v = v3_madd(v3_scale(w, -1), n, 2 * v3_dot(n, w));
        double sl[3] = {0}, sd = 0, sa = 0;
        float nv = v3_dot(n, v), dmin = NDF_TAIL / ((float)M_PI * f->p.ax * f->p.ay);

        float th = acosf(CLAMP(w.z, -1.f, 1.f)), cone = cosf(cone_rad);
        int y0 = MAX(0, (int)floorf((th - cone_rad) / (float)M_PI * s->h));
        int y1 = MIN(s->h, (int)ceilf((th + cone_rad) / (float)M_PI * s->h) + 1);

        for (int i = y0 * s->w; i < y1 * s->w; i++) { /* the rows the cone reaches */
                struct v3 l = v3(s->dir[3 * i], s->dir[3 * i + 1], s->dir[3 * i + 2]);
                float nl = v3_dot(l, n);
                if (v3_dot(l, w) < cone || nl <= 0)
                        continue;
                struct v3 h = v3_norm(v3_add(l, v));
                float d = beckmann_ndf(&sf, v3_dot(h, n), v3_dot(h, t), v3_dot(h, b));
                if (d <= dmin) /* the NDF's tail: no weight in either sum */
                        continue;
                d *= s->dw[i];
                for (int c = 0; c < 3; c++)
                        sl[c] += d * s->rgb[3 * i + c];
                sd += d;
                if (nv > 0) /* brdf_cos's specular part for ks = 1, its NDF from d */
                        sa += d * beckmann_gf(&sf, t, b, l, v, h, nl, nv);
        }
        for (int c = 0; c < 3; c++)
                out[c] = sd > 0 ? (float)(sl[c] / sd) : 0;
        out[3] = (float)sa;
}

static void *prefilter_pairs(void *arg)
{
        const struct job *j = arg;
        const struct ap_prefilter *f = j->f;
        float amax = fmaxf(f->p.ax, f->p.ay), texel_rad = (float)(2 * M_PI / j->s->w);
        /* the NDF below e^-9 of its peak beyond tan(theta_h) = 3 alpha */
        float cone = fminf((float)M_PI, 2 * atanf(3 * amax) + 2 * texel_rad);

        for (int k = j->k0; k < j->k1; k++) {
                struct v3 nk = v3(f->normals[3 * k], f->normals[3 * k + 1], f->normals[3 * k + 2]);
                float *map = f->maps + (size_t)k * f->width * f->height * 4;
                for (int y = 0; y < f->height; y++)
                        for (int x = 0; x < f->width; x++) {
                                float d[3];
                                lat_long_dir(f->width, f->height, x + 0.5f, y + 0.5f, d);
                                struct v3 w = v3(d[0], d[1], d[2]);
                                struct v3 n = v3_dot(w, nk) >= 0 ? nk : v3_scale(nk, -1);
                                texel(f, j->s, n, w, cone, map + 4 * ((size_t)y * f->width + x));
                        }
        }
        return NULL;
}

static int run_jobs(struct ap_prefilter *f, const struct src *s)
{
        int nt = CLAMP(f->p.threads, 1, MIN(MAX_THREADS, f->p.pairs)), started = 0, r = 0;
        pthread_t th[MAX_THREADS];
        struct job jobs[MAX_THREADS];

        for (int i = 0; i < nt; i++) {
                jobs[i] = (struct job){f, s, f->p.pairs * i / nt, f->p.pairs * (i + 1) / nt};
                if (i == nt - 1 || pthread_create(&th[i], NULL, prefilter_pairs, &jobs[i]))
                        prefilter_pairs(&jobs[i]); /* the last share (or a failed thread's) here */
                else
                        started |= 1 << i;
        }
        for (int i = 0; i < nt; i++)
                if (started & (1 << i))
                        r |= pthread_join(th[i], NULL);
        return r ? -EIO : 0;
}

/* n points on the upper hemisphere at equal area (rows of equal z steps, golden azimuths). */
static void hemisphere_points(int n, float *out)
{
        for (int k = 0; k < n; k++) {
                double z = 1 - (k + 0.5) / n, r = sqrt(1 - z * z), ph = k * M_PI * (3 - sqrt(5.0));
                out[3 * k] = (float)(r * cos(ph));
                out[3 * k + 1] = (float)(r * sin(ph));
                out[3 * k + 2] = (float)z;
        }
}

/* The light lobes: even directions over the sphere, sharpness from their spacing, each
 * carrying the mean radiance within it times the lobe's solid angle. */
static void light_lobes(struct ap_prefilter *f, const struct src *s)
{
        hemisphere_points(AP_PREFILTER_SGS / 2, f->sg_dir);
        for (int k = 0; k < AP_PREFILTER_SGS / 2; k++)
                for (int q = 0; q < 3; q++)
                        f->sg_dir[3 * (k + AP_PREFILTER_SGS / 2) + q] = -f->sg_dir[3 * k + q];
        f->sg_eta = (float)(AP_PREFILTER_SGS / M_PI);
        for (int k = 0; k < AP_PREFILTER_SGS; k++) {
                double e = 0;
                for (int i = 0; i < s->w * s->h; i++) {
                        const float *d = s->dir + 3 * i, *g = f->sg_dir + 3 * k;
                        double lum = (s->rgb[3 * i] + s->rgb[3 * i + 1] + s->rgb[3 * i + 2]) / 3;
                        e += lum * s->dw[i] *
                             exp(f->sg_eta * (d[0] * g[0] + d[1] * g[1] + d[2] * g[2] - 1));
                }
                f->sg_mu[k] = (float)e;
        }
}

/* The clamped cosine's SH coefficients per band (Ramamoorthi and Hanrahan 2001): odd bands
 * above 1 vanish; band 4 keeps the ringing of a small bright source down. */
static void irradiance_sh(struct ap_prefilter *f, const struct ap_envmap *env)
{
        static const double band[AP_PREFILTER_SH_ORDER] = {M_PI, 2 * M_PI / 3, M_PI / 4, 0,
                                                           -M_PI / 24};
        double coef[AP_PREFILTER_SH * 3];

        ap_envmap_project(env, AP_PREFILTER_SH_ORDER, coef);
        for (int l = 0; l < AP_PREFILTER_SH_ORDER; l++)
                for (int m = l * l; m < (l + 1) * (l + 1); m++)
                        for (int c = 0; c < 3; c++)
                                f->sh[m * 3 + c] = (float)(band[l] * coef[m * 3 + c]);
}

int ap_prefilter_build(const struct ap_envmap *env, const struct ap_prefilter_params *p,
                       struct ap_prefilter *out)
{
        struct src s = {0};
        int r;

        memset(out, 0, sizeof(*out));
        if (!env || env->width < 2 || env->height < 1 || !p || p->pairs < 1 || p->pairs > 256 ||
            p->width < 8 || p->width > 1024 || !(p->ax > 0) || !(p->ay > 0))
                return -EINVAL;
        out->p = *p;
        out->width = p->width;
        out->height = p->width / 2;
        /* (cos(s / 2))^a = 1/2 at half the spacing s of the normals */
        out->a = (float)(log(0.5) / log(cos(0.5 * sqrt(2 * M_PI / p->pairs))));
        out->cmin = expf(logf(1e-3f) / out->a);
        out->normals = malloc(3 * sizeof(float) * p->pairs);
        out->maps = malloc(4 * sizeof(float) * p->pairs * out->width * out->height);
        r = out->normals && out->maps ? downsample(env, 2 * out->width, out->width, &s) : -ENOMEM;
        if (r >= 0) {
                hemisphere_points(p->pairs, out->normals);
                r = run_jobs(out, &s);
                light_lobes(out, &s);
                irradiance_sh(out, env);
        }
        src_free(&s);
        if (r < 0)
                ap_prefilter_free(out);
        return r;
}

void ap_prefilter_free(struct ap_prefilter *f)
{
        free(f->normals);
        free(f->maps);
        memset(f, 0, sizeof(*f));
}

void ap_prefilter_specular(const struct ap_prefilter *f, const float n[3], const float r[3],
                           float out[3])
{
        float phi = atan2f(r[1], r[0]), th = acosf(CLAMP(r[2], -1.f, 1.f)), wsum = 0;
        float x = phi * (float)(0.5 * M_1_PI) * f->width - 0.5f,
              y = th * (float)M_1_PI * f->height - 0.5f;

        out[0] = out[1] = out[2] = 0;
        for (int k = 0; k < f->p.pairs; k++) {
                const float *nk = f->normals + 3 * k;
                float c = fabsf(n[0] * nk[0] + n[1] * nk[1] + n[2] * nk[2]), w, px[4];
                if (c < f->cmin)
                        continue;
                w = expf(f->a * logf(c));
                ap_envmap_bilinear(f->maps + (size_t)k * f->width * f->height * 4, f->width,
                                   f->height, 4, x, y, px);
                for (int q = 0; q < 3; q++)
                        out[q] += w * px[q] * px[3];
                wsum += w;
        }
        for (int q = 0; q < 3 && wsum > 0; q++)
                out[q] /= wsum;
}

void ap_prefilter_irradiance(const struct ap_prefilter *f, const float n[3], float out[3])
{
        float y[AP_PREFILTER_SH];

        ap_sh_evalf(AP_PREFILTER_SH_ORDER, n, y);
        for (int c = 0; c < 3; c++) {
                out[c] = 0;
                for (int m = 0; m < AP_PREFILTER_SH; m++)
                        out[c] += f->sh[m * 3 + c] * y[m];
                out[c] = fmaxf(out[c], 0);
        }
}

int ap_prefilter_nearest(const struct ap_prefilter *f, const float n[3])
{
        int best = 0;
        float bc = -2;

        for (int k = 0; k < f->p.pairs; k++) {
                const float *nk = f->normals + 3 * k;
                float c = n[0] * nk[0] + n[1] * nk[1] + n[2] * nk[2];
                if (fabsf(c) > bc) {
                        bc = fabsf(c);
                        best = c >= 0 ? k : k + f->p.pairs;
                }
        }
        return best;
}
