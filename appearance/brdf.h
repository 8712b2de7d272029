/* brdf.h - the reflectance model of issue 12 (docs/appearance.md, "The BRDF model"): per
 * texel of a texture atlas on the object's mesh (atlas.h), or where there is no mesh per pixel
 * of each captured view (the view kind, "The view-kind BRDF model"), the parameters of the
 * material gonio-sim renders (sim/render/material.c, SPEC_BECKMANN):
 *
 *     f(l, v) cos_l = (1 - ks) albedo / pi cos_l + ks D(h) G(l, v) F(l . h) / (4 cos_v)
 *
 * D the anisotropic Beckmann NDF (seed 002 eq. 6) with roughness ax along the tangent t and
 * ay along b = n x t, G the height-correlated Smith term (Walter et al. 2007's fit of
 * Lambda), F Schlick's with f0; n the texel's shading normal. Where the SH model (model.h)
 * keeps how a pixel's value changes with the light, this one keeps a parametric material:
 * sharp highlights, any light, and other tools (glTF, webexport.h) can use it.
 *
 * Units: a pixel's linear value (1 = full scale at the dataset's base exposure, as model.h)
 * under a point light of intensity I (the rig file's units) at distance r from the surface
 * point is  scale * (I / r^2) * f(l, v) cos_l  with `scale` the camera's response (the
 * model's `response`, from the rig file's sensor), so that albedo, ks and f0 are the material's
 * own (what gonio-sim was given). Directions in the object frame (model.h). */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "appearance/atlas.h"
#include "appearance/model.h"

#define AP_BRDF_FORMAT "gonio-brdf 1"

enum ap_brdf_flags {
        AP_BRDF_FITTED = 1,       /* every parameter fitted */
        AP_BRDF_DIFFUSE_ONLY = 2, /* no sample near a highlight: albedo only, ks 0 (a fallback) */
        AP_BRDF_MASKED = 4,       /* too few usable samples (seen, lit, not saturated): none */
        AP_BRDF_ISOTROPIC = 8,    /* view kind: too few samples near the highlight to tell ax
                                   * from ay: one roughness, the tangent not fitted */
        AP_BRDF_LOBE_VIEW = 16,   /* view kind: as ISOTROPIC, but ax, ay the view's medians
                                   * (struct ap_brdf_view) along the base tangent */
};

/* What a model's parameters are attached to. */
enum ap_brdf_kind {
        AP_BRDF_KIND_TEXEL, /* texels of an atlas on the object's mesh */
        AP_BRDF_KIND_VIEW,  /* pixels of each captured view (no mesh) */
};

/* One texel's material. */
struct ap_brdf_texel {
        float albedo[3];             /* diffuse reflectance, linear RGB */
        float ks, ax, ay, f0;        /* specular weight, roughness along t and b, Fresnel f0 */
        float normal[3], tangent[3]; /* unit, object frame; tangent orthogonal to normal */
        float rms;                   /* residual RMS over the texel's samples (pixel units) */
        uint32_t n_samples;          /* (view, light) samples the fit used */
        uint32_t flags;              /* enum ap_brdf_flags */
};

/* One captured view of a view-kind model: a texel per pixel. */
struct ap_brdf_view {
        struct ap_camera cam;
        double dir[3];            /* unit, object centre towards the camera */
        struct ap_brdf_texel *px; /* cam.width * cam.height, row-major */
        float *points;            /* 3 per pixel: the surface point its lights were placed from
                                   * (object frame, mm; on its ray, the depth fitted) */
        float ax, ay;             /* the medians of its pixels whose lobe's shape was fitted
                                   * (ax along the base tangent), given to the others
                                   * (AP_BRDF_LOBE_VIEW); 0: too few such pixels */
};

struct ap_brdf_model {
        char name[AP_NAME_MAX];
        enum ap_brdf_kind kind;
        struct ap_atlas atlas;        /* texel kind: the mesh and its texture atlas */
        struct ap_brdf_texel *texels; /* texel kind: atlas.width * atlas.height, row-major */
        struct ap_brdf_view *views;   /* view kind */
        size_t n_views;
        double centre[3]; /* view kind: the object's centre (mean of the views') */
        double response;  /* pixel value per unit of (I / r^2) f cos (Units) */
        char notes[1024]; /* the fallbacks taken, "" none */
        double fit_seconds;
        double read_seconds; /* of fit_seconds, reading the samples (not stored) */
};

/* Frees m and its arrays; NULL is a no-op. Returns NULL. */
struct ap_brdf_model *ap_brdf_model_free(struct ap_brdf_model *m);

/* f(l, v) cos_l of texel x (the formula above) into out (RGB) for unit l (towards the light)
 * and v (towards the viewer); 0 where either is below the shading normal's horizon. */
void ap_brdf_eval(const struct ap_brdf_texel *x, const float l[3], const float v[3], float out[3]);

/* Whether x can be stored and read back: every number finite, known flags, and unless masked
 * ax, ay > 0 and 0 <= ks <= 1. */
bool ap_brdf_texel_valid(const struct ap_brdf_texel *x);

/* Writes m as models/<m->name>/ of the dataset directory ds_dir (atomically, as
 * ap_model_write), beside or instead of an SH model of that name. Returns 0, -EINVAL (a texel that
 * is not ap_brdf_texel_valid: it could not be read back) or -errno. */
int ap_brdf_write(const struct ap_brdf_model *m, const char *ds_dir);

/* Reads the BRDF model in directory dir (models/<name>/). Returns 0, -ENOENT (no BRDF model
 * there) or -EBADMSG with a sentence naming the file and the problem in err, or -errno. */
int ap_brdf_read(const char *dir, struct ap_brdf_model **ret, char *err, size_t errlen);
