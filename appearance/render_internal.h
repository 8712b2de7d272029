/* render_internal.h - what render.c (setup, lights) and render_px.c (the frame's raster and
 * its pixels) share. Not a public API. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "appearance/render.h"

/* A sampled view in single precision for the per-pixel projection. */
struct rview {
        float R[9], t[3], fx, fy, cx, cy, dist[5];
        bool distorted;
        int width, height;
        int dw, dh; /* its depth map: the pinhole image grown by mx, my each side */
        float mx, my;
        float tol; /* depth tolerance of a tap relative to the depth (AP_RENDER_BIAS, _SLOPE) */
        float *depth;
        const float *weights;
        const uint8_t *mask;
};

struct ap_renderer {
        const struct ap_model *m;
        const struct ap_mesh *mesh;
        struct ap_views *views;
        struct rview *rv; /* n_views */
        float *cube;      /* 6 * AP_RENDER_CUBE^2 texels of (K + 1) * 3 */
        float *planes;    /* per triangle: unit normal, offset (object frame) */
        float *vnormals;  /* per vertex: unit normal outwards (a closed mesh), else NULL */
        double centre[3];
        /* the last frame's raster (pinhole, grown to hold a distorted camera's rays) */
        struct ap_pinhole ras;
        float *ras_depth;
        int32_t *ras_tri;
        size_t ras_cap;
        float *rays; /* 2 per output pixel: undistorted normalised coordinates, or NULL */
        size_t rays_cap;
        struct ap_camera rays_cam; /* the intrinsics rays was made for */
};

/* What every thread of a frame reads. */
struct frame {
        const struct ap_renderer *r;
        const struct ap_camera *cam;
        float Rt[9], C[3];     /* camera to object rotation, camera centre (object frame) */
        float ifxy[2], cxy[2]; /* 1 / fx, 1 / fy, cx, cy */
        enum ap_view_mode mode;
        int oidx[3], on; /* the per-object mode's views and weights */
        float ow[3];
        enum ap_light_kind kind;
        float lpos[3];
        float lconst[(AP_K_MAX + 1) * 3];
        float scale;
        float *rgb;
        uint8_t *mask;
};

/* Sizes r's raster for cam (r->ras*, and r->rays when cam is distorted). Returns 0 or
 * -ENOMEM. */
int render_prepare_raster(struct ap_renderer *r, const struct ap_camera *cam);

/* Rasterises the mesh into r's raster by bands, then shades every pixel of frame f, on up to
 * threads threads. Returns 0 or -ENOMEM. */
int render_run(const struct frame *f, int threads);
