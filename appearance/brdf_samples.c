/* brdf_samples.c - the samples of the BRDF fit (brdf_internal.h): per view, the texels it
 * sees (the mesh's depth map in the view's pinhole space, as render.c's views) and where they
 * project (with distortion); per lamp-lit image of the view, its image read (dark frame
 * subtracted, normalised to the base exposure and gain, as fit_view.c), the lamp's shadow map
 * of the mesh, and for each seen texel that the lamp lights the value of the pixel nearest its
 * projection (its directions moved from that pixel's surface point to the texel: struct
 * seen), left out when saturated. Brackets are separate samples: the saturated
 * ones drop out. Images are read once, in order. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "appearance/brdf_internal.h"
#include "appearance/fit_internal.h"
#include "common/cleanup.h"
#include "dataset/ds_png.h"

#define SHADOW_SIDE  256   /* shadow map pixels a side */
#define SHADOW_BIAS  0.002 /* relative depth tolerance of the shadow test... */
#define SHADOW_SLOPE 2.0   /* ...plus this many of the map's pixel footprints */
#define VIEW_BIAS    0.005 /* as AP_RENDER_BIAS and AP_RENDER_SLOPE */
#define VIEW_SLOPE   2.5
#define VIEW_MARGIN  8 /* the depth map grown by 1/8 of the image a side */

/* A texel seen by the view being read, through the pixel its point projects nearest to: the
 * surface point on that pixel's ray (the texel's triangle, extended), and the rotation taking
 * that point's normal to the texel's, applied to the sample's directions so that each sample
 * is exact at the pixel's centre (no interpolation across a sharp highlight). */
struct seen {
        uint32_t texel;
        uint32_t pixel;
        float p[3];   /* the pixel's surface point */
        float n[3];   /* its normal */
        float rot[9]; /* its normal to the texel's */
        float v[3];   /* unit, towards the camera, rotated */
};

/* The samples gathered so far, unsorted (texel of each in tex). */
struct acc {
        struct brdf_sample *s;
        uint32_t *tex;
        size_t n, cap;
};

static int acc_push(struct acc *a, uint32_t texel, const struct brdf_sample *s)
{
        if (a->n == a->cap) {
                size_t cap = a->cap ? 2 * a->cap : 4096;
                struct brdf_sample *ns = realloc(a->s, cap * sizeof(*ns));
                uint32_t *nt = ns ? realloc(a->tex, cap * sizeof(*nt)) : NULL;
                if (ns)
                        a->s = ns;
                if (!nt)
                        return -ENOMEM;
                a->tex = nt, a->cap = cap;
        }
        a->s[a->n] = *s;
        a->tex[a->n++] = texel;
        return 0;
}

static void mat_vec(const double R[9], const double t[3], const float p[3], double x[3])
{
        for (int i = 0; i < 3; i++)
                x[i] = R[3 * i] * p[0] + R[3 * i + 1] * p[1] + R[3 * i + 2] * p[2] + t[i];
}

/* The point of texel i's triangle (barycentrics b, extended beyond its edges) at b. */
static void tri_point(const struct ap_atlas *a, int32_t t, const double b[3], double p[3],
                      float n[3])
{
        float l = 0;

        for (int j = 0; j < 3; j++) {
                p[j] = n[j] = 0;
                for (int c = 0; c < 3; c++) {
                        uint32_t v = a->mesh.idx[3 * (size_t)t + c];
                        p[j] += b[c] * a->mesh.pos[3 * v + j];
                        n[j] += (float)b[c] * a->vnormal[3 * v + j];
                }
                l += n[j] * n[j];
        }
        for (int j = 0; j < 3; j++)
                n[j] /= sqrtf(l);
}

/* The surface point p and normal n of texel i's triangle that camera g sees at pixel centre
 * px: Newton's method on the barycentrics from the texel's. False when it does not settle. */
static bool pixel_point(const struct ap_atlas *a, size_t i, const struct ap_camera *g,
                        const double px[2], double p[3], float n[3])
{
        const float *b0 = &a->bary[3 * i];
        double b[3] = {b0[0], b0[1], b0[2]}, uv[2], e[2];
        int32_t t = a->tri[i];

        for (int it = 0; it < 6; it++) {
                double J[2][2], q[3], quv[2], det, d1, d2;
                tri_point(a, t, b, p, n);
                if (!ap_camera_project(g, p, uv, NULL))
                        return false;
                e[0] = px[0] - uv[0], e[1] = px[1] - uv[1];
                if (fabs(e[0]) + fabs(e[1]) < 1e-3)
                        return true;
                for (int k = 0; k < 2; k++) { /* d uv / d b_{k+1}, b_0 taking up the rest */
                        double bb[3] = {b[0] - 1e-3, b[1] + (k == 0) * 1e-3,
                                        b[2] + (k == 1) * 1e-3};
                        float nn[3];
                        tri_point(a, t, bb, q, nn);
                        if (!ap_camera_project(g, q, quv, NULL))
                                return false;
                        J[0][k] = (quv[0] - uv[0]) / 1e-3, J[1][k] = (quv[1] - uv[1]) / 1e-3;
                }
                det = J[0][0] * J[1][1] - J[0][1] * J[1][0];
                if (fabs(det) < 1e-9)
                        return false;
                d1 = (J[1][1] * e[0] - J[0][1] * e[1]) / det;
                d2 = (J[0][0] * e[1] - J[1][0] * e[0]) / det;
                b[1] += d1, b[2] += d2, b[0] = 1 - b[1] - b[2];
        }
        return fabs(e[0]) + fabs(e[1]) < 0.05;
}

/* The rotation taking unit a to unit b (Rodrigues), row-major. */
static void rotation(const float a[3], const float b[3], float R[9])
{
        float v[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                      a[0] * b[1] - a[1] * b[0]};
        float c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], k = c > -0.999f ? 1 / (1 + c) : 0;
        float V[9] = {0, -v[2], v[1], v[2], 0, -v[0], -v[1], v[0], 0};

        for (int r = 0; r < 3; r++)
                for (int s = 0; s < 3; s++) {
                        float vv = 0;
                        for (int j = 0; j < 3; j++)
                                vv += V[3 * r + j] * V[3 * j + s];
                        R[3 * r + s] = (r == s) + V[3 * r + s] + k * vv;
                }
}

static void rotate(const float R[9], const float x[3], float y[3])
{
        for (int i = 0; i < 3; i++)
                y[i] = R[3 * i] * x[0] + R[3 * i + 1] * x[1] + R[3 * i + 2] * x[2];
}

/* Texel i as view g sees it (o its centre; depth its depth map in ph, tolerance tol) into s:
 * false when it faces away, is hidden or projects outside. */
static bool see(const struct brdf_ctx *c, const struct ap_camera *g, const struct ap_pinhole *ph,
                const float *depth, double tol, const double o[3], size_t i, struct seen *s)
{
        const float *nn = &c->normals[3 * i];
        double x[3], uv[2], px[2], p[3], d[3], len;
        int u, v;

        if (isnan(c->points[3 * i]))
                return false;
        for (int k = 0; k < 3; k++)
                p[k] = c->points[3 * i + k];
        if (!ap_camera_project(g, p, uv, NULL))
                return false;
        px[0] = round(uv[0]), px[1] = round(uv[1]);
        if (px[0] < 0 || px[1] < 0 || px[0] >= g->width || px[1] >= g->height ||
            !pixel_point(&c->atlas, i, g, px, p, s->n))
                return false;
        for (int k = 0; k < 3; k++) {
                s->p[k] = (float)p[k];
                d[k] = o[k] - p[k];
        }
        mat_vec(g->R, g->t, s->p, x);
        u = (int)lrint(ph->fx * x[0] / x[2] + ph->cx),
        v = (int)lrint(ph->fy * x[1] / x[2] + ph->cy);
        len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (x[2] <= 0 || d[0] * nn[0] + d[1] * nn[1] + d[2] * nn[2] <= 0 ||
            d[0] * s->n[0] + d[1] * s->n[1] + d[2] * s->n[2] <= 0 || u < 1 || v < 1 ||
            u >= ph->width - 1 || v >= ph->height - 1 ||
            x[2] > depth[(size_t)v * ph->width + u] * (1 + tol))
                return false;
        for (int dv = -1; dv <= 1; dv++) /* not at the silhouette: its pixels mix background */
                for (int du = -1; du <= 1; du++)
                        if (isinf(depth[(size_t)(v + dv) * ph->width + u + du]))
                                return false;
        s->texel = (uint32_t)i;
        s->pixel = (uint32_t)(px[1] * g->width + px[0]);
        rotation(s->n, nn, s->rot);
        float vd[3] = {(float)(d[0] / len), (float)(d[1] / len), (float)(d[2] / len)};
        rotate(s->rot, vd, s->v);
        return true;
}

/* The texels view g sees. */
static int view_texels(const struct brdf_ctx *c, const struct ap_camera *g, struct seen **ret,
                       size_t *n_ret)
{
        int mx = g->width / VIEW_MARGIN, my = g->height / VIEW_MARGIN;
        struct ap_pinhole ph = {g->width + 2 * mx, g->height + 2 * my, g->fx, g->fy,
                                g->cx + mx,        g->cy + my};
        size_t n = (size_t)c->atlas.width * c->atlas.height, k = 0;
        _cleanup_free_ float *depth = malloc((size_t)ph.width * ph.height * sizeof(float));
        struct seen *s = malloc(n * sizeof(*s));
        double o[3], tol = fmax(VIEW_BIAS, VIEW_SLOPE / g->fx);

        memcpy(ph.R, g->R, sizeof(ph.R));
        memcpy(ph.t, g->t, sizeof(ph.t));
        for (int i = 0; i < 3; i++) /* the camera's centre: -R^T t */
                o[i] = -(g->R[i] * g->t[0] + g->R[3 + i] * g->t[1] + g->R[6 + i] * g->t[2]);
        if (!depth || !s || ap_raster(&c->atlas.mesh, &ph, depth, NULL) < 0) {
                free(s);
                return -ENOMEM;
        }
        for (size_t i = 0; i < n; i++)
                k += see(c, g, &ph, depth, tol, o, i, &s[k]);
        *ret = s;
        *n_ret = k;
        return 0;
}

/* A shadow map: the mesh's depth seen from a lamp, looking at the mesh's bounding sphere. */
struct shadow {
        struct ap_pinhole ph;
        float *depth; /* NULL: the lamp is inside the sphere, nothing is shadowed */
};

static void look_at(const double from[3], const double to[3], double R[9], double t[3])
{
        double z[3] = {to[0] - from[0], to[1] - from[1], to[2] - from[2]}, a[3] = {1, 0, 0};
        double zl = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]), x[3], y[3], xl;

        for (int i = 0; i < 3; i++)
                z[i] /= zl;
        if (fabs(z[0]) > 0.9)
                a[0] = 0, a[1] = 1;
        x[0] = a[1] * z[2] - a[2] * z[1], x[1] = a[2] * z[0] - a[0] * z[2];
        x[2] = a[0] * z[1] - a[1] * z[0];
        xl = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        for (int i = 0; i < 3; i++)
                x[i] /= xl;
        y[0] = z[1] * x[2] - z[2] * x[1], y[1] = z[2] * x[0] - z[0] * x[2];
        y[2] = z[0] * x[1] - z[1] * x[0];
        for (int i = 0; i < 3; i++) {
                R[i] = x[i], R[3 + i] = y[i], R[6 + i] = z[i];
        }
        for (int i = 0; i < 3; i++)
                t[i] = -(R[3 * i] * from[0] + R[3 * i + 1] * from[1] + R[3 * i + 2] * from[2]);
}

static int shadow_map(const struct brdf_ctx *c, const double lamp[3], const double centre[3],
                      double radius, struct shadow *sh)
{
        double d = sqrt(pow(lamp[0] - centre[0], 2) + pow(lamp[1] - centre[1], 2) +
                        pow(lamp[2] - centre[2], 2)),
               f;

        if (d <= radius * 1.01) {
                sh->depth = NULL;
                return 0;
        }
        f = SHADOW_SIDE / 2.0 / tan(asin(radius / d)) * 0.98;
        sh->ph = (struct ap_pinhole){
                SHADOW_SIDE, SHADOW_SIDE, f, f, SHADOW_SIDE / 2.0 - 0.5, SHADOW_SIDE / 2.0 - 0.5};
        look_at(lamp, centre, sh->ph.R, sh->ph.t);
        if (!sh->depth)
                sh->depth = malloc(SHADOW_SIDE * SHADOW_SIDE * sizeof(float));
        return sh->depth ? ap_raster(&c->atlas.mesh, &sh->ph, sh->depth, NULL) : -ENOMEM;
}

/* The lamp of sh sees point p: no nearer surface in the 3 x 3 pixels around it. */
static bool lit(const struct shadow *sh, const float p[3])
{
        double x[3], u, v, dmax = 0;

        if (!sh->depth)
                return true;
        mat_vec(sh->ph.R, sh->ph.t, p, x);
        u = sh->ph.fx * x[0] / x[2] + sh->ph.cx, v = sh->ph.fy * x[1] / x[2] + sh->ph.cy;
        for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                        int iu = (int)lrint(u) + dx, iv = (int)lrint(v) + dy;
                        if (iu < 0 || iv < 0 || iu >= SHADOW_SIDE || iv >= SHADOW_SIDE)
                                return true;
                        dmax = fmax(dmax, sh->depth[iv * SHADOW_SIDE + iu]);
                }
        return x[2] <= dmax * (1 + SHADOW_BIAS) + SHADOW_SLOPE * x[2] / sh->ph.fx;
}

static void image_free(struct brdf_image *im)
{
        free(im->px);
        free(im->sat);
}

static int decode(const struct brdf_ctx *c, const struct ds_capture *r, struct gn_frame *f)
{
        return fit_read_image(c->dir, r, f, (char *)c->err, sizeof(c->err));
}

static float raw(const struct gn_frame *f, int x, int y, int ch)
{
        const uint8_t *row = f->data + (size_t)y * f->stride;
        size_t i = (size_t)x * f->channels + (f->channels == 3 ? ch : 0);

        return f->bits == 8 ? row[i] * (1 / 255.0f) : ((const uint16_t *)row)[i] * (1 / 65535.0f);
}

/* The dark frame of row r (in c->g's rows, id order), or NULL. */
static const struct ds_capture *dark_of(const struct brdf_ctx *c, const struct ds_capture *r)
{
        size_t lo = 0, hi = c->g->n_rows;

        while (r->dark_id > 0 && lo < hi) {
                size_t mid = (lo + hi) / 2;
                if (c->g->rows[mid].id == r->dark_id)
                        return &c->g->rows[mid];
                if (c->g->rows[mid].id < r->dark_id)
                        lo = mid + 1;
                else
                        hi = mid;
        }
        return NULL;
}

int brdf_image_read(const struct brdf_ctx *c, const struct ds_capture *r, struct brdf_image *im)
{
        const struct ds_capture *dr = dark_of(c, r);
        struct gn_frame f = {0}, dk = {0};
        double gain = r->gain > 0 ? r->gain : 1, e = r->exposure_us > 0 ? r->exposure_us : 0;
        float k = (float)((e > 0 ? c->exposure_ref / e : 1) * c->gain_ref / gain);
        float sat = (float)c->o->saturation;
        int ret = decode(c, r, &f);

        if (ret == 0 && dr)
                ret = decode(c, dr, &dk);
        if (ret == 0 && dr && (dk.width != f.width || dk.height != f.height))
                ret = -EBADMSG;
        if (ret == 0 && (f.width != im->w || f.height != im->h)) {
                snprintf((char *)c->err, sizeof(c->err), "%s: %dx%d, the camera's images are %dx%d",
                         r->file, f.width, f.height, im->w, im->h);
                ret = -EBADMSG;
        }
        for (int y = 0; ret == 0 && y < f.height; y++)
                for (int x = 0; x < f.width; x++) {
                        size_t p = (size_t)y * f.width + x;
                        im->sat[p] = 0;
                        for (int ch = 0; ch < 3; ch++) {
                                float v = raw(&f, x, y, ch);
                                im->sat[p] |= v >= sat;
                                im->px[3 * p + ch] = (v - (dr ? raw(&dk, x, y, ch) : 0)) * k;
                        }
                }
        gn_frame_free_data(&f);
        gn_frame_free_data(&dk);
        return ret;
}

/* tan of the angle between the half vector of l, v and n (large when below). */
static double tan_half(const float l[3], const float v[3], const float n[3])
{
        float h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
        double hl = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        double c = hl > 0 ? (h[0] * n[0] + h[1] * n[1] + h[2] * n[2]) / hl : 0;

        return c > 1e-6 ? sqrt(fmax(1 - c * c, 0)) / c : 1e6;
}

/* The samples of shot sh (its image im) at the texels seen s[0..n) into a. */
static int shot_samples(const struct brdf_ctx *c, const struct ap_shot *sh,
                        const struct brdf_image *im, const struct shadow *smap,
                        const struct seen *s, size_t n, struct acc *a, struct brdf_samples *out)
{
        int r = 0;

        for (size_t i = 0; r == 0 && i < n; i++) {
                const float *nn = &c->normals[3 * s[i].texel];
                struct brdf_sample x;
                float l[3];
                double d[3], r2 = 0;
                for (int k = 0; k < 3; k++) {
                        d[k] = sh->lamp[k] - s[i].p[k];
                        r2 += d[k] * d[k];
                }
                for (int k = 0; k < 3; k++)
                        l[k] = (float)(d[k] / sqrt(r2));
                rotate(s[i].rot, l, x.l);
                memcpy(x.v, s[i].v, sizeof(x.v));
                if (l[0] * s[i].n[0] + l[1] * s[i].n[1] + l[2] * s[i].n[2] <= 0 ||
                    !lit(smap, s[i].p)) {
                        out->n_shadowed++;
                        continue;
                }
                if (im->sat[s[i].pixel]) {
                        out->n_sat++;
                        out->n_sat_near[s[i].texel] += tan_half(x.l, x.v, nn) < AP_BRDF_NEAR_TAN;
                        continue;
                }
                memcpy(x.y, &im->px[3 * (size_t)s[i].pixel], sizeof(x.y));
                x.e = (float)(c->response * sh->intensity / r2);
                r = acc_push(a, s[i].texel, &x);
        }
        return r;
}

/* The centre and radius of a sphere holding the mesh (its bounding box's). */
static void bounds(const struct ap_mesh *m, double centre[3], double *radius)
{
        double lo[3], hi[3];

        ap_mesh_bounds(m, lo, hi);
        for (int k = 0; k < 3; k++)
                centre[k] = (lo[k] + hi[k]) / 2;
        *radius = 0.5 * sqrt(pow(hi[0] - lo[0], 2) + pow(hi[1] - lo[1], 2) + pow(hi[2] - lo[2], 2));
}

/* The samples of view i (shots [first, last) of c->g) into a. */
static int view_samples(const struct brdf_ctx *c, size_t i, size_t first, size_t last,
                        struct acc *a, struct brdf_samples *out)
{
        const struct ap_camera *g = &c->g->cameras[i];
        size_t n_seen = 0, npx = (size_t)g->width * g->height;
        _cleanup_free_ struct seen *seen = NULL;
        _cleanup_(image_free) struct brdf_image im = {g->width, g->height,
                                                      malloc(3 * npx * sizeof(float)), malloc(npx)};
        struct shadow sh = {0};
        double centre[3], radius;
        int r = view_texels(c, g, &seen, &n_seen);

        if (r == 0 && (!im.px || !im.sat))
                r = -ENOMEM;
        bounds(&c->atlas.mesh, centre, &radius);
        for (size_t k = first; r == 0 && k < last && n_seen; k++) {
                r = brdf_image_read(c, c->g->shots[k].row, &im);
                if (r == 0)
                        r = shadow_map(c, c->g->shots[k].lamp, centre, radius, &sh);
                if (r == 0)
                        r = shot_samples(c, &c->g->shots[k], &im, &sh, seen, n_seen, a, out);
        }
        free(sh.depth);
        return r;
}

/* a's samples grouped by texel into out (a counting sort). */
static int group(struct acc *a, struct brdf_samples *out)
{
        out->first = calloc(out->n_texels + 1, sizeof(size_t));
        out->s = malloc((a->n + 1) * sizeof(*out->s));
        if (!out->first || !out->s)
                return -ENOMEM;
        for (size_t i = 0; i < a->n; i++)
                out->first[a->tex[i] + 1]++;
        for (size_t t = 0; t < out->n_texels; t++)
                out->first[t + 1] += out->first[t];
        for (size_t i = 0; i < a->n; i++) /* first[t] advances to first[t + 1]... */
                out->s[out->first[a->tex[i]]++] = a->s[i];
        for (size_t t = out->n_texels; t > 0; t--) /* ...and back */
                out->first[t] = out->first[t - 1];
        out->first[0] = 0;
        return 0;
}

int brdf_samples_read(struct brdf_ctx *c, struct brdf_samples *out)
{
        struct acc a = {0};
        struct timespec t0, t1;
        int r = 0;

        clock_gettime(CLOCK_MONOTONIC, &t0);
        *out = (struct brdf_samples){.n_texels = (size_t)c->atlas.width * c->atlas.height};
        out->n_sat_near = calloc(out->n_texels, sizeof(uint32_t));
        if (!out->n_sat_near)
                return -ENOMEM;
        for (size_t k = 0, j; r == 0 && k < c->g->n_shots; k = j) { /* shots grouped by view */
                for (j = k + 1; j < c->g->n_shots && c->g->shots[j].view == c->g->shots[k].view;)
                        j++;
                r = view_samples(c, c->g->shots[k].view, k, j, &a, out);
        }
        if (r == 0)
                r = group(&a, out);
        free(a.s);
        free(a.tex);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        out->read_seconds = (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
        return r;
}

void brdf_samples_free(struct brdf_samples *s)
{
        free(s->first);
        free(s->s);
        free(s->n_sat_near);
        *s = (struct brdf_samples){0};
}
