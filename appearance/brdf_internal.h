/* brdf_internal.h - what the parts of the BRDF fit share (brdf_fit.c: setup, threads, the
 * model; brdf_samples.c: the samples of every texel from the images; brdf_view.c: the
 * samples and fit of every pixel of each view, the model without a mesh; brdf_solve.c: one
 * texel's or pixel's nonlinear least squares). Private to appearance/. */
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

/* A lamp-lit image normalised: 3 floats a pixel (linear, dark frame subtracted, at the base
 * exposure and gain), saturated pixels flagged. */
struct brdf_image {
        int w, h;
        float *px;
        uint8_t *sat;
};

/* Reads row r of c->g (minus its dark frame) into im (w, h set, arrays allocated by the
 * caller). Returns 0 or -errno with c->err. */
int brdf_image_read(const struct brdf_ctx *c, const struct ds_capture *r, struct brdf_image *im);

/* The base tangent at unit normal n: the object's z axis (the turntable's, the simulator's
 * anisotropy axis) projected on the tangent plane, else x. */
void brdf_base_tangent(const float n[3], float t[3]);

/* Runs fn(args + k * size) for k in 0 .. n (at most 16) on n threads, the calling one
 * included (a thread that cannot start has its share run by the caller), and joins them. */
void brdf_run_threads(int n, void *(*fn)(void *), void *args, size_t size);

/* Adds a sentence to notes (len bytes, "; "-separated). */
void brdf_note(char *notes, size_t len, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Fits the model of c without a mesh into m (kind AP_BRDF_KIND_VIEW): per view, per pixel
 * where the object is, its samples under every lamp of the view. Returns 0 or -errno with
 * c->err. */
int brdf_view_fit(struct brdf_ctx *c, struct ap_brdf_model *m);

/* Reads every lamp-lit image of c->g once and keeps, per texel, the samples of the views that
 * see it and the lamps that light it, unsaturated. Returns 0 or -errno with c->err. */
int brdf_samples_read(struct brdf_ctx *c, struct brdf_samples *out);

void brdf_samples_free(struct brdf_samples *s);

/* What a texel or pixel needs: samples, else masked; samples near a highlight (of its base
 * normal), else diffuse only; samples near a highlight for the lobe's shape, else ax, ay
 * (along the base tangent) where given (AP_BRDF_LOBE_VIEW), else one roughness
 * (AP_BRDF_ISOTROPIC). */
struct brdf_limits {
        size_t min_samples, min_near, min_aniso;
        float ax, ay; /* 0: none given */
};

/* The texels': AP_BRDF_MIN_SAMPLES, AP_BRDF_MIN_NEAR, the lobe's shape always fitted. */
extern const struct brdf_limits brdf_texel_limits;

/* How many of the n samples s are near a highlight of unit normal n0 (tan(h, n0) below
 * AP_BRDF_NEAR_TAN). */
size_t brdf_near_highlight(const struct brdf_sample *s, size_t n, const float n0[3]);

/* Fits texel x (on entry its base normal, tangent and f0) to its n samples s: fitted
 * (isotropic where lim says), diffuse only or masked (lim). Sets every field of *x. Any
 * thread. */
void brdf_solve_texel(const struct brdf_sample *s, size_t n, const struct brdf_limits *lim,
                      struct ap_brdf_texel *x);
