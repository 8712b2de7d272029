/* raster.h - a small z-buffer rasteriser of triangle meshes for the renderers: the depth
 * (camera z, mm) and the triangle seen at each pixel of a pinhole camera, both sides of
 * every face, pixel centres at integer coordinates (OpenCV). A triangle with a corner
 * closer than AP_RASTER_NEAR_MM to the camera plane is skipped (no clipping). */
#pragma once

#include <stddef.h>
#include <stdint.h>

#define AP_RASTER_NEAR_MM 1.0

/* A triangle mesh in the object frame (mm). */
struct ap_mesh {
        size_t nv, nt;
        float *pos;    /* 3 * nv */
        uint32_t *idx; /* 3 * nt, each < nv */
};

/* A pinhole camera without distortion: x_cam = R x_obj + t, u = fx x / z + cx. */
struct ap_pinhole {
        int width, height;
        double fx, fy, cx, cy;
        double R[9], t[3];
};

/* Frees m's arrays and zeroes it. Safe on a zeroed mesh. */
void ap_mesh_free(struct ap_mesh *m);

/* Rasterises m seen by c: depth (width * height, INFINITY where nothing) and, when tri is
 * not NULL, the index of the triangle seen (-1 where nothing). Returns 0 or -ENOMEM. */
int ap_raster(const struct ap_mesh *m, const struct ap_pinhole *c, float *depth, int32_t *tri);

/* Like ap_raster for the rows y0 <= y < y1 only (0 <= y0 <= y1 <= height): the other rows of
 * depth and tri are left as they are, so threads can share a frame by bands. */
int ap_raster_band(const struct ap_mesh *m, const struct ap_pinhole *c, int y0, int y1,
                   float *depth, int32_t *tri);
