/* brdf_render.h - the view-kind BRDF model (brdf.h, AP_BRDF_KIND_VIEW: no mesh) relit under a
 * point or directional light (render_env.h's struct ap_env_light), at a captured view pixel for
 * pixel and at another view by blending the captured views around it with the barycentric
 * weights of the triangulated view sphere (views.h). Without a mesh, the surface seen by an
 * output pixel is the point of its ray nearest the model's centre (the fit's own placement);
 * it is looked up in each blended view there, so parallax between views shows as ghosting
 * away from the captured views. docs/appearance.md, "The view-kind BRDF model". */
#pragma once

#include <stdint.h>

#include "appearance/brdf.h"
#include "appearance/render_env.h"
#include "appearance/views.h"

/* The triangulation of the view directions of view-kind model m into *ret (ap_views_free).
 * Returns 0, -EINVAL (not a view-kind model) or -ENOMEM. */
int ap_brdf_views_new(const struct ap_brdf_model *m, struct ap_views **ret);

/* Renders what cam sees of view-kind model m (vs: ap_brdf_views_new's) under light L (I in the
 * rig's units) into rgb (3 floats a pixel, the model's units: the dataset's pixel values) and
 * mask (1 where some view gave the pixel, else 0 and rgb 0), both cam->width * cam->height:
 * each pixel shaded from the parameters and surface point of the nearest pixel of each
 * blended view, seen from cam. Returns 0 or -EINVAL (not a view-kind model, a camera without
 * size). */
int ap_brdf_view_render(const struct ap_brdf_model *m, const struct ap_views *vs,
                        const struct ap_camera *cam, const struct ap_env_light *L, float *rgb,
                        uint8_t *mask);
