/* envmap.h - environment maps for relighting (seed 001 section 5): a latitude-longitude
 * image of the light arriving from every direction, read from PNG (8 or 16 bit, grey or
 * RGB, samples taken as linear over full scale) or PFM (float, grey or RGB), and projected
 * onto the real SH basis (appearance/sh.h) so that the light term of the model is
 * L_env(k, c) = sum_m b_{k,m,c} E_{m,c}: the basis is orthonormal.
 *
 * Directions in the object frame: column x is the azimuth phi = 2 pi (x + 0.5) / width
 * from +x towards +y, row y (top first) the polar angle theta = pi (y + 0.5) / height from
 * +z (up the turntable axis): d = (sin theta cos phi, sin theta sin phi, cos theta).
 * A value of 1 everywhere is one unit of the model's light per steradian. */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#define AP_ENVMAP_MAX_SIDE 8192

/* A lat-long map in linear float RGB, rows top first. */
struct ap_envmap {
        int width, height;
        float *rgb; /* 3 * width * height */
        bool ldr;   /* no HDR range: a PNG, whose white clips brighter light (a fallback) */
};

/* Reads path (PNG or PFM, told by its first bytes) into *out. Returns 0, -ENOENT or
 * -errno of reading, -EBADMSG (neither format, truncated, a side above AP_ENVMAP_MAX_SIDE,
 * not lat-long: the width not twice the height, a negative or non-finite texel, no light at
 * all) or -EOPNOTSUPP (a PNG with alpha or a palette) with a sentence in err. Free with
 * ap_envmap_free. */
int ap_envmap_load(const char *path, struct ap_envmap *out, char *err, size_t errlen);

/* Frees e's pixels and zeroes it. Safe on a zeroed map. */
void ap_envmap_free(struct ap_envmap *e);

/* The unit direction d at image position (x, y) in pixels of a width x height map
 * (pixel centres at half-integers). */
void ap_envmap_dir(int width, int height, double x, double y, double d[3]);

/* Bilinear lookup at (x, y) in pixels (centres at integers) of a lat-long image px of
 * channels floats a pixel: wrapped in x, clamped in y. out gets channels values. */
void ap_envmap_bilinear(const float *px, int width, int height, int channels, float x, float y,
                        float *out);

/* Projects e onto the SH of order P: coef[m * 3 + c] = sum over pixels of
 * E_c Y_m d(omega), each pixel's solid angle exact for its row. Never fails. */
void ap_envmap_project(const struct ap_envmap *e, int order, double *coef);
