/* brdf_fit.h - the BRDF model of a dataset (brdf.h; docs/appearance.md, "The BRDF fit"): per
 * texel of an atlas on the object's mesh (mesh.h), every (view, lamp) sample that sees it
 * (depth map of the mesh per view), lit (shadow map of the mesh per lamp) and not saturated,
 * fitted with GSL's multifit_nlinear: roughness along and across the tangent, the tangent's
 * angle and the shading normal's tilt nonlinear, albedo and ks solved linearly inside the
 * residual (variable projection), a Cauchy loss by reweighting. Reads the dataset through
 * the dataset library only. */
#pragma once

#include <stddef.h>

#include "appearance/brdf.h"
#include "common/rigconf.h"
#include "dataset/ds.h"

#define AP_BRDF_TEXELS_DEFAULT 20000
#define AP_BRDF_MIN_SAMPLES    48   /* usable samples a texel needs, else masked */
#define AP_BRDF_NEAR_TAN       0.35 /* a sample is near a highlight: tan(h, n) below this */
#define AP_BRDF_MIN_NEAR       3    /* samples near a highlight for the lobe, else diffuse only */
#define AP_BRDF_MAX_SAMPLES                                                                        \
        768 /* a texel's samples fitted at most: all near a highlight                              \
             * (up to half, more if the rest are fewer), a stride of                               \
             * the rest */

/* Which model the fit makes (brdf.h's kinds). */
enum ap_brdf_fit_kind {
        AP_BRDF_FIT_AUTO,  /* per texel where there is a mesh, else per pixel of each view */
        AP_BRDF_FIT_TEXEL, /* per texel; no mesh is an error */
        AP_BRDF_FIT_VIEW,  /* per pixel of each view, even where there is a mesh */
};

#define AP_BRDF_VIEW_MIN_SAMPLES 12 /* a pixel's lit, unsaturated samples, else masked */
#define AP_BRDF_VIEW_MIN_ANISO   12 /* its samples near the highlight for ax != ay */

struct ap_brdf_fit_opts {
        enum ap_brdf_fit_kind kind;
        const char *name;        /* the model's name (models/<name>), default "default" */
        size_t texels;           /* about this many texels in the atlas */
        int threads;             /* texels fitted at once, 1..16 */
        double saturation;       /* a raw sample at or above this (full scale 1) is saturated */
        double f0;               /* Fresnel f0 when the rig's scene does not give it */
        double background;       /* view kind: a pixel below this in every light is not the
                                  * object (full scale 1, as ap_fit_opts) */
        const char *calibration; /* as ap_fit_opts */
        const struct rig_backend *const *backends; /* to read the dataset's rig.yaml */
};

/* Fills o: kind auto, name "default", AP_BRDF_TEXELS_DEFAULT texels, 2 threads, saturation
 * 0.995, f0 0.04 (a dielectric of index 1.5), background 0.01, backends NULL (the caller sets
 * them). */
void ap_brdf_fit_opts_default(struct ap_brdf_fit_opts *o);

/* Fits the BRDF model of dataset d into *ret (free with ap_brdf_model_free; not written: see
 * ap_brdf_write): per texel of the mesh, or (o->kind) per pixel of each view (docs/
 * appearance.md, "The view-kind BRDF model"). Texels or pixels with too few usable samples are
 * masked, those without a sample near a highlight diffuse only, pixels with too few to tell
 * ax from ay isotropic, all counted in (*ret)->notes. Returns 0 or -EINVAL (bad options),
 * -ENOENT (no rig file; no mesh for kind texel), -ENODATA (no lamp-lit image), -ENOMEM or the
 * -errno of reading the dataset, with a sentence in err. */
int ap_brdf_fit(struct ds *d, const struct ap_brdf_fit_opts *o, struct ap_brdf_model **ret,
                char *err, size_t errlen);
