/* render_env.c - environment relighting of the BRDF model (render_env.h): the visibility of
 * the diffuse light per vertex and on a ground grid when the renderer is made; per frame,
 * bands of rows rasterised and shaded by threads. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/render_env.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define MAX_THREADS 16
#define COS_ETA     2.133f /* the cosine lobe as one SG (seed 000, section 4.5) */
#define COS_MU      1.170f

struct ap_env_renderer {
        struct ap_env_scene sc;
        struct ap_spheres none; /* no spheres: only the table of visible fractions */
        const struct ap_spheres *sp;
        float *vvis;  /* per vertex: V_d */
        float *tex_e; /* per texel: E at its normal (RGB) */
        float *gvis;  /* AP_ENV_GROUND_GRID^2: V_d on the ground */
        float ground_e[3];
        struct ap_pinhole ph;
        float *depth;
        int32_t *tri;
        size_t cap;
};

struct band {
        const struct ap_env_renderer *r;
        float Rt[9], C[3];
        int y0, y1, ret;
        float *rgb;
        uint8_t *mask;
};

static float dot3(const float *a, const float *b)
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The angle of z above the ground's horizon: the plane's SSDF. */
static float plane_ssdf(const struct ap_env_renderer *r, const float z[3])
{
        return r->sc.ground_radius > 0 ? asinf(CLAMP(z[2], -1.f, 1.f)) : (float)M_PI_2;
}

/* V_d at p (normal n): the light lobes times the cosine lobe (eq. 11), their visible
 * fractions (eq. 12) weighted by their integrals. on_ground: p is on the plane itself. */
static float diffuse_vis(const struct ap_env_renderer *r, const float p[3], const float n[3],
                         bool on_ground)
{
        const struct ap_prefilter *pf = r->sc.pf;
        double num = 0, den = 0;

        for (int k = 0; k < AP_PREFILTER_SGS; k++) {
                const float *zk = pf->sg_dir + 3 * k;
                float zm[3], len, z[3], eta, mu, td, tp;
                for (int q = 0; q < 3; q++)
                        zm[q] = pf->sg_eta * zk[q] + COS_ETA * n[q];
                len = sqrtf(dot3(zm, zm));
                if (len <= 0)
                        continue;
                for (int q = 0; q < 3; q++)
                        z[q] = zm[q] / len;
                eta = len;
                mu = pf->sg_mu[k] * COS_MU * expf(len - pf->sg_eta - COS_ETA);
                double full = mu * 2 * M_PI / eta * (1 - exp(-2 * eta));
                /* the point's own tangent plane cuts both: E(n) holds only the light above it */
                tp = asinf(CLAMP(dot3(z, n), -1.f, 1.f));
                td = fminf(ap_ssdf(r->sp, p, n, z), tp);
                if (!on_ground)
                        td = fminf(td, plane_ssdf(r, z));
                num += full * ap_sg_visible(r->sp, td, eta);
                den += full * ap_sg_visible(r->sp, tp, eta);
        }
        return den > 0 ? (float)(num / den) : 1;
}

static int vertex_visibility(struct ap_env_renderer *r)
{
        const struct ap_mesh *m = &r->sc.m->atlas.mesh;
        _cleanup_free_ float *nrm = calloc(3 * m->nv, sizeof(float));

        r->vvis = malloc(m->nv * sizeof(float));
        if (!nrm || !r->vvis)
                return -ENOMEM;
        for (size_t t = 0; t < m->nt; t++) { /* area-weighted: the cross product's length */
                const uint32_t *ix = m->idx + 3 * t;
                const float *a = m->pos + 3 * ix[0], *b = m->pos + 3 * ix[1],
                            *c = m->pos + 3 * ix[2];
                float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
                float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
                float fn[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                               e1[0] * e2[1] - e1[1] * e2[0]};
                for (int k = 0; k < 3; k++)
                        for (int q = 0; q < 3; q++)
                                nrm[3 * ix[k] + q] += fn[q] * (m->front < 0 ? -1.f : 1.f);
        }
        for (size_t i = 0; i < m->nv; i++) {
                float *n = nrm + 3 * i, l = sqrtf(dot3(n, n));
                for (int q = 0; q < 3 && l > 0; q++)
                        n[q] /= l;
                r->vvis[i] = diffuse_vis(r, m->pos + 3 * i, n, false);
        }
        return 0;
}

static int texel_irradiance(struct ap_env_renderer *r)
{
        const struct ap_brdf_model *m = r->sc.m;
        size_t n = (size_t)m->atlas.width * m->atlas.height;

        r->tex_e = malloc(3 * n * sizeof(float));
        if (!r->tex_e)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                ap_prefilter_irradiance(r->sc.pf, m->texels[i].normal, r->tex_e + 3 * i);
        return 0;
}

static int ground_visibility(struct ap_env_renderer *r)
{
        const int g = AP_ENV_GROUND_GRID;
        const float up[3] = {0, 0, 1}, R = r->sc.ground_radius;

        r->gvis = malloc(sizeof(float) * g * g);
        if (!r->gvis)
                return -ENOMEM;
        for (int j = 0; j < g; j++)
                for (int i = 0; i < g; i++) {
                        float p[3] = {-R + 2 * R * i / (g - 1), -R + 2 * R * j / (g - 1), 0.01f};
                        r->gvis[j * g + i] = diffuse_vis(r, p, up, true);
                }
        ap_prefilter_irradiance(r->sc.pf, up, r->ground_e);
        return 0;
}

int ap_env_renderer_new(const struct ap_env_scene *sc, struct ap_env_renderer **ret)
{
        struct ap_env_renderer *r;
        int e;

        if (!sc || !sc->m || (!sc->light && (!sc->env || !sc->pf)) || !sc->m->atlas.mesh.nt ||
            !sc->m->texels)
                return -EINVAL;
        r = calloc(1, sizeof(*r));
        if (!r)
                return -ENOMEM;
        r->sc = *sc;
        ap_spheres_table(&r->none);
        r->sp = sc->sp ? sc->sp : &r->none;
        e = sc->light ? 0 : vertex_visibility(r);
        if (e >= 0 && !sc->light)
                e = texel_irradiance(r);
        if (e >= 0 && sc->ground_radius > 0 && !sc->light)
                e = ground_visibility(r);
        if (e < 0) {
                ap_env_renderer_free(r);
                return e;
        }
        *ret = r;
        return 0;
}

struct ap_env_renderer *ap_env_renderer_free(struct ap_env_renderer *r)
{
        if (!r)
                return NULL;
        free(r->vvis);
        free(r->tex_e);
        free(r->gvis);
        free(r->depth);
        free(r->tri);
        free(r);
        return NULL;
}

/* The map's radiance along unit d (bilinear, as gonio-sim's dome). */
static void env_lookup(const struct ap_envmap *e, const float d[3], float out[3])
{
        float x = atan2f(d[1], d[0]) * (float)(0.5 * M_1_PI) * e->width - 0.5f;
        float y = acosf(CLAMP(d[2], -1.f, 1.f)) * (float)M_1_PI * e->height - 0.5f;

        ap_envmap_bilinear(e->rgb, e->width, e->height, 3, x, y, out);
}

/* Barycentric coordinates of p in triangle t of m. */
static void bary_of(const struct ap_mesh *m, int32_t t, const float p[3], float w[3])
{
        const float *a = m->pos + 3 * m->idx[3 * t], *b = m->pos + 3 * m->idx[3 * t + 1];
        const float *c = m->pos + 3 * m->idx[3 * t + 2];
        float v0[3], v1[3], v2[3];

        for (int q = 0; q < 3; q++) {
                v0[q] = b[q] - a[q];
                v1[q] = c[q] - a[q];
                v2[q] = p[q] - a[q];
        }
        float d00 = dot3(v0, v0), d01 = dot3(v0, v1), d11 = dot3(v1, v1);
        float d20 = dot3(v2, v0), d21 = dot3(v2, v1), den = d00 * d11 - d01 * d01;
        w[1] = den != 0 ? (d11 * d20 - d01 * d21) / den : 1.f / 3;
        w[2] = den != 0 ? (d00 * d21 - d01 * d20) / den : 1.f / 3;
        w[0] = 1 - w[1] - w[2];
}

/* The texel of triangle t at barycentric w: the one under its uv, or a neighbour of t's. */
static const struct ap_brdf_texel *texel_at(const struct ap_brdf_model *m, int32_t t,
                                            const float w[3])
{
        const struct ap_atlas *a = &m->atlas;
        const float *uv = a->uv + 6 * t;
        float u = w[0] * uv[0] + w[1] * uv[2] + w[2] * uv[4];
        float v = w[0] * uv[1] + w[1] * uv[3] + w[2] * uv[5];
        int x = CLAMP((int)(u * a->width), 0, a->width - 1);
        int y = CLAMP((int)(v * a->height), 0, a->height - 1);

        for (int k = 0; k < 9; k++) {
                int xx = CLAMP(x + (k % 3 + 1) % 3 - 1, 0, a->width - 1);
                int yy = CLAMP(y + (k / 3 + 1) % 3 - 1, 0, a->height - 1);
                if (a->tri[(size_t)yy * a->width + xx] == t)
                        return &m->texels[(size_t)yy * a->width + xx];
        }
        return &m->texels[(size_t)y * a->width + x];
}

/* Up to four texels of triangle t around its point of barycentric w, bilinear weights
 * summing to 1; masked texels and other triangles' left out (texel_at's alone when none is
 * left). */
struct taps {
        size_t i[4];
        float w[4];
        int n;
};

static void texel_taps(const struct ap_brdf_model *m, int32_t t, const float w[3], struct taps *tp)
{
        const struct ap_atlas *a = &m->atlas;
        const float *uv = a->uv + 6 * t;
        float u = (w[0] * uv[0] + w[1] * uv[2] + w[2] * uv[4]) * a->width - 0.5f;
        float v = (w[0] * uv[1] + w[1] * uv[3] + w[2] * uv[5]) * a->height - 0.5f, sum = 0;
        int x0 = (int)floorf(u), y0 = (int)floorf(v);

        tp->n = 0;
        for (int k = 0; k < 4; k++) {
                int x = x0 + (k & 1), y = y0 + (k >> 1);
                float wk = (k & 1 ? u - x0 : 1 - (u - x0)) * (k >> 1 ? v - y0 : 1 - (v - y0));
                size_t i = (size_t)y * a->width + x;
                if (x < 0 || y < 0 || x >= a->width || y >= a->height || a->tri[i] != t ||
                    m->texels[i].flags & AP_BRDF_MASKED || !(wk > 0))
                        continue;
                tp->i[tp->n] = i, tp->w[tp->n++] = wk, sum += wk;
        }
        for (int k = 0; k < tp->n; k++)
                tp->w[k] /= sum;
        if (!tp->n)
                *tp = (struct taps){{(size_t)(texel_at(m, t, w) - m->texels)}, {1}, 1};
}

/* The texels of tp blended into out: parameters weighted, the normal and the tangent made
 * unit and orthogonal again. */
static void texel_blend(const struct ap_brdf_model *m, const struct taps *tp,
                        struct ap_brdf_texel *out)
{
        float l, tn;

        *out = m->texels[tp->i[0]];
        if (tp->n == 1)
                return;
        memset(out->albedo, 0, sizeof(out->albedo));
        memset(out->normal, 0, sizeof(out->normal));
        memset(out->tangent, 0, sizeof(out->tangent));
        out->ks = out->ax = out->ay = 0;
        for (int k = 0; k < tp->n; k++) {
                const struct ap_brdf_texel *x = &m->texels[tp->i[k]];
                float wk = tp->w[k];
                out->ks += wk * x->ks, out->ax += wk * x->ax, out->ay += wk * x->ay;
                for (int q = 0; q < 3; q++) {
                        out->albedo[q] += wk * x->albedo[q];
                        out->normal[q] += wk * x->normal[q];
                        out->tangent[q] += wk * x->tangent[q];
                }
        }
        l = sqrtf(dot3(out->normal, out->normal));
        for (int q = 0; q < 3 && l > 0; q++)
                out->normal[q] /= l;
        tn = dot3(out->tangent, out->normal);
        for (int q = 0; q < 3; q++)
                out->tangent[q] -= tn * out->normal[q];
        l = sqrtf(dot3(out->tangent, out->tangent));
        for (int q = 0; q < 3 && l > 0; q++)
                out->tangent[q] /= l;
}

static void shade_object(const struct ap_env_renderer *r, int32_t t, const float p[3],
                         const float d[3], float out[3])
{
        const struct ap_mesh *m = &r->sc.m->atlas.mesh;
        struct ap_brdf_texel xb, *x = &xb;
        struct taps tps;
        float w[3], v[3], rr[3], s[3], vd, vs, nv, td, e[3] = {0};
        const float *n;

        bary_of(m, t, p, w);
        texel_taps(r->sc.m, t, w, &tps);
        texel_blend(r->sc.m, &tps, x);
        for (int k = 0; k < tps.n; k++)
                for (int q = 0; q < 3; q++)
                        e[q] += tps.w[k] * r->tex_e[3 * tps.i[k] + q];
        n = x->normal;
        for (int q = 0; q < 3; q++)
                v[q] = -d[q];
        nv = dot3(n, v);
        vd = w[0] * r->vvis[m->idx[3 * t]] + w[1] * r->vvis[m->idx[3 * t + 1]] +
             w[2] * r->vvis[m->idx[3 * t + 2]];
        for (int q = 0; q < 3; q++)
                out[q] = (1 - x->ks) * x->albedo[q] * (float)M_1_PI * e[q] * vd;
        if (x->ks <= 0 || nv <= 0)
                return;
        for (int q = 0; q < 3; q++)
                rr[q] = 2 * nv * n[q] - v[q];
        ap_prefilter_specular(r->sc.pf, n, rr, s);
        float eta = 1 / (2 * x->ax * x->ay), tp = asinf(CLAMP(dot3(rr, n), -1.f, 1.f));
        td = fminf(fminf(ap_ssdf(r->sp, p, n, rr), plane_ssdf(r, rr)), tp);
        vs = ap_sg_visible(r->sp, td, eta) / fmaxf(ap_sg_visible(r->sp, tp, eta), 1e-3f);
        for (int q = 0; q < 3; q++)
                out[q] += x->ks * s[q] * vs;
}

/* The ground at ray C + s d, if it is hit within its radius. */
static bool shade_ground(const struct ap_env_renderer *r, const float C[3], const float d[3],
                         float out[3])
{
        const int g = AP_ENV_GROUND_GRID;
        float R = r->sc.ground_radius, s, x, y, fx, fy, v;

        if (R <= 0 || d[2] >= 0 || C[2] <= 0)
                return false;
        s = -C[2] / d[2];
        x = C[0] + s * d[0];
        y = C[1] + s * d[1];
        if (x * x + y * y > R * R)
                return false;
        fx = CLAMP((x + R) / (2 * R) * (g - 1), 0.f, g - 1.001f);
        fy = CLAMP((y + R) / (2 * R) * (g - 1), 0.f, g - 1.001f);
        int i = (int)fx, j = (int)fy;
        const float *q = r->gvis + j * g + i;
        fx -= i;
        fy -= j;
        v = (1 - fy) * ((1 - fx) * q[0] + fx * q[1]) + fy * ((1 - fx) * q[g] + fx * q[g + 1]);
        for (int c = 0; c < 3; c++)
                out[c] = r->sc.ground_albedo[c] * (float)M_1_PI * r->ground_e[c] * v;
        return true;
}

float ap_env_light_at(const struct ap_env_light *L, const float p[3], float l[3])
{
        float r2 = 1, len;

        for (int q = 0; q < 3; q++)
                l[q] = L->point ? L->v[q] - p[q] : L->v[q];
        len = sqrtf(dot3(l, l));
        if (L->point)
                r2 = len * len;
        for (int q = 0; q < 3; q++)
                l[q] /= len > 0 ? len : 1;
        return L->intensity / (r2 > 0 ? r2 : 1);
}

/* The visible fraction of the light along l at p (normal n): the sphere set and, off the
 * ground, the plane, relative to the part above p's tangent plane. */
static float light_vis(const struct ap_env_renderer *r, const float p[3], const float n[3],
                       const float l[3], bool on_ground)
{
        float tp = asinf(CLAMP(dot3(l, n), -1.f, 1.f)), td = fminf(ap_ssdf(r->sp, p, n, l), tp);

        if (!on_ground)
                td = fminf(td, plane_ssdf(r, l));
        return ap_sg_visible(r->sp, td, AP_ENV_LIGHT_ETA) /
               fmaxf(ap_sg_visible(r->sp, tp, AP_ENV_LIGHT_ETA), 1e-3f);
}

static void shade_object_light(const struct ap_env_renderer *r, int32_t t, const float p[3],
                               const float d[3], float out[3])
{
        struct ap_brdf_texel xb, *x = &xb;
        struct taps tps;
        float w[3], v[3] = {-d[0], -d[1], -d[2]}, l[3], e, vis;

        bary_of(&r->sc.m->atlas.mesh, t, p, w);
        texel_taps(r->sc.m, t, w, &tps);
        texel_blend(r->sc.m, &tps, x);
        e = ap_env_light_at(r->sc.light, p, l);
        ap_brdf_eval(x, l, v, out);
        vis = dot3(l, x->normal) > 0 ? light_vis(r, p, x->normal, l, false) : 0;
        for (int q = 0; q < 3; q++)
                out[q] *= e * vis;
}

static bool shade_ground_light(const struct ap_env_renderer *r, const float C[3], const float d[3],
                               float out[3])
{
        const float up[3] = {0, 0, 1};
        float R = r->sc.ground_radius, s, p[3], l[3], e;

        if (R <= 0 || d[2] >= 0 || C[2] <= 0)
                return false;
        s = -C[2] / d[2];
        p[0] = C[0] + s * d[0], p[1] = C[1] + s * d[1], p[2] = 0.01f;
        if (p[0] * p[0] + p[1] * p[1] > R * R)
                return false;
        e = ap_env_light_at(r->sc.light, p, l);
        e *= l[2] > 0 ? l[2] * light_vis(r, p, up, l, true) : 0;
        for (int c = 0; c < 3; c++)
                out[c] = r->sc.ground_albedo[c] * (float)M_1_PI * e;
        return true;
}

/* Pixel out at ray C + s d: the object at p (triangle t >= 0), else the ground, else the
 * background; its mask class. */
static uint8_t shade(const struct ap_env_renderer *r, int32_t t, const float p[3], const float C[3],
                     const float d[3], float out[3])
{
        bool light = r->sc.light != NULL;

        if (t >= 0) {
                (light ? shade_object_light : shade_object)(r, t, p, d, out);
                return 1;
        }
        if ((light ? shade_ground_light : shade_ground)(r, C, d, out))
                return 2;
        if (light)
                out[0] = out[1] = out[2] = 0;
        else
                env_lookup(r->sc.env, d, out);
        return 0;
}

static void *render_band(void *arg)
{
        struct band *b = arg;
        const struct ap_env_renderer *r = b->r;
        const struct ap_pinhole *ph = &r->ph;

        b->ret = ap_raster_band(&r->sc.m->atlas.mesh, ph, b->y0, b->y1, r->depth, r->tri);
        for (int y = b->y0; y < b->y1 && b->ret >= 0; y++)
                for (int x = 0; x < ph->width; x++) {
                        size_t i = (size_t)y * ph->width + x;
                        float dc[3] = {(float)((x - ph->cx) / ph->fx),
                                       (float)((y - ph->cy) / ph->fy), 1};
                        float d[3], p[3], *out = b->rgb + 3 * i, l;
                        uint8_t mk;
                        for (int q = 0; q < 3; q++)
                                d[q] = b->Rt[3 * q] * dc[0] + b->Rt[3 * q + 1] * dc[1] +
                                       b->Rt[3 * q + 2];
                        if (r->tri[i] >= 0) {
                                for (int q = 0; q < 3; q++)
                                        p[q] = b->C[q] + d[q] * r->depth[i];
                        }
                        l = sqrtf(dot3(d, d));
                        for (int q = 0; q < 3; q++)
                                d[q] /= l;
                        mk = shade(r, r->tri[i], p, b->C, d, out);
                        for (int q = 0; q < 3; q++)
                                out[q] *= r->sc.scale;
                        if (b->mask)
                                b->mask[i] = mk;
                }
        return NULL;
}

static int prepare(struct ap_env_renderer *r, const struct ap_camera *cam)
{
        size_t n = (size_t)cam->width * cam->height;

        r->ph = (struct ap_pinhole){cam->width, cam->height, cam->fx, cam->fy, cam->cx, cam->cy};
        memcpy(r->ph.R, cam->R, sizeof(cam->R));
        memcpy(r->ph.t, cam->t, sizeof(cam->t));
        if (n <= r->cap)
                return 0;
        free(r->depth);
        free(r->tri);
        r->depth = malloc(n * sizeof(float));
        r->tri = malloc(n * sizeof(int32_t));
        r->cap = r->depth && r->tri ? n : 0;
        return r->cap ? 0 : -ENOMEM;
}

int ap_env_render(struct ap_env_renderer *r, const struct ap_camera *cam, int threads, float *rgb,
                  uint8_t *mask)
{
        struct band b[MAX_THREADS];
        pthread_t th[MAX_THREADS];
        int nt, e, started = 0;

        if (!r || !cam || cam->width < 1 || cam->height < 1 || !(cam->fx > 0) || !(cam->fy > 0) ||
            !rgb)
                return -EINVAL;
        if ((e = prepare(r, cam)) < 0)
                return e;
        nt = CLAMP(threads, 1, MIN(MAX_THREADS, cam->height));
        for (int i = 0; i < nt; i++) {
                b[i] = (struct band){.r = r,
                                     .y0 = cam->height * i / nt,
                                     .y1 = cam->height * (i + 1) / nt,
                                     .rgb = rgb,
                                     .mask = mask};
                for (int q = 0; q < 3; q++) {
                        for (int k = 0; k < 3; k++)
                                b[i].Rt[3 * q + k] = (float)cam->R[3 * k + q];
                        b[i].C[q] = (float)-(cam->R[q] * cam->t[0] + cam->R[3 + q] * cam->t[1] +
                                             cam->R[6 + q] * cam->t[2]);
                }
                if (i == nt - 1 || pthread_create(&th[i], NULL, render_band, &b[i]))
                        render_band(&b[i]);
                else
                        started |= 1 << i;
        }
        for (int i = 0; i < nt; i++)
                if (started & (1 << i))
                        pthread_join(th[i], NULL);
        for (int i = 0; i < nt; i++)
                if (b[i].ret < 0)
                        return b[i].ret;
        return 0;
}

/* The principal eigenvector of the symmetric 3x3 matrix S (power iteration from the
 * largest diagonal axis) into v. */
static void principal_axis(const double S[9], float v[3])
{
        int k = S[0] >= S[4] && S[0] >= S[8] ? 0 : S[4] >= S[8] ? 1 : 2;
        double x[3] = {k == 0, k == 1, k == 2};

        for (int it = 0; it < 64; it++) {
                double y[3], l;
                for (int i = 0; i < 3; i++)
                        y[i] = S[3 * i] * x[0] + S[3 * i + 1] * x[1] + S[3 * i + 2] * x[2];
                l = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
                if (!(l > 0))
                        break;
                for (int i = 0; i < 3; i++)
                        x[i] = y[i] / l;
        }
        for (int i = 0; i < 3; i++)
                v[i] = (float)x[i];
}

float ap_env_default_ground(const struct ap_mesh *m)
{
        double lo[3], hi[3];

        ap_mesh_bounds(m, lo, hi);
        if (!(fabs(lo[2]) <= AP_ENV_GROUND_TOUCH))
                return 0;
        return (float)(AP_ENV_GROUND_RADII * 0.5 *
                       sqrt(pow(hi[0] - lo[0], 2) + pow(hi[1] - lo[1], 2) + pow(hi[2] - lo[2], 2)));
}

void ap_brdf_prefilter_params(const struct ap_brdf_model *m, struct ap_prefilter_params *p)
{
        size_t n = (size_t)m->atlas.width * m->atlas.height, k = 0;
        _cleanup_free_ double *v = malloc(3 * (n + 1) * sizeof(double));
        double S[9] = {0};

        p->ax = p->ay = 0.3f, p->f0 = 0.04f;
        p->axis[0] = p->axis[1] = 0, p->axis[2] = 1;
        for (size_t i = 0; v && i < n; i++) {
                const struct ap_brdf_texel *x = &m->texels[i];
                if (!(x->flags & AP_BRDF_FITTED))
                        continue;
                v[k] = x->ax, v[n + k] = x->ay, v[2 * n + k] = x->f0, k++;
                for (int a = 0; a < 9; a++)
                        S[a] += x->ks * x->tangent[a / 3] * x->tangent[a % 3];
        }
        if (!k)
                return;
        if (S[0] + S[4] + S[8] > 0)
                principal_axis(S, p->axis);
        p->ax = (float)gn_median(v, k);
        p->ay = (float)gn_median(v + n, k);
        p->f0 = (float)gn_median(v + 2 * n, k);
}

const float *ap_env_renderer_vertex_vis(const struct ap_env_renderer *r)
{
        return r->vvis;
}

const float *ap_env_renderer_ground_vis(const struct ap_env_renderer *r)
{
        return r->gvis;
}
