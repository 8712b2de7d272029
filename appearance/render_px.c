/* render_px.c - a frame of the renderer (render.h): the mesh rasterised from the output
 * camera (for a distorted camera, in a pinhole image grown to hold its undistorted rays, the
 * surface point being where the pixel's ray meets the plane of the triangle seen), then per
 * pixel the views' weights sampled and blended (Step 4.1) and the light term (Step 4.2).
 * Threads take bands of rows from a shared counter. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/cube.h"
#include "appearance/render_internal.h"
#include "appearance/views.h"

#define BAND_ROWS 8

static bool cam_distorted(const struct ap_camera *c)
{
        for (int i = 0; i < 5; i++)
                if (c->dist[i] != 0)
                        return true;
        return false;
}

/* OpenCV's distortion of normalised (x, y): k1 k2 p1 p2 k3. */
static inline void distortf(const float k[5], float x, float y, float *xd, float *yd)
{
        float r2 = x * x + y * y, rad = 1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));

        *xd = x * rad + 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x);
        *yd = y * rad + k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y;
}

/* The inverse by OpenCV's fixed-point iteration (undistortPoints). */
static void undistort(const struct ap_camera *c, double xd, double yd, float *out)
{
        const double *k = c->dist;
        double x = xd, y = yd;

        for (int it = 0; it < 20; it++) {
                double r2 = x * x + y * y, rad = 1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
                double dx = 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x);
                double dy = k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y;
                x = (xd - dx) / rad;
                y = (yd - dy) / rad;
        }
        out[0] = (float)x;
        out[1] = (float)y;
}

static bool same_intrinsics(const struct ap_camera *a, const struct ap_camera *b)
{
        return a->width == b->width && a->height == b->height && a->fx == b->fx && a->fy == b->fy &&
               a->cx == b->cx && a->cy == b->cy && !memcmp(a->dist, b->dist, sizeof(a->dist));
}

/* The undistorted rays of a distorted camera, kept while its intrinsics stay. */
static int make_rays(struct ap_renderer *r, const struct ap_camera *c)
{
        size_t n = (size_t)c->width * c->height;

        if (r->rays && same_intrinsics(&r->rays_cam, c))
                return 0;
        if (n > r->rays_cap) {
                float *p = realloc(r->rays, 2 * n * sizeof(float));
                if (!p)
                        return -ENOMEM;
                r->rays = p;
                r->rays_cap = n;
        }
        for (int y = 0; y < c->height; y++)
                for (int x = 0; x < c->width; x++)
                        undistort(c, (x - c->cx) / c->fx, (y - c->cy) / c->fy,
                                  &r->rays[2 * ((size_t)y * c->width + x)]);
        r->rays_cam = *c;
        return 0;
}

/* The pinhole raster holding every ray of c: c itself, or grown to the rays' extent. */
static void raster_extent(const struct ap_renderer *r, const struct ap_camera *c,
                          struct ap_pinhole *ph)
{
        double lo[2] = {0, 0}, hi[2] = {c->width - 1, c->height - 1};

        *ph = (struct ap_pinhole){c->width, c->height, c->fx, c->fy, c->cx, c->cy};
        if (!r->rays)
                return;
        for (size_t i = 0; i < (size_t)c->width * c->height; i++)
                for (int j = 0; j < 2; j++) {
                        double u = j ? c->fy * r->rays[2 * i + 1] + c->cy
                                     : c->fx * r->rays[2 * i] + c->cx;
                        lo[j] = fmin(lo[j], u);
                        hi[j] = fmax(hi[j], u);
                }
        lo[0] = fmax(lo[0], -AP_RENDER_MAX_SIDE), lo[1] = fmax(lo[1], -AP_RENDER_MAX_SIDE);
        hi[0] = fmin(hi[0], 2 * AP_RENDER_MAX_SIDE), hi[1] = fmin(hi[1], 2 * AP_RENDER_MAX_SIDE);
        ph->cx = c->cx - floor(lo[0]) + 1;
        ph->cy = c->cy - floor(lo[1]) + 1;
        ph->width = (int)(ceil(hi[0]) - floor(lo[0])) + 3;
        ph->height = (int)(ceil(hi[1]) - floor(lo[1])) + 3;
}

int render_prepare_raster(struct ap_renderer *r, const struct ap_camera *cam)
{
        size_t n;
        int e;

        if (!cam_distorted(cam)) {
                free(r->rays);
                r->rays = NULL;
                r->rays_cap = 0;
        } else if ((e = make_rays(r, cam)) < 0) {
                return e;
        }
        raster_extent(r, cam, &r->ras);
        memcpy(r->ras.R, cam->R, sizeof(cam->R));
        memcpy(r->ras.t, cam->t, sizeof(cam->t));
        n = (size_t)r->ras.width * r->ras.height;
        if (n > r->ras_cap) {
                float *d = realloc(r->ras_depth, n * sizeof(float));
                int32_t *t = d ? realloc(r->ras_tri, n * sizeof(int32_t)) : NULL;
                if (d)
                        r->ras_depth = d;
                if (!t)
                        return -ENOMEM;
                r->ras_tri = t;
                r->ras_cap = n;
        }
        return 0;
}

/* The normal n at point p of triangle tri: the vertex normals interpolated (barycentric),
 * or the face's (its plane pl) where the mesh has none. */
static void surface_normal(const struct ap_renderer *r, int32_t tri, const float *pl,
                           const float p[3], float n[3])
{
        const uint32_t *ix = &r->mesh->idx[3 * (size_t)tri];
        float lam[3], len;

        if (!r->vnormals) {
                memcpy(n, pl, 3 * sizeof(float));
                return;
        }
        for (int k = 0; k < 3; k++) { /* the area of p and the edge opposite vertex k */
                const float *a = &r->mesh->pos[3 * ix[(k + 1) % 3]],
                            *b = &r->mesh->pos[3 * ix[(k + 2) % 3]];
                float u[3] = {a[0] - p[0], a[1] - p[1], a[2] - p[2]},
                      v[3] = {b[0] - p[0], b[1] - p[1], b[2] - p[2]};
                lam[k] = pl[0] * (u[1] * v[2] - u[2] * v[1]) + pl[1] * (u[2] * v[0] - u[0] * v[2]) +
                         pl[2] * (u[0] * v[1] - u[1] * v[0]);
                lam[k] = lam[k] > 0 ? lam[k] : 0; /* p rounded onto the triangle */
        }
        for (int j = 0; j < 3; j++)
                n[j] = 0;
        for (int k = 0; k < 3; k++)
                for (int j = 0; j < 3; j++)
                        n[j] += lam[k] * r->vnormals[3 * ix[k] + j];
        len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(len > 0)) {
                memcpy(n, pl, 3 * sizeof(float));
                return;
        }
        for (int j = 0; j < 3; j++)
                n[j] /= len;
}

/* The surface point p (object frame) seen at output pixel (x, y) and the unit normal n there
 * (surface_normal), turned towards the output camera; false where none. */
static bool surface_point(const struct frame *f, int x, int y, float p[3], float n[3])
{
        const struct ap_renderer *r = f->r;
        const struct ap_camera *c = f->cam;
        float xn, yn, d[3], den, s;
        const float *pl;
        int32_t tri;

        if (r->rays) {
                const float *ray = &r->rays[2 * ((size_t)y * c->width + x)];
                int iu = (int)lrint(c->fx * ray[0] + r->ras.cx);
                int iv = (int)lrint(c->fy * ray[1] + r->ras.cy);
                if (iu < 0 || iv < 0 || iu >= r->ras.width || iv >= r->ras.height)
                        return false;
                xn = ray[0], yn = ray[1];
                tri = r->ras_tri[(size_t)iv * r->ras.width + iu];
        } else {
                xn = ((float)x - f->cxy[0]) * f->ifxy[0], yn = ((float)y - f->cxy[1]) * f->ifxy[1];
                tri = r->ras_tri[(size_t)y * c->width + x];
        }
        if (tri < 0)
                return false;
        for (int i = 0; i < 3; i++)
                d[i] = f->Rt[3 * i] * xn + f->Rt[3 * i + 1] * yn + f->Rt[3 * i + 2];
        pl = &r->planes[4 * (size_t)tri];
        den = pl[0] * d[0] + pl[1] * d[1] + pl[2] * d[2];
        if (fabsf(den) < 1e-12f)
                return false;
        s = (pl[3] - pl[0] * f->C[0] - pl[1] * f->C[1] - pl[2] * f->C[2]) / den;
        for (int i = 0; i < 3; i++)
                p[i] = f->C[i] + s * d[i];
        surface_normal(r, tri, pl, p, n);
        if (n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0) /* d points away from the camera */
                for (int i = 0; i < 3; i++)
                        n[i] = -n[i];
        return true;
}

/* The weight of a view that sees a surface at cosine c to its line of sight: 0 at grazing
 * rising smoothly to 1, so that a view fades out before its silhouette instead of being cut
 * there (a seam along the edge of what it sees). */
static inline float view_fade(float c)
{
        float t = (c - (float)AP_RENDER_FADE_LO) / (float)(AP_RENDER_FADE_HI - AP_RENDER_FADE_LO);

        t = t < 0 ? 0 : t > 1 ? 1 : t;
        return t * t * (3 - 2 * t);
}

static inline int ifloor(float v)
{
        int i = (int)v;

        return i - (v < (float)i);
}

/* Adds wgt times view v's weights at object point p (normal n) to acc, faded by the view's
 * cosine to the surface (view_fade; not with n NULL); returns the weight added, 0 where p is hidden
 * from v or outside its mask. Each bilinear tap counts only where the view's mask holds and its
 * depth map sees the point's surface there, within v->tol times the depth (no blending
 * across occlusion edges: a tap on an occluder, or on a surface behind, is dropped). The
 * depth map is read at the pinhole position of each tap (its offset from the point's). */
static float sample_view(const struct rview *v, const float p[3], const float *n, int K, float wgt,
                         float *acc)
{
        float x[3], iz, xd, yd, pu, pv, u, w, a, b, tw = 0, bw[4], tol, du, dv, c;
        const float *t0, *dp;
        const uint8_t *mp;
        int x0, y0, W = v->width;

        for (int i = 0; i < 3; i++)
                x[i] = v->R[3 * i] * p[0] + v->R[3 * i + 1] * p[1] + v->R[3 * i + 2] * p[2] +
                       v->t[i];
        if (x[2] <= 0)
                return 0;
        if (n) {
                c = 0; /* the cosine between n and the way from p to the view's camera, -x */
                for (int i = 0; i < 3; i++)
                        c -= (v->R[3 * i] * n[0] + v->R[3 * i + 1] * n[1] +
                              v->R[3 * i + 2] * n[2]) *
                             x[i];
                wgt *= view_fade(c / sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]));
                if (!(wgt > 0))
                        return 0;
        }
        iz = 1 / x[2];
        xd = x[0] * iz, yd = x[1] * iz;
        pu = v->fx * xd + v->cx, pv = v->fy * yd + v->cy;
        if (v->distorted)
                distortf(v->dist, x[0] * iz, x[1] * iz, &xd, &yd);
        u = v->fx * xd + v->cx, w = v->fy * yd + v->cy;
        x0 = ifloor(u), y0 = ifloor(w);
        a = u - (float)x0, b = w - (float)y0;
        du = pu - a + v->mx + 0.5f, dv = pv - b + v->my + 0.5f;
        if (x0 < 0 || y0 < 0 || x0 + 1 >= W || y0 + 1 >= v->height || du < 0 || dv < 0 ||
            (int)du + 1 >= v->dw || (int)dv + 1 >= v->dh)
                return 0;
        dp = v->depth + (size_t)(int)dv * v->dw + (int)du;
        mp = v->mask + (size_t)y0 * W + x0;
        tol = x[2] * v->tol;
        bw[0] = mp[0] && fabsf(dp[0] - x[2]) <= tol ? (1 - a) * (1 - b) : 0;
        bw[1] = mp[1] && fabsf(dp[1] - x[2]) <= tol ? a * (1 - b) : 0;
        bw[2] = mp[W] && fabsf(dp[v->dw] - x[2]) <= tol ? (1 - a) * b : 0;
        bw[3] = mp[W + 1] && fabsf(dp[v->dw + 1] - x[2]) <= tol ? a * b : 0;
        tw = bw[0] + bw[1] + bw[2] + bw[3];
        if (!(tw > 1e-3f))
                return 0;
        tw = wgt / tw;
        for (int j = 0; j < 4; j++)
                bw[j] *= tw;
        t0 = v->weights + ((size_t)y0 * W + x0) * K;
        for (int k = 0; k < K; k++)
                acc[k] += bw[0] * t0[k] + bw[1] * t0[K + k] + bw[2] * t0[W * K + k] +
                          bw[3] * t0[(W + 1) * K + k];
        return wgt;
}

/* L(l, k, c) at unit l from the cube map, bilinear inside a face. */
static void cube_sample(const struct ap_renderer *r, const float l[3], float *out)
{
        const int n = AP_RENDER_CUBE, row = (r->m->k + 1) * 3;
        float s, t, fs, ft, a, b;
        int face = ap_cube_face(l, &s, &t), i0, j0, i1, j1;
        const float *q00, *q01, *q10, *q11;

        fs = (s + 1) * 0.5f * n - 0.5f, ft = (t + 1) * 0.5f * n - 0.5f;
        fs = fs < 0 ? 0 : fs > n - 1 ? n - 1 : fs;
        ft = ft < 0 ? 0 : ft > n - 1 ? n - 1 : ft;
        i0 = (int)fs, j0 = (int)ft;
        i1 = i0 + 1 < n ? i0 + 1 : i0, j1 = j0 + 1 < n ? j0 + 1 : j0;
        a = fs - (float)i0, b = ft - (float)j0;
        q00 = &r->cube[(((size_t)face * n + j0) * n + i0) * row];
        q01 = &r->cube[(((size_t)face * n + j0) * n + i1) * row];
        q10 = &r->cube[(((size_t)face * n + j1) * n + i0) * row];
        q11 = &r->cube[(((size_t)face * n + j1) * n + i1) * row];
        for (int i = 0; i < row; i++)
                out[i] = (1 - b) * ((1 - a) * q00[i] + a * q01[i]) +
                         b * ((1 - a) * q10[i] + a * q11[i]);
}

/* Step 4.1 at surface point p (normal n): the weights of the views around its view direction
 * blended into acc (K values, normalised by the views that see p; faded near their grazing
 * unless all are there). False where no view sees p. */
static inline __attribute__((always_inline)) bool
blend_views(const struct frame *f, const float p[3], const float n[3], float *acc)
{
        const struct ap_renderer *r = f->r;
        int idx[3], nv = f->on, K = r->m->k;
        float w[3], ws = 0;

        memcpy(idx, f->oidx, sizeof(idx));
        memcpy(w, f->ow, sizeof(w));
        if (f->mode == AP_VIEW_PIXEL) {
                float v[3] = {f->C[0] - p[0], f->C[1] - p[1], f->C[2] - p[2]};
                float len = 1 / sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                for (int j = 0; j < 3; j++)
                        v[j] *= len;
                nv = ap_views_weights(r->views, v, idx, w);
        }
        for (int j = 0; j < nv; j++)
                if (w[j] > 0)
                        ws += sample_view(&r->rv[idx[j]], p, n, K, w[j], acc);
        for (int j = 0; j < nv && !(ws > 0); j++) /* every view at grazing: unfaded */
                if (w[j] > 0)
                        ws += sample_view(&r->rv[idx[j]], p, NULL, K, w[j], acc);
        if (!(ws > 0))
                return false;
        ws = 1 / ws;
        for (int k = 0; k < K; k++)
                acc[k] *= ws;
        return true;
}

/* Pixel i: s (L row 0 + sum_k acc_k L row k + 1). */
static inline __attribute__((always_inline)) void light_sum(const struct frame *f, const float *L,
                                                            const float *acc, float s, size_t i)
{
        float q[3] = {L[0], L[1], L[2]};

        for (int k = 0; k < f->r->m->k; k++) {
                q[0] += acc[k] * L[(k + 1) * 3];
                q[1] += acc[k] * L[(k + 1) * 3 + 1];
                q[2] += acc[k] * L[(k + 1) * 3 + 2];
        }
        for (int c = 0; c < 3; c++)
                f->rgb[3 * i + c] = s * q[c];
}

/* Step 4.2: pixel i from the blended weights acc at surface point p. */
static inline __attribute__((always_inline)) void
apply_light(const struct frame *f, const float p[3], const float *acc, size_t i)
{
        float lt[(AP_K_MAX + 1) * 3], l[3], r2, rl;

        if (f->kind != AP_LIGHT_POINT) {
                light_sum(f, f->lconst, acc, f->scale, i);
                return;
        }
        for (int j = 0; j < 3; j++)
                l[j] = f->lpos[j] - p[j];
        r2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2], rl = 1 / sqrtf(r2);
        for (int j = 0; j < 3; j++)
                l[j] *= rl, lt[j] = 0; /* (lt: gcc cannot see that K >= 0 fills it) */
        cube_sample(f->r, l, lt);
        light_sum(f, lt, acc, f->scale / r2, i);
}

static inline __attribute__((always_inline)) void shade(const struct frame *f, int x, int y)
{
        size_t i = (size_t)y * f->cam->width + x;
        float p[3], n[3], acc[AP_K_MAX] = {0};

        f->mask[i] = 0;
        f->rgb[3 * i] = f->rgb[3 * i + 1] = f->rgb[3 * i + 2] = 0;
        if (!surface_point(f, x, y, p, n) || !blend_views(f, p, n, acc))
                return;
        apply_light(f, p, acc, i);
        f->mask[i] = 1;
}

struct band_ctx {
        const struct frame *f;
        int bands;
        atomic_int next_band, next_row, error;
};

/* Rasterises bands of the frame's raster until none is left. */
static void *raster_worker(void *arg)
{
        struct band_ctx *b = arg;
        const struct ap_renderer *r = b->f->r;
        int i, h = r->ras.height, e;

        while ((i = atomic_fetch_add(&b->next_band, 1)) < b->bands)
                if ((e = ap_raster_band(r->mesh, &r->ras, h * i / b->bands, h * (i + 1) / b->bands,
                                        r->ras_depth, r->ras_tri)) < 0)
                        atomic_store(&b->error, e);
        return NULL;
}

static void shade_row(const struct frame *f, int y)
{
        for (int x = 0; x < f->cam->width; x++)
                shade(f, x, y);
}

/* Shades bands of BAND_ROWS rows until none is left. */
static void *shade_worker(void *arg)
{
        struct band_ctx *b = arg;
        const struct frame *f = b->f;
        int y0;

        while ((y0 = atomic_fetch_add(&b->next_row, BAND_ROWS)) < f->cam->height)
                for (int y = y0; y < y0 + BAND_ROWS && y < f->cam->height; y++)
                        shade_row(f, y);
        return NULL;
}

/* Runs fn on up to threads threads, this one included (fewer when a thread cannot be
 * created: fn takes work from a shared counter, so what is left is done here). */
static void parallel(void *(*fn)(void *), void *arg, int threads)
{
        pthread_t th[threads > 1 ? threads - 1 : 1];
        int started = 0;

        while (started < threads - 1 && pthread_create(&th[started], NULL, fn, arg) == 0)
                started++;
        fn(arg);
        for (int i = 0; i < started; i++)
                pthread_join(th[i], NULL);
}

int render_run(const struct frame *f, int threads)
{
        struct band_ctx b = {.f = f, .bands = threads};

        atomic_init(&b.next_band, 0);
        atomic_init(&b.next_row, 0);
        atomic_init(&b.error, 0);
        parallel(raster_worker, &b, threads);
        if (atomic_load(&b.error) < 0)
                return atomic_load(&b.error);
        parallel(shade_worker, &b, threads);
        return 0;
}
