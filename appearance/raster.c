/* raster.c - the z-buffer rasteriser (raster.h): vertices to the camera once, then per
 * triangle its pixel bounding box scanned with edge functions; 1/z is affine in the image,
 * so the depth of a pixel is the inverse of the barycentric blend of the corners' 1/z. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "appearance/raster.h"
#include "common/cleanup.h"

void ap_mesh_free(struct ap_mesh *m)
{
        free(m->pos);
        free(m->idx);
        *m = (struct ap_mesh){0};
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
static void draw(const struct corner *q[3], const struct ap_pinhole *c, int yb0, int yb1,
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
        if (area == 0)
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
                        draw(k, c, y0, y1, (int32_t)t, depth, tri);
        }
        return 0;
}

int ap_raster(const struct ap_mesh *m, const struct ap_pinhole *c, float *depth, int32_t *tri)
{
        return ap_raster_band(m, c, 0, c->height, depth, tri);
}
