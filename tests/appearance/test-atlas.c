/* test-atlas.c - the per-triangle texture atlas (appearance/atlas.h) on a sphere mesh: every
 * texel lies on its triangle, the triangles' uvs put each texel's point back at its centre,
 * the texels around any texel inside a triangle are of that triangle (bilinear taps never mix
 * two), every triangle has texels, and bad arguments are refused; a simplified mesh
 * (mesh.h) keeps its points and its outward normals. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

#include "appearance/atlas.h"
#include "appearance/mesh.h"
#include "tests/test.h"

#define ROWS 12

static void sphere(struct ap_mesh *m)
{
        int cols = 2 * ROWS;
        size_t v = 0, t = 0;

        *m = (struct ap_mesh){.nv = (size_t)(ROWS + 1) * (cols + 1), .nt = (size_t)ROWS * cols * 2};
        m->pos = malloc(3 * m->nv * sizeof(float));
        m->idx = malloc(3 * m->nt * sizeof(uint32_t));
        CHECK(m->pos && m->idx);
        for (int i = 0; i <= ROWS; i++)
                for (int j = 0; j <= cols; j++, v++) {
                        double th = M_PI * i / ROWS, ph = 2 * M_PI * j / cols;
                        m->pos[3 * v] = (float)(30 * sin(th) * cos(ph));
                        m->pos[3 * v + 1] = (float)(30 * sin(th) * sin(ph));
                        m->pos[3 * v + 2] = (float)(30 * cos(th));
                }
        for (int i = 0; i < ROWS; i++)
                for (int j = 0; j < cols; j++, t += 2) {
                        uint32_t a = (uint32_t)(i * (cols + 1) + j), b = a + (uint32_t)cols + 1;
                        uint32_t q[6] = {a, b, a + 1, a + 1, b, b + 1};
                        for (int k = 0; k < 6; k++)
                                m->idx[3 * t + k] = q[k];
                }
}

/* Whether triangle t has two corners at one point (the poles of the UV sphere). */
static bool degenerate(const struct ap_mesh *m, int32_t t)
{
        for (int c = 0; c < 3; c++) {
                const float *p = &m->pos[3 * m->idx[3 * t + c]],
                            *q = &m->pos[3 * m->idx[3 * t + (c + 1) % 3]];
                if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2])
                        return true;
        }
        return false;
}

/* Whether texel i's centre lies inside its triangle (no barycentric clamped to 0). */
static bool interior(const struct ap_atlas *a, size_t i)
{
        return a->tri[i] >= 0 && a->bary[3 * i] > 0 && a->bary[3 * i + 1] > 0 &&
               a->bary[3 * i + 2] > 0;
}

/* The uv of texel i's point through its triangle's corner uvs, against its centre's. */
static void check_uv(const struct ap_atlas *a, size_t i)
{
        const float *uv = &a->uv[6 * (size_t)a->tri[i]], *b = &a->bary[3 * i];
        float u = b[0] * uv[0] + b[1] * uv[2] + b[2] * uv[4];
        float v = b[0] * uv[1] + b[1] * uv[3] + b[2] * uv[5];

        CHECK_NEAR(u * a->width, (double)(i % (size_t)a->width) + 0.5, 1e-3);
        CHECK_NEAR(v * a->height, (double)(i / (size_t)a->width) + 0.5, 1e-3);
}

/* Bilinear taps at random points of every triangle's patch are texels of that triangle. */
static void check_taps(const struct ap_atlas *a)
{
        srand(1);
        for (size_t t = 0; t < a->mesh.nt; t++)
                for (int k = 0; k < 20; k++) {
                        float b0 = (float)rand() / RAND_MAX, b1 = (float)rand() / RAND_MAX;
                        const float *uv = &a->uv[6 * t];
                        float u, v;
                        int x0, y0;
                        if (b0 + b1 > 1)
                                b0 = 1 - b0, b1 = 1 - b1;
                        u = (b0 * uv[0] + b1 * uv[2] + (1 - b0 - b1) * uv[4]) * a->width - 0.5f;
                        v = (b0 * uv[1] + b1 * uv[3] + (1 - b0 - b1) * uv[5]) * a->height - 0.5f;
                        x0 = (int)floorf(u), y0 = (int)floorf(v);
                        for (int j = 0; j < 4; j++) {
                                int x = x0 + (j & 1), y = y0 + (j >> 1);
                                CHECK(x >= 0 && y >= 0 && x < a->width && y < a->height);
                                CHECK_INT(a->tri[(size_t)y * a->width + x], (int32_t)t);
                        }
                }
}

static void test_layout(int cell)
{
        struct ap_mesh m;
        struct ap_atlas a;
        size_t *per_tri, n_interior = 0;

        sphere(&m);
        CHECK_INT(ap_atlas_build(&m, cell, &a), 0);
        CHECK(m.pos == NULL && a.mesh.nt == (size_t)ROWS * 4 * ROWS);
        per_tri = calloc(a.mesh.nt, sizeof(size_t));
        CHECK(per_tri);
        for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
                float p[3], n[3];
                if (!ap_atlas_point(&a, i, p, n))
                        continue;
                CHECK_NEAR(sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), 30,
                           30 * (1 - cos(M_PI / ROWS)));
                if (!degenerate(&a.mesh, a.tri[i])) /* outward, unit */
                        CHECK(n[0] * p[0] + n[1] * p[1] + n[2] * p[2] > 0.9 * 30);
                per_tri[a.tri[i]]++;
                if (!interior(&a, i))
                        continue;
                n_interior++;
                check_uv(&a, i);
        }
        for (size_t t = 0; t < a.mesh.nt; t++)
                CHECK(per_tri[t] >= 1);
        check_taps(&a);
        fprintf(stderr, "cell %d: %dx%d texels, %zu inside their triangle\n", cell, a.width,
                a.height, n_interior);
        CHECK(n_interior >= a.mesh.nt * (size_t)(cell - 5) * (cell - 5) / 4);
        free(per_tri);
        ap_atlas_free(&a);
}

/* A mesh finer than the texels asked (appearance/mesh.h, ap_mesh_simplify, as the BRDF fit
 * does), wound either way: about the target's triangles, its points on the sphere, the
 * atlas's normals still outward (but for a fold or two). */
static void test_simplify(bool flip)
{
        struct ap_mesh m;
        struct ap_atlas a;
        size_t outward = 0, total = 0;

        sphere(&m);
        for (size_t t = 0; flip && t < m.nt; t++) {
                uint32_t v = m.idx[3 * t + 1];
                m.idx[3 * t + 1] = m.idx[3 * t + 2];
                m.idx[3 * t + 2] = v;
        }
        CHECK_INT(ap_mesh_orient(&m), 0);
        CHECK_INT(ap_mesh_simplify(&m, 0), -EINVAL);
        CHECK_INT(ap_mesh_simplify(&m, 150), 0);
        fprintf(stderr, "simplified%s: %zu triangles, %zu vertices, front %d\n",
                flip ? " (wound clockwise)" : "", m.nt, m.nv, m.front);
        CHECK(m.nt >= 75 && m.nt <= 225 && m.nv < (ROWS + 1) * (2 * ROWS + 1));
        for (size_t v = 0; v < m.nv; v++) /* vertices of the original, on the sphere */
                CHECK_NEAR(sqrt(m.pos[3 * v] * m.pos[3 * v] + m.pos[3 * v + 1] * m.pos[3 * v + 1] +
                                m.pos[3 * v + 2] * m.pos[3 * v + 2]),
                           30, 1e-3);
        CHECK_INT(ap_atlas_build(&m, AP_ATLAS_MIN_CELL, &a), 0);
        for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
                float p[3], n[3];
                if (!ap_atlas_point(&a, i, p, n) || degenerate(&a.mesh, a.tri[i]))
                        continue;
                total++;
                outward += n[0] * p[0] + n[1] * p[1] + n[2] * p[2] > 0;
        }
        fprintf(stderr, "%zu of %zu texels' normals outward\n", outward, total);
        CHECK(total > 0 && outward >= 0.99 * total); /* a fold or two where the poles were */
        ap_atlas_free(&a);
}

int main(void)
{
        struct ap_mesh m = {0};
        struct ap_atlas a;

        test_layout(6);
        test_layout(9);
        test_layout(16);
        test_simplify(false);
        test_simplify(true);
        CHECK_INT(ap_atlas_build(&m, 8, &a), -EINVAL); /* empty */
        sphere(&m);
        CHECK_INT(ap_atlas_build(&m, 5, &a), -EINVAL);
        CHECK_INT(ap_atlas_build(&m, 20000, &a), -EINVAL);
        ap_mesh_free(&m);
        CHECK_INT(ap_atlas_cell_for(1000, 1000 * 32), 8);
        CHECK_INT(ap_atlas_cell_for(1000, 10), AP_ATLAS_MIN_CELL);
        return 0;
}
