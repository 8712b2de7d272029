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

struct ap_brdf_fit_opts {
        const char *name;        /* the model's name (models/<name>), default "default" */
        size_t texels;           /* about this many texels in the atlas */
        int threads;             /* texels fitted at once, 1..16 */
        double saturation;       /* a raw sample at or above this (full scale 1) is saturated */
        double f0;               /* Fresnel f0 when the rig's scene does not give it */
        const char *calibration; /* as ap_fit_opts */
        const struct rig_backend *const *backends; /* to read the dataset's rig.yaml */
};

/* Fills o: name "default", AP_BRDF_TEXELS_DEFAULT texels, 2 threads, saturation 0.995, f0
 * 0.04 (a dielectric of index 1.5), backends NULL (the caller sets them). */
void ap_brdf_fit_opts_default(struct ap_brdf_fit_opts *o);

/* Fits the BRDF model of dataset d into *ret (free with ap_brdf_model_free; not written: see
 * ap_brdf_write). Texels with too few usable samples are masked, texels without a sample near
 * a highlight diffuse only, both counted in (*ret)->notes. Returns 0 or -EINVAL (bad
 * options), -ENOENT (no rig file, no mesh), -ENODATA (no lamp-lit image), -ENOMEM or the
 * -errno of reading the dataset, with a sentence in err. */
int ap_brdf_fit(struct ds *d, const struct ap_brdf_fit_opts *o, struct ap_brdf_model **ret,
                char *err, size_t errlen);
