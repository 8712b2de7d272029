/* envscene.h - environment relighting against gonio-sim (tests and bench/envlight): a glossy
 * sphere on the turntable disc under a lat-long map (a sky and a small bright sun) as the
 * simulator's dome, its converged reference rendered by gonio-sim, and the BRDF model of the
 * object built in memory from the simulator's true material (atlas.h's atlas, every
 * texel the material with the mesh's interpolated normal), as the fit would give it. */
#pragma once

#include <stdbool.h>

#include "appearance/brdf.h"
#include "appearance/envmap.h"
#include "tests/render/rtest.h"

struct envscene_opts {
        int width, height;    /* the camera's image */
        double elevation;     /* the camera's, degrees, 400 mm from (0, 0, 30) */
        int env_width;        /* the map's (height: half) */
        int dome_elements;    /* the reference's cap */
        double ks, ax, ay;    /* the sphere's Beckmann lobe (no Fresnel falloff) */
        double ground_radius; /* the turntable disc's, mm */
        int mesh_rows;        /* the model's sphere tessellation (sim_object_mesh); 0: 96 */
        bool lamp;            /* a lamp (ENVSCENE_LAMP_I) lit instead of the map's dome */
};

#define ENVSCENE_LAMP_I 2.0e4 /* the lamp's intensity: 300 mm away, 45 deg up, azimuth 60 */

struct envscene {
        struct envscene_opts o;
        struct rtest t;
        char env_path[64];
        struct ap_envmap env;
        struct ap_brdf_model *model;
        struct ap_camera cam;
        double lamp_pos[3]; /* with o.lamp: its position (object frame, mm) */
};

#define ENVSCENE_ALBEDO                                                                            \
        {                                                                                          \
                0.55f, 0.35f, 0.25f                                                                \
        }
#define ENVSCENE_GROUND                                                                            \
        {                                                                                          \
                0.5f, 0.5f, 0.5f                                                                   \
        }
#define ENVSCENE_F0 1.0f /* ior 0: no Fresnel falloff (a metal-like lobe) */

/* Writes the map, opens the simulated rig, builds the model. Exits the test on failure. */
void envscene_open(struct envscene *es, const struct envscene_opts *o);

void envscene_close(struct envscene *es);

/* gonio-sim's picture (lit by the dome, or by the lamp with o.lamp) in radiance (3 floats a pixel);
 * its wall-clock time into *seconds. */
void envscene_reference(struct envscene *es, float *rgb, double *seconds);

/* PSNR (dB) of a against the reference b over the pixels where mask is non-zero (NULL: all),
 * the peak the reference's largest value there. */
double envscene_psnr(const float *a, const float *b, const uint8_t *mask, size_t n);

/* With $RTEST_DUMP naming a directory: a and the reference b side by side as NAME.ppm (8 bit,
 * gamma 2.2, white at radiance 0.6), for looking at failures. */
void envscene_dump(const float *a, const float *b, int w, int h, const char *name);
