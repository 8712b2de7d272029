/* atlas.c - the per-triangle texture atlas (atlas.h). Cell k of the grid holds triangles 2k
 * (above the cell's anti-diagonal) and 2k + 1 (below it), each a right isosceles triangle a
 * texel in from the cell's border and from the diagonal, so that bilinear taps inside one
 * triangle never reach the other. Every texel of a used cell belongs to the triangle on its
 * side of the diagonal: the texels whose centres fall outside (the gutter) take the nearest
 * point of that triangle, so that they hold the values of the surface next to them. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/atlas.h"

#define ATLAS_MAX_SIDE 16384

/* Corner j of triangle t's patch, in texel units from the cell's corner (x0, y0): the upper
 * triangle (1, 1), (c - 3, 1), (1, c - 3); the lower one mirrored through the cell's centre.
 * A bilinear tap reaches texel centres less than a texel away in x and in y, so from a point
 * of the upper patch (x + y <= c - 2) only centres with x + y <= c, the upper side. */
static void patch_corner(int c, bool lower, int j, float xy[2])
{
        static const int ux[3] = {1, -3, 1}, uy[3] = {1, 1, -3};
        float x = (float)(ux[j] < 0 ? c + ux[j] : ux[j]),
              y = (float)(uy[j] < 0 ? c + uy[j] : uy[j]);

        xy[0] = lower ? (float)c - x : x;
        xy[1] = lower ? (float)c - y : y;
}

/* Barycentric coordinates of (x, y) in the patch's corners, clamped onto the triangle. */
static void patch_bary(const float q[3][2], float x, float y, float b[3])
{
        float d = (q[1][1] - q[2][1]) * (q[0][0] - q[2][0]) +
                  (q[2][0] - q[1][0]) * (q[0][1] - q[2][1]);
        float s = 0;

        b[0] = ((q[1][1] - q[2][1]) * (x - q[2][0]) + (q[2][0] - q[1][0]) * (y - q[2][1])) / d;
        b[1] = ((q[2][1] - q[0][1]) * (x - q[2][0]) + (q[0][0] - q[2][0]) * (y - q[2][1])) / d;
        b[2] = 1 - b[0] - b[1];
        for (int j = 0; j < 3; j++)
                s += b[j] = fmaxf(b[j], 0);
        for (int j = 0; j < 3; j++)
                b[j] /= s;
}

/* Fills the texels of cell k (triangles 2k and 2k + 1 where they exist) and their uvs. */
static void fill_cell(struct ap_atlas *a, size_t k, int per_row)
{
        int c = a->cell, x0 = (int)(k % (size_t)per_row) * c, y0 = (int)(k / (size_t)per_row) * c;
        float q[2][3][2];

        for (int h = 0; h < 2 && 2 * k + (size_t)h < a->mesh.nt; h++)
                for (int j = 0; j < 3; j++) {
                        patch_corner(c, h, j, q[h][j]);
                        a->uv[6 * (2 * k + h) + 2 * j] = (x0 + q[h][j][0]) / (float)a->width;
                        a->uv[6 * (2 * k + h) + 2 * j + 1] = (y0 + q[h][j][1]) / (float)a->height;
                }
        for (int y = 0; y < c; y++)
                for (int x = 0; x < c; x++) {
                        size_t i = (size_t)(y0 + y) * a->width + x0 + x;
                        int h = x + y + 1 > c; /* the centre's side of the anti-diagonal */
                        if (2 * k + (size_t)h >= a->mesh.nt)
                                continue;
                        a->tri[i] = (int32_t)(2 * k + h);
                        patch_bary(q[h], x + 0.5f, y + 0.5f, &a->bary[3 * i]);
                }
}

int ap_atlas_build(struct ap_mesh *mesh, int cell, struct ap_atlas *a)
{
        size_t cells = (mesh->nt + 1) / 2, n;
        int per_row = (int)ceil(sqrt((double)cells)), rows;

        memset(a, 0, sizeof(*a));
        if (mesh->nt == 0 || cell < AP_ATLAS_MIN_CELL || (double)per_row * cell > ATLAS_MAX_SIDE)
                return -EINVAL;
        rows = (int)((cells + (size_t)per_row - 1) / (size_t)per_row);
        *a = (struct ap_atlas){
                .mesh = *mesh, .width = per_row * cell, .height = rows * cell, .cell = cell};
        memset(mesh, 0, sizeof(*mesh));
        n = (size_t)a->width * a->height;
        a->uv = malloc(6 * a->mesh.nt * sizeof(float));
        a->tri = malloc(n * sizeof(int32_t));
        a->bary = calloc(3 * n, sizeof(float));
        a->vnormal = calloc(3 * a->mesh.nv, sizeof(float));
        if (!a->uv || !a->tri || !a->bary || !a->vnormal) {
                ap_atlas_free(a);
                return -ENOMEM;
        }
        memset(a->tri, 0xff, n * sizeof(int32_t));
        for (size_t k = 0; k < cells; k++)
                fill_cell(a, k, per_row);
        ap_mesh_vertex_normals(&a->mesh, a->vnormal);
        return 0;
}

int ap_atlas_cell_for(size_t nt, size_t texels)
{
        double c = nt ? sqrt(2.0 * (double)texels / (double)nt) : AP_ATLAS_MIN_CELL;

        return c < AP_ATLAS_MIN_CELL ? AP_ATLAS_MIN_CELL : (int)lrint(c);
}

bool ap_atlas_point(const struct ap_atlas *a, size_t i, float p[3], float n[3])
{
        const float *b = &a->bary[3 * i];
        int32_t t = a->tri[i];
        float l;

        if (t < 0)
                return false;
        for (int j = 0; j < 3; j++) {
                p[j] = n[j] = 0;
                for (int c = 0; c < 3; c++) {
                        uint32_t v = a->mesh.idx[3 * (size_t)t + c];
                        p[j] += b[c] * a->mesh.pos[3 * v + j];
                        n[j] += b[c] * a->vnormal[3 * v + j];
                }
        }
        l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(l > 0)) { /* vertices of degenerate faces only: the face's own normal */
                ap_mesh_face_normal(&a->mesh, (size_t)t, n);
                l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) * (a->mesh.front < 0 ? -1 : 1);
        }
        for (int j = 0; j < 3 && l > 0; j++)
                n[j] /= l;
        return true;
}

void ap_atlas_free(struct ap_atlas *a)
{
        ap_mesh_free(&a->mesh);
        free(a->uv);
        free(a->tri);
        free(a->bary);
        free(a->vnormal);
        memset(a, 0, sizeof(*a));
}
