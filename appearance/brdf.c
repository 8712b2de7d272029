/* brdf.c - the BRDF model's evaluation (brdf.h): gonio-sim's own SPEC_BECKMANN lobe
 * (sim/render/material.c's brdf_cos: Lambert plus the anisotropic Beckmann lobe with
 * height-correlated Smith shadowing and Schlick's Fresnel term) called on the texel's
 * parameters, so that a fitted texel predicts the simulator's pixels with its arithmetic. */
#include "appearance/brdf.h"
#include "sim/render/internal.h"

void ap_brdf_eval(const struct ap_brdf_texel *x, const float l[3], const float v[3], float out[3])
{
        const struct surf s = {.model = x->ks > 0 ? SPEC_BECKMANN : SPEC_NONE, /* ks 0: no lobe */
                               .albedo = {x->albedo[0], x->albedo[1], x->albedo[2]},
                               .ks = x->ks,
                               .ax = x->ax,
                               .ay = x->ay,
                               .f0 = x->f0};

        brdf_cos(&s, v3(x->normal[0], x->normal[1], x->normal[2]),
                 v3(x->tangent[0], x->tangent[1], x->tangent[2]), v3(l[0], l[1], l[2]),
                 v3(v[0], v[1], v[2]), out);
}
