/* render.h - relighting the appearance model (seed 001 sections 4.2 and 5) for any light and
 * view by projective texture mapping onto the object's mesh: the mesh rasterised from the
 * requested camera; each visible surface point projected into the up-to-3 sampled views
 * around its view direction (views.h; the direction of each point in the per-pixel mode,
 * the object centre's in the per-object mode), with their distortion; a view dropped where
 * the point is hidden from it (a depth map of the mesh from its camera) or outside its
 * mask; the views' weight images sampled bilinearly and blended by the barycentric weights
 * (Step 4.1), then the light term applied (Step 4.2):
 *
 *     pixel_c = s (L(l, 0, c) + sum_k WL_k L(l, k, c)),  L(l, k, c) = sum_m b_{k,m,c} Y_m(l)
 *
 * with row 0 the model's mean. L is tabulated on a cube map of AP_RENDER_CUBE texels a side
 * so a point light (l per pixel) costs no more than a directional one; a directional light
 * and an environment map use the exact sums. s follows the model's Units (model.h).
 * docs/appearance.md, "Rendering". */
#pragma once

#include <stdint.h>

#include "appearance/model.h"
#include "appearance/raster.h"

#define AP_RENDER_CUBE     32    /* texels per side of the cube map of L(l, k, c) */
#define AP_RENDER_BIAS     0.005 /* depth tolerance of a view's tap, relative to the depth... */
#define AP_RENDER_SLOPE    2.5   /* ...or this many of the view's pixel footprints if more */
#define AP_RENDER_FADE_LO  0.10  /* a view's weight fades in from this cosine to the surface... */
#define AP_RENDER_FADE_HI  0.35  /* ...to full at this one: no seam where it stops seeing it */
#define AP_RENDER_MARGIN   8     /* view depth maps extend by width/this each side (distortion) */
#define AP_RENDER_MAX_SIDE 8192

enum ap_light_kind {
        AP_LIGHT_POINT,       /* v: position (mm, object frame) */
        AP_LIGHT_DIRECTIONAL, /* v: direction towards the light */
        AP_LIGHT_ENV,         /* env: the map's SH coefficients (envmap.h) */
};

struct ap_light {
        enum ap_light_kind kind;
        double v[3];
        double intensity;  /* in the units of the model's light_intensity (0: the model's) */
        const double *env; /* 3M coefficients, [m * 3 + c], of the model's order */
};

enum ap_view_mode {
        AP_VIEW_PIXEL,  /* the view direction of each surface point */
        AP_VIEW_OBJECT, /* one direction per frame: the object centre's (the paper's 60 fps) */
};

struct ap_renderer;

/* Prepares the rendering of model m on mesh (both borrowed: they must outlive the
 * renderer): the view triangulation, the cube map of L and every view's depth map.
 * Returns 0, -EINVAL (no views, a view without weights or size, an empty mesh) or -ENOMEM. */
int ap_renderer_new(const struct ap_model *m, const struct ap_mesh *mesh, struct ap_renderer **ret);

/* Frees r; NULL is a no-op. Returns NULL. */
struct ap_renderer *ap_renderer_free(struct ap_renderer *r);

/* The centre of the mesh's bounding box (object frame, mm). */
void ap_renderer_centre(const struct ap_renderer *r, double c[3]);

/* The views' triangulation (views.h), valid as long as r. */
const struct ap_views *ap_renderer_views(const struct ap_renderer *r);

/* Renders what cam sees of the model under light l into rgb (3 floats a pixel, linear, in
 * the model's units) and mask (1 where the model gave the pixel, else 0 and rgb 0), both
 * cam->width * cam->height, on threads threads (at least 1). Not reentrant on one r (it
 * keeps the frame's buffers). Returns 0, -EINVAL (bad camera or light) or -ENOMEM. */
int ap_render(struct ap_renderer *r, const struct ap_camera *cam, const struct ap_light *l,
              enum ap_view_mode mode, int threads, float *rgb, uint8_t *mask);

/* The light term of model m for directional light from unit direction l: out[(K + 1) * 3],
 * row 0 the mean's (exact sums, no table). Never fails. */
void ap_render_light_dir(const struct ap_model *m, const double l[3], float *out);

/* Fills out with intr's size, intrinsics and distortion and the pose of a camera at eye
 * (object frame, mm) looking at target, the image's up towards +z (towards +y when looking
 * along z). Returns 0, or -EINVAL when eye and target coincide. */
int ap_camera_look_at(const struct ap_camera *intr, const double eye[3], const double target[3],
                      struct ap_camera *out);
