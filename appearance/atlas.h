/* atlas.h - a texture atlas on a triangle mesh, for per-texel data (the BRDF model, brdf.h;
 * its glTF textures): every triangle gets its own patch of texels, two triangles to a square
 * cell (one above the diagonal, one below), texel centres inside their triangle, a gutter of
 * texels copied from their neighbours so that bilinear lookups never mix triangles. Cells
 * are the same size for every triangle: for the near-uniform meshes of a scan (simplified
 * with meshoptimizer, calib/scan.h) texels are near the same size on the surface. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "appearance/raster.h"

#define AP_ATLAS_MIN_CELL 6 /* texels per cell side: legs of two texels */

struct ap_atlas {
        struct ap_mesh mesh; /* owned */
        int width, height;   /* texels */
        int cell;            /* texels per cell side */
        float *uv;           /* 6 per triangle: (u, v) of its corners, [0, 1], v down */
        int32_t *tri;        /* width * height: the triangle a texel's centre lies in, or -1 */
        float *bary;         /* 3 per texel: its centre's barycentric coordinates in tri */
        float *vnormal;      /* 3 per vertex: area-weighted unit normals, outwards when the
                              * mesh is closed (front != 0), else by its winding */
};

/* Builds the atlas of mesh (moved into a->mesh: the caller's struct is zeroed) with cells of
 * cell x cell texels (at least AP_ATLAS_MIN_CELL). Returns 0, -EINVAL (an empty mesh, a smaller
 * cell, an atlas beyond 16384 texels a side) or -ENOMEM. */
int ap_atlas_build(struct ap_mesh *mesh, int cell, struct ap_atlas *a);

/* The cell size giving about `texels` texels in all for a mesh of nt triangles. */
int ap_atlas_cell_for(size_t nt, size_t texels);

/* The object point and the interpolated (area-weighted vertex) normal of texel i; false for a
 * texel of no triangle. */
bool ap_atlas_point(const struct ap_atlas *a, size_t i, float p[3], float n[3]);

/* Frees a's arrays and mesh and zeroes it. Safe on a zeroed atlas. */
void ap_atlas_free(struct ap_atlas *a);
