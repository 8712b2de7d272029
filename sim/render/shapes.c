/* shapes.c - triangle meshes of the built-in objects (tessellated sphere, cylinder,
 * faceted gem, relief plate like a bronze mirror's back, board rectangle, turntable disc),
 * all in their shape frame with the base on z = 0, and mesh utilities. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

int mesh_alloc(struct mesh *m, size_t nv, size_t nt, bool normals, bool uvs)
{
        memset(m, 0, sizeof(*m));
        m->nv = nv;
        m->nt = nt;
        m->pos = calloc(nv * 3 + 1, sizeof(float));    /* +1: Embree reads 16 bytes */
        m->idx = calloc(nt * 3 + 1, sizeof(uint32_t)); /* +1: Embree reads 16 bytes */
        m->nrm = normals ? calloc(nv * 3, sizeof(float)) : NULL;
        m->uv = uvs ? calloc(nv * 2, sizeof(float)) : NULL;
        if (!m->pos || !m->idx || (normals && !m->nrm) || (uvs && !m->uv)) {
                mesh_free(m);
                return -ENOMEM;
        }
        return 0;
}

void mesh_free(struct mesh *m)
{
        free(m->pos);
        free(m->nrm);
        free(m->uv);
        free(m->idx);
        memset(m, 0, sizeof(*m));
}

static void set3(float *p, size_t i, float x, float y, float z)
{
        p[3 * i] = x;
        p[3 * i + 1] = y;
        p[3 * i + 2] = z;
}

static void tri(struct mesh *m, size_t *k, uint32_t a, uint32_t b, uint32_t c)
{
        m->idx[3 * *k] = a;
        m->idx[3 * *k + 1] = b;
        m->idx[3 * *k + 2] = c;
        (*k)++;
}

/* Triangulates a (rows+1) x (cols+1) vertex grid starting at vertex base. */
static void grid(struct mesh *m, size_t *k, uint32_t base, int rows, int cols)
{
        for (int i = 0; i < rows; i++)
                for (int j = 0; j < cols; j++) {
                        uint32_t a = base + i * (cols + 1) + j, b = a + cols + 1;
                        tri(m, k, a, a + 1, b + 1);
                        tri(m, k, a, b + 1, b);
                }
}

int shape_sphere_mesh(float radius, int res, struct mesh *m)
{
        int rows = MAX(res, 3), cols = 2 * rows, r;
        size_t k = 0, v = 0;

        r = mesh_alloc(m, (size_t)(rows + 1) * (cols + 1), (size_t)rows * cols * 2, true, true);
        if (r < 0)
                return r;
        for (int i = 0; i <= rows; i++)
                for (int j = 0; j <= cols; j++, v++) {
                        double th = M_PI * i / rows, ph = 2 * M_PI * j / cols;
                        float x = sin(th) * cos(ph), y = sin(th) * sin(ph), z = cos(th);
                        set3(m->pos, v, radius * x, radius * y, radius * (z + 1));
                        set3(m->nrm, v, x, y, z);
                        m->uv[2 * v] = (float)j / cols;
                        m->uv[2 * v + 1] = 1 - (float)i / rows;
                }
        grid(m, &k, 0, rows, cols);
        return 0;
}

/* Side wall of a solid of revolution (radius rad(z) constant: a cylinder) plus caps. */
int shape_cylinder(float radius, float height, int res, struct mesh *m)
{
        int n = MAX(res, 8), r;
        size_t k = 0, v = 0;

        r = mesh_alloc(m, 2 * (size_t)(n + 1) + 2 * (size_t)(n + 1), 2 * (size_t)n + 2 * (n - 2),
                       true, true);
        if (r < 0)
                return r;
        for (int i = 0; i <= 1; i++)
                for (int j = 0; j <= n; j++, v++) {
                        double ph = 2 * M_PI * j / n;
                        set3(m->pos, v, radius * cos(ph), radius * sin(ph), height * i);
                        set3(m->nrm, v, cos(ph), sin(ph), 0);
                        m->uv[2 * v] = (float)j / n;
                        m->uv[2 * v + 1] = (float)i;
                }
        grid(m, &k, 0, 1, n);
        for (int c = 0; c < 2; c++) { /* caps: fans over the first n rim vertices */
                uint32_t base = (uint32_t)v;
                for (int j = 0; j <= n; j++, v++) {
                        double ph = 2 * M_PI * j / n;
                        set3(m->pos, v, radius * cos(ph), radius * sin(ph), height * c);
                        set3(m->nrm, v, 0, 0, c ? 1 : -1);
                        m->uv[2 * v] = 0.5f + 0.5f * cos(ph);
                        m->uv[2 * v + 1] = 0.5f + 0.5f * sin(ph);
                }
                for (int j = 1; j < n - 1; j++)
                        tri(m, &k, base, base + j + (c ? 0 : 1), base + j + (c ? 1 : 0));
        }
        return 0;
}

/* A round brilliant-like gem resting on a small culet: table, crown and pavilion facets
 * (flat shaded). size is the girdle diameter. */
int shape_gem(float size, int facets, struct mesh *m)
{
        int n = MAX(facets, 5), r;
        float rg = size / 2, rt = 0.55f * rg, rc = 0.08f * rg;
        float zc = 0, zg = 0.43f * size, zt = 0.59f * size;
        float ring[4][2] = {{rc, zc}, {rg, zg}, {rt, zt}, {0, zt}};
        size_t k = 0;

        r = mesh_alloc(m, 4 * (size_t)n + 2, 6 * (size_t)n + 2 * n, false, false);
        if (r < 0)
                return r;
        for (int i = 0; i < 4; i++)
                for (int j = 0; j < n; j++) {
                        double ph = 2 * M_PI * (j + (i == 2 ? 0.5 : 0)) / n;
                        set3(m->pos, (size_t)i * n + j, ring[i][0] * cos(ph), ring[i][0] * sin(ph),
                             ring[i][1]);
                }
        set3(m->pos, 4 * (size_t)n, 0, 0, zc);
        set3(m->pos, 4 * (size_t)n + 1, 0, 0, zt);
        for (int j = 0; j < n; j++) {
                uint32_t j1 = (j + 1) % n;
                tri(m, &k, j, j1, n + j1); /* pavilion */
                tri(m, &k, j, n + j1, n + j);
                tri(m, &k, n + j, n + j1, 2 * n + j); /* crown */
                tri(m, &k, n + j1, 2 * n + j1, 2 * n + j);
                tri(m, &k, 4 * n, j1, j);                     /* culet */
                tri(m, &k, 4 * n + 1, 2 * n + j, 2 * n + j1); /* table */
        }
        m->nt = k;
        return 0;
}

/* Height of the relief at polar (rho in [0,1], phi): a rim, a central knob and petals. */
static float relief_height(double rho, double phi)
{
        double rim = exp(-pow((rho - 0.92) / 0.04, 2));
        double knob = exp(-pow(rho / 0.12, 2));
        double petals = (0.5 + 0.5 * cos(8 * phi)) * exp(-pow((rho - 0.55) / 0.15, 2));
        double rings = 0.3 * exp(-pow((rho - 0.3) / 0.02, 2));

        return (float)(0.6 * rim + 0.8 * knob + 0.4 * petals + rings);
}

int shape_relief(float size, int res, struct mesh *m)
{
        int nr = MAX(res, 8), np = 4 * nr, r;
        float rad = size / 2, base = 0.04f * size, amp = 0.05f * size;
        size_t k = 0, v = 0;

        r = mesh_alloc(m, (size_t)(nr + 1) * (np + 1), (size_t)nr * np * 2, false, true);
        if (r < 0)
                return r;
        for (int i = 0; i <= nr; i++)
                for (int j = 0; j <= np; j++, v++) {
                        double rho = (double)i / nr, ph = 2 * M_PI * j / np;
                        float z = i == nr ? 0 : base + amp * relief_height(rho, ph);
                        set3(m->pos, v, rad * rho * cos(ph), rad * rho * sin(ph), z);
                        m->uv[2 * v] = 0.5f + 0.5f * rho * cos(ph);
                        m->uv[2 * v + 1] = 0.5f + 0.5f * rho * sin(ph);
                }
        grid(m, &k, 0, nr, np);
        return mesh_smooth_normals(m);
}

int shape_rect(float x0, float y0, float x1, float y1, struct mesh *m)
{
        size_t k = 0;
        int r = mesh_alloc(m, 4, 2, false, false);

        if (r < 0)
                return r;
        set3(m->pos, 0, x0, y0, 0);
        set3(m->pos, 1, x1, y0, 0);
        set3(m->pos, 2, x1, y1, 0);
        set3(m->pos, 3, x0, y1, 0);
        tri(m, &k, 0, 1, 2);
        tri(m, &k, 0, 2, 3);
        return 0;
}

int shape_disc(float radius, int res, struct mesh *m)
{
        int n = MAX(res, 8), r = mesh_alloc(m, (size_t)n + 1, (size_t)n, false, false);
        size_t k = 0;

        if (r < 0)
                return r;
        for (int j = 0; j < n; j++) {
                double ph = 2 * M_PI * j / n;
                set3(m->pos, j, radius * cos(ph), radius * sin(ph), 0);
                tri(m, &k, n, j, (j + 1) % n);
        }
        return 0;
}

int mesh_smooth_normals(struct mesh *m)
{
        free(m->nrm);
        m->nrm = calloc(m->nv * 3, sizeof(float));
        if (!m->nrm)
                return -ENOMEM;
        for (size_t t = 0; t < m->nt; t++) {
                const uint32_t *ix = m->idx + 3 * t;
                struct v3 a = v3(m->pos[3 * ix[0]], m->pos[3 * ix[0] + 1], m->pos[3 * ix[0] + 2]);
                struct v3 b = v3(m->pos[3 * ix[1]], m->pos[3 * ix[1] + 1], m->pos[3 * ix[1] + 2]);
                struct v3 c = v3(m->pos[3 * ix[2]], m->pos[3 * ix[2] + 1], m->pos[3 * ix[2] + 2]);
                struct v3 n = v3_cross(v3_sub(b, a), v3_sub(c, a));
                for (int i = 0; i < 3; i++) {
                        m->nrm[3 * ix[i]] += n.x;
                        m->nrm[3 * ix[i] + 1] += n.y;
                        m->nrm[3 * ix[i] + 2] += n.z;
                }
        }
        for (size_t i = 0; i < m->nv; i++) {
                struct v3 n = v3_norm(v3(m->nrm[3 * i], m->nrm[3 * i + 1], m->nrm[3 * i + 2]));
                set3(m->nrm, i, n.x, n.y, n.z);
        }
        return 0;
}

void mesh_fit(struct mesh *m, float size)
{
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        float ext = 0, s;

        for (size_t i = 0; i < m->nv; i++)
                for (int c = 0; c < 3; c++) {
                        lo[c] = fminf(lo[c], m->pos[3 * i + c]);
                        hi[c] = fmaxf(hi[c], m->pos[3 * i + c]);
                }
        for (int c = 0; c < 3; c++)
                ext = fmaxf(ext, hi[c] - lo[c]);
        s = ext > 0 ? size / ext : 1;
        for (size_t i = 0; i < m->nv; i++) {
                m->pos[3 * i] = (m->pos[3 * i] - (lo[0] + hi[0]) / 2) * s;
                m->pos[3 * i + 1] = (m->pos[3 * i + 1] - (lo[1] + hi[1]) / 2) * s;
                m->pos[3 * i + 2] = (m->pos[3 * i + 2] - lo[2]) * s;
        }
}

void mesh_transform(struct mesh *m, const double R[9], const double t[3])
{
        for (size_t i = 0; i < m->nv; i++) {
                double p[3] = {m->pos[3 * i], m->pos[3 * i + 1], m->pos[3 * i + 2]}, q[3];
                m3d_apply(R, p, q);
                for (int c = 0; c < 3; c++)
                        m->pos[3 * i + c] = (float)(q[c] + t[c]);
                if (!m->nrm)
                        continue;
                for (int c = 0; c < 3; c++)
                        p[c] = m->nrm[3 * i + c];
                m3d_apply(R, p, q);
                for (int c = 0; c < 3; c++)
                        m->nrm[3 * i + c] = (float)q[c];
        }
}
