/* render_env.h - the BRDF model (brdf.h) relit by an environment map with soft shadows, in
 * real time (issue 12): the mesh rasterised from the camera (raster.h), each pixel's texel found
 * through the atlas (atlas.h: the triangle seen, its barycentric point, the triangle's uv);
 *
 *     pixel = scale (diffuse + specular),
 *     diffuse  = (1 - ks) albedo / pi  E(n)  V_d        E: SH irradiance, per texel
 *     specular = ks  S(n, r)  V_s                      S: the blended prefiltered maps
 *
 * V_d the visible share of the light reaching the point: the light lobes of prefilter.h each
 * multiplied by the cosine lobe (seed 000 eq. 11, cosine as one SG: eta 2.133, mu 1.170),
 * their visible fractions from the SSDF of the sphere set (spheres.h) and of the ground plane
 * (eq. 12), weighted by their energy, over the same relative to the point's own tangent plane
 * (E holds only the light above it); computed once per mesh vertex (and per point of a grid on
 * the ground) when the renderer is made, interpolated in between. V_s the visible fraction of
 * the specular lobe (an SG about the reflected direction r of sharpness 1 / (2 ax ay)), per
 * pixel, relative to its part above the tangent plane (the maps' albedo has the rest). The ground:
 * the plane z = 0 within ground_radius, a Lambert surface shaded the same way and shadowed by the
 * spheres. Elsewhere the map itself. docs/appearance.md, "Environment relighting". */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "appearance/brdf.h"
#include "appearance/envmap.h"
#include "appearance/prefilter.h"
#include "appearance/spheres.h"

#define AP_ENV_GROUND_GRID 96 /* visibility samples along each side of the ground's square */
/* The defaults of the renderer's users (gonioctl model render, the web export): */
#define AP_ENV_SPHERES       32   /* spheres of the shadows */
#define AP_ENV_SPHERE_GRID   32   /* ap_spheres_fit's grid */
#define AP_ENV_PAIRS         16   /* representative normal pairs (bench/envlight: 38 dB) */
#define AP_ENV_GROUND_ALBEDO 0.5f /* a grey turntable */
#define AP_ENV_GROUND_TOUCH                                                                        \
        2.0                     /* mm: a mesh stands on z = 0 when its lowest point is this near   \
                                 */
#define AP_ENV_GROUND_RADII 3.0 /* the default ground's radius in the mesh's bounding radii */

/* A point or directional light instead of the map: f(l, v) cos_l times I / r^2 (point) or
 * I (directional), shadowed by the sphere set and the ground as a lobe of sharpness
 * AP_ENV_LIGHT_ETA; the background black. */
struct ap_env_light {
        bool point;      /* else directional */
        float v[3];      /* position (mm, object frame), or the direction towards the light */
        float intensity; /* I */
};

/* Light L's unit direction l from point p and its irradiance factor I / r^2 (point) or I
 * (directional). */
float ap_env_light_at(const struct ap_env_light *L, const float p[3], float l[3]);

#define AP_ENV_LIGHT_ETA 4000.f /* a light of about a degree: shadows nearly hard */

struct ap_env_scene {
        const struct ap_brdf_model *m; /* borrowed, as the rest: they must outlive the renderer */
        const struct ap_envmap *env;   /* the background */
        const struct ap_prefilter *pf;
        const struct ap_spheres *sp; /* NULL: no shadows */
        float ground_albedo[3];
        float ground_radius;              /* mm; 0: no ground */
        float scale;                      /* pixel value per unit of radiance */
        const struct ap_env_light *light; /* not NULL: this light, env and pf unused */
};

/* The prefilter's material for model m (prefilter.h takes one NDF for the whole map): the
 * median ax, ay and f0 over the fitted texels, the anisotropy axis as the principal direction
 * of their tangents; pairs, width and threads left as p has them. A model without a fitted
 * texel gives ax = ay = 0.3, f0 0.04 and the axis +z. */
void ap_brdf_prefilter_params(const struct ap_brdf_model *m, struct ap_prefilter_params *p);

/* The default ground's radius for mesh m: AP_ENV_GROUND_RADII times its bounding radius
 * when it stands on z = 0 (its lowest point within AP_ENV_GROUND_TOUCH), else 0 (none). */
float ap_env_default_ground(const struct ap_mesh *m);

struct ap_env_renderer;

/* Prepares the rendering of sc (the per-vertex and ground visibility). Returns 0, -EINVAL (no
 * model, no light and no map or prefilter, an empty mesh) or -ENOMEM. */
int ap_env_renderer_new(const struct ap_env_scene *sc, struct ap_env_renderer **ret);

/* Frees r; NULL is a no-op. Returns NULL. */
struct ap_env_renderer *ap_env_renderer_free(struct ap_env_renderer *r);

/* Renders what cam sees (its distortion ignored) into rgb (3 floats a pixel, linear) and,
 * if not NULL, mask (1: the object, 2: the ground, 0: the map), on threads threads. Not
 * reentrant on one r. Returns 0, -EINVAL (a bad camera) or -ENOMEM. */
int ap_env_render(struct ap_env_renderer *r, const struct ap_camera *cam, int threads, float *rgb,
                  uint8_t *mask);

/* The diffuse visibility V_d at each vertex of the model's atlas mesh (atlas.mesh.nv floats),
 * as ap_env_render interpolates it; valid while r lives. Never fails. */
const float *ap_env_renderer_vertex_vis(const struct ap_env_renderer *r);

/* V_d on the ground's grid (AP_ENV_GROUND_GRID^2 floats, row j at y = -R + 2 R j / (grid - 1),
 * column i likewise in x, R the ground radius), or NULL without a ground; valid while r
 * lives. */
const float *ap_env_renderer_ground_vis(const struct ap_env_renderer *r);
