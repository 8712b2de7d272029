/* brdf_internal.h - what the parts of the BRDF fit share (brdf_fit.c: setup, threads, the
 * model; brdf_samples.c: the samples of every texel from the images; brdf_solve.c: one
 * texel's nonlinear least squares). Private to appearance/. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "appearance/brdf_fit.h"
#include "appearance/fit.h"

/* One (view, lamp) observation of a texel. */
struct brdf_sample {
        float y[3]; /* the pixel's linear value at the base exposure (model.h's units) */
        float l[3]; /* unit, towards the lamp */
        float v[3]; /* unit, towards the camera */
        float e;    /* response x intensity / r^2: y = e f(l, v) cos_l */
};

/* Every texel's samples, grouped by texel (CSR). */
struct brdf_samples {
        size_t n_texels;
        size_t *first;            /* n_texels + 1: texel i's samples first[i] .. first[i + 1] */
        struct brdf_sample *s;    /* first[n_texels] */
        uint32_t *n_sat_near;     /* per texel: saturated samples near a highlight (left out) */
        size_t n_shadowed, n_sat; /* samples left out */
        double read_seconds;
};

/* The fit's inputs: geometry, atlas, each texel's point and normal. */
struct brdf_ctx {
        const struct ap_brdf_fit_opts *o;
        const char *dir; /* the dataset's */
        struct ap_geometry *g;
        struct ap_atlas atlas;
        float *points, *normals; /* 3 per texel; NAN: no triangle */
        double response, f0;
        double exposure_ref, gain_ref;
        char err[512];
};

/* Reads every lamp-lit image of c->g once and keeps, per texel, the samples of the views that
 * see it and the lamps that light it, unsaturated. Returns 0 or -errno with c->err. */
int brdf_samples_read(struct brdf_ctx *c, struct brdf_samples *out);

void brdf_samples_free(struct brdf_samples *s);

/* Fits texel x (on entry its base normal, tangent and f0) to its n samples s: fitted, diffuse
 * only (fewer than AP_BRDF_MIN_NEAR samples near a highlight) or masked (fewer than
 * AP_BRDF_MIN_SAMPLES). Sets every field of *x. Any thread. */
void brdf_solve_texel(const struct brdf_sample *s, size_t n, struct ap_brdf_texel *x);
