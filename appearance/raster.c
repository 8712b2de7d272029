/* raster.c - the z-buffer rasteriser (raster.h): vertices to the camera once, then per
 * triangle its pixel bounding box scanned with edge functions; 1/z is affine in the image,
 * so the depth of a pixel is the inverse of the barycentric blend of the corners' 1/z. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/raster.h"
#include "common/cleanup.h"

void ap_mesh_free(struct ap_mesh *m)
{
        free(m->pos);
        free(m->idx);
        *m = (struct ap_mesh){0};
}

/* A vertex's position rounded to the weld grid, and its index: sorted to weld. */
struct vkey {
        int64_t p[3];
        uint32_t i;
};

static int cmp_vkey(const void *a, const void *b)
{
        const struct vkey *x = a, *y = b;

        for (int j = 0; j < 3; j++)
                if (x->p[j] != y->p[j])
                        return x->p[j] < y->p[j] ? -1 : 1;
        return 0;
}

static int cmp_u64(const void *a, const void *b)
{
        uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;

        return (x > y) - (x < y);
}

/* The welded index of every vertex into weld: vertices whose positions round to the same
 * point of a grid of AP_MESH_WELD times the mesh's extent share the first one's index (the
 * seam and the poles of a sphere made by angles are equal only to rounding). */
static int weld_vertices(const struct ap_mesh *m, uint32_t *weld)
{
        _cleanup_free_ struct vkey *k = malloc((m->nv + 1) * sizeof(*k));
        double ext = 0;

        if (!k)
                return -ENOMEM;
        for (size_t i = 0; i < 3 * m->nv; i++)
                ext = fmax(ext, fabs(m->pos[i]));
        ext = ext > 0 ? ext * AP_MESH_WELD : 1;
        for (size_t i = 0; i < m->nv; i++) {
                for (int j = 0; j < 3; j++)
                        k[i].p[j] = llrint(m->pos[3 * i + j] / ext);
                k[i].i = (uint32_t)i;
        }
        qsort(k, m->nv, sizeof(*k), cmp_vkey);
        for (size_t i = 0; i < m->nv; i++)
                weld[k[i].i] = i && !cmp_vkey(&k[i], &k[i - 1]) ? weld[k[i - 1].i] : k[i].i;
        return 0;
}

/* True when every directed edge (sorted keys a << 32 | b) is unique and its reverse is there. */
static bool edges_paired(const uint64_t *e, size_t n)
{
        for (size_t i = 0; i < n; i++) {
                uint64_t rev = e[i] >> 32 | e[i] << 32;
                if ((i + 1 < n && e[i + 1] == e[i]) || !bsearch(&rev, e, n, sizeof(*e), cmp_u64))
                        return false;
        }
        return true;
}

void ap_mesh_bounds(const struct ap_mesh *m, double lo[3], double hi[3])
{
        for (int j = 0; j < 3; j++)
                lo[j] = INFINITY, hi[j] = -INFINITY;
        for (size_t i = 0; i < m->nv; i++)
                for (int j = 0; j < 3; j++) {
                        lo[j] = fmin(lo[j], m->pos[3 * i + j]);
                        hi[j] = fmax(hi[j], m->pos[3 * i + j]);
                }
}

void ap_mesh_face_normal(const struct ap_mesh *m, size_t t, float n[3])
{
        const float *p0 = &m->pos[3 * m->idx[3 * t]], *p1 = &m->pos[3 * m->idx[3 * t + 1]],
                    *p2 = &m->pos[3 * m->idx[3 * t + 2]];
        float u[3], v[3];

        for (int j = 0; j < 3; j++)
                u[j] = p1[j] - p0[j], v[j] = p2[j] - p0[j];
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
}

void ap_mesh_vertex_normals(const struct ap_mesh *m, float *out)
{
        float sign = m->front < 0 ? -1.f : 1.f;

        for (size_t t = 0; t < m->nt; t++) {
                float n[3];
                ap_mesh_face_normal(m, t, n);
                for (int c = 0; c < 3; c++)
                        for (int j = 0; j < 3; j++)
                                out[3 * m->idx[3 * t + c] + j] += n[j];
        }
        for (size_t i = 0; i < m->nv; i++) {
                float *n = &out[3 * i], l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                for (int j = 0; j < 3 && l > 0; j++)
                        n[j] *= sign / l;
        }
}

int ap_mesh_orient(struct ap_mesh *m)
{
        _cleanup_free_ uint32_t *weld = malloc((m->nv + 1) * sizeof(uint32_t));
        _cleanup_free_ uint64_t *e = malloc((3 * m->nt + 1) * sizeof(uint64_t));
        double vol = 0;
        size_t n = 0;

        m->front = 0;
        if (!weld || !e || weld_vertices(m, weld) < 0)
                return -ENOMEM;
        for (size_t t = 0; t < m->nt; t++) {
                const uint32_t *f = &m->idx[3 * t];
                const float *a = &m->pos[3 * f[0]], *b = &m->pos[3 * f[1]], *c = &m->pos[3 * f[2]];
                uint32_t w[3] = {weld[f[0]], weld[f[1]], weld[f[2]]};
                if (w[0] == w[1] || w[1] == w[2] || w[2] == w[0])
                        continue; /* collapsed (a pole's cap): no surface, no edges */
                for (int j = 0; j < 3; j++)
                        e[n++] = (uint64_t)w[j] << 32 | w[(j + 1) % 3];
                vol += a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) +
                       a[1] * ((double)b[2] * c[0] - (double)b[0] * c[2]) +
                       a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
        }
        qsort(e, n, sizeof(*e), cmp_u64);
        if (n && edges_paired(e, n) && vol != 0)
                m->front = vol > 0 ? 1 : -1;
        return 0;
}

/* Projected corners: u, v and 1/z. */
struct corner {
        float u, v, iz;
};

static void project_all(const struct ap_mesh *m, const struct ap_pinhole *c, struct corner *out)
{
        for (size_t i = 0; i < m->nv; i++) {
                const float *p = &m->pos[3 * i];
                double x[3];
                for (int j = 0; j < 3; j++)
                        x[j] = c->R[3 * j] * p[0] + c->R[3 * j + 1] * p[1] +
                               c->R[3 * j + 2] * p[2] + c->t[j];
                if (x[2] < AP_RASTER_NEAR_MM) {
                        out[i] = (struct corner){0, 0, -1};
                        continue;
                }
                out[i] = (struct corner){(float)(c->fx * x[0] / x[2] + c->cx),
                                         (float)(c->fy * x[1] / x[2] + c->cy), (float)(1 / x[2])};
        }
}

static float edge(const struct corner *a, const struct corner *b, float x, float y)
{
        return (b->u - a->u) * (y - a->v) - (b->v - a->v) * (x - a->u);
}

static inline float min3(float a, float b, float c)
{
        float m = a < b ? a : b;

        return m < c ? m : c;
}

static inline float max3(float a, float b, float c)
{
        float m = a > b ? a : b;

        return m > c ? m : c;
}

/* The smallest integer >= v, for |v| far below INT_MAX. */
static inline int iceil(float v)
{
        int i = (int)v;

        return i + (v > (float)i);
}

/* Draws triangle q (index id) into the rows yb0 <= y < yb1: the barycentric weights by
 * edge functions stepped along each row, the depth as the inverse of the blend of 1/z. */
static void draw(const struct corner *q[3], const struct ap_pinhole *c, int front, int yb0, int yb1,
                 int32_t id, float *depth, int32_t *tri)
{
        int y0 = iceil(min3(q[0]->v, q[1]->v, q[2]->v)),
            y1 = iceil(max3(q[0]->v, q[1]->v, q[2]->v)) - 1;
        int x0 = iceil(min3(q[0]->u, q[1]->u, q[2]->u)),
            x1 = iceil(max3(q[0]->u, q[1]->u, q[2]->u)) - 1;
        float area, inv, d0, d1;

        y0 = y0 < yb0 ? yb0 : y0, y1 = y1 >= yb1 ? yb1 - 1 : y1;
        x0 = x0 < 0 ? 0 : x0, x1 = x1 >= c->width ? c->width - 1 : x1;
        if (y0 > y1 || x0 > x1)
                return;
        area = edge(q[0], q[1], q[2]->u, q[2]->v);
        if (area == 0 || area * (float)front > 0) /* rows run down: a front face is negative */
                return;
        inv = 1 / area;
        d0 = -(q[2]->v - q[1]->v) * inv, d1 = -(q[0]->v - q[2]->v) * inv;
        for (int y = y0; y <= y1; y++) {
                float w0 = edge(q[1], q[2], (float)x0, (float)y) * inv;
                float w1 = edge(q[2], q[0], (float)x0, (float)y) * inv;
                size_t i = (size_t)y * c->width + x0;
                for (int x = x0; x <= x1; x++, i++, w0 += d0, w1 += d1) {
                        float w2 = 1 - w0 - w1, iz;
                        if (w0 < 0 || w1 < 0 || w2 < 0)
                                continue;
                        iz = w0 * q[0]->iz + w1 * q[1]->iz + w2 * q[2]->iz;
                        if (iz * depth[i] > 1) { /* nearer than what is there */
                                depth[i] = 1 / iz;
                                if (tri)
                                        tri[i] = id;
                        }
                }
        }
}

int ap_raster_band(const struct ap_mesh *m, const struct ap_pinhole *c, int y0, int y1,
                   float *depth, int32_t *tri)
{
        _cleanup_free_ struct corner *q = malloc((m->nv + 1) * sizeof(*q));
        size_t a = (size_t)y0 * c->width, b = (size_t)y1 * c->width;

        if (!q)
                return -ENOMEM;
        for (size_t i = a; i < b; i++)
                depth[i] = INFINITY;
        if (tri)
                for (size_t i = a; i < b; i++)
                        tri[i] = -1;
        project_all(m, c, q);
        for (size_t t = 0; t < m->nt; t++) {
                const struct corner *k[3] = {&q[m->idx[3 * t]], &q[m->idx[3 * t + 1]],
                                             &q[m->idx[3 * t + 2]]};
                if (k[0]->iz > 0 && k[1]->iz > 0 && k[2]->iz > 0)
                        draw(k, c, m->front, y0, y1, (int32_t)t, depth, tri);
        }
        return 0;
}

int ap_raster(const struct ap_mesh *m, const struct ap_pinhole *c, float *depth, int32_t *tri)
{
        return ap_raster_band(m, c, 0, c->height, depth, tri);
}
