/* raster.h - a small z-buffer rasteriser of triangle meshes for the renderers: the depth
 * (camera z, mm) and the triangle seen at each pixel of a pinhole camera, both sides of
 * every face, pixel centres at integer coordinates (OpenCV). A triangle with a corner
 * closer than AP_RASTER_NEAR_MM to the camera plane is skipped (no clipping). */
#pragma once

#include <stddef.h>
#include <stdint.h>

#define AP_RASTER_NEAR_MM 1.0
#define AP_MESH_WELD      1e-6 /* ap_mesh_orient welds vertices this close (times the extent) */

/* A triangle mesh in the object frame (mm). */
struct ap_mesh {
        size_t nv, nt;
        float *pos;    /* 3 * nv */
        uint32_t *idx; /* 3 * nt, each < nv */
        int front;     /* 0: both sides drawn; 1 (-1): a closed surface wound counter-clockwise
                        * (clockwise) seen from outside, back faces skipped (ap_mesh_orient) */
};

/* A pinhole camera without distortion: x_cam = R x_obj + t, u = fx x / z + cx. */
struct ap_pinhole {
        int width, height;
        double fx, fy, cx, cy;
        double R[9], t[3];
};

/* Frees m's arrays and zeroes it. Safe on a zeroed mesh. */
void ap_mesh_free(struct ap_mesh *m);

/* The corners lo and hi of m's bounding box (object frame, mm); empty: +inf and -inf. */
void ap_mesh_bounds(const struct ap_mesh *m, double lo[3], double hi[3]);

/* Triangle t's normal times twice its area (unnormalised), by its winding. */
void ap_mesh_face_normal(const struct ap_mesh *m, size_t t, float n[3]);

/* Area-weighted unit vertex normals into out (3 * nv floats, zeroed by the caller): the faces'
 * normals times area summed, then normalised; outwards on a closed mesh (m->front). */
void ap_mesh_vertex_normals(const struct ap_mesh *m, float *out);

/* Sets m->front to 1 or -1 when m is a closed surface (its vertices welded where their
 * positions agree to AP_MESH_WELD, collapsed faces ignored, every edge run by exactly two
 * faces in opposite directions) enclosing a positive or negative volume, else to 0: a camera
 * outside a closed surface never sees a back face first, so the rasteriser skips them.
 * Returns 0 or -ENOMEM (m->front 0). */
int ap_mesh_orient(struct ap_mesh *m);

/* Rasterises m seen by c: depth (width * height, INFINITY where nothing) and, when tri is
 * not NULL, the index of the triangle seen (-1 where nothing). Returns 0 or -ENOMEM. */
int ap_raster(const struct ap_mesh *m, const struct ap_pinhole *c, float *depth, int32_t *tri);

/* Like ap_raster for the rows y0 <= y < y1 only (0 <= y0 <= y1 <= height): the other rows of
 * depth and tri are left as they are, so threads can share a frame by bands. */
int ap_raster_band(const struct ap_mesh *m, const struct ap_pinhole *c, int y0, int y1,
                   float *depth, int32_t *tri);
