/* prefilter.h - an environment map made ready for real-time glossy relighting, after Motegi
 * et al. (seed 002): for P representative normals n_k spread evenly over the upper hemisphere
 * (equal-area rows), each paired with its opposite -n_k in one lat-long map (a texel w belongs
 * to n_k when w . n_k >= 0, else to -n_k: each normal only ever reads its own hemisphere),
 * the map prefiltered with the anisotropic Beckmann NDF (eq. 6) as the weighted average of
 * eq. 4-5, for the view v that reflects about n_k into w:
 *
 *     L'_k(w) = sum_i L(w_i) D(h_i) dw_i / sum_i D(h_i) dw_i,   h_i = unit(v + w_i),
 *
 * with, in a fourth channel, the lobe's directional albedo A_k(w) = sum_i f_s(w_i, v) dw_i (the
 * specular part of brdf.h for ks = 1: D G F / (4 cos_v) with the tangent of n_k). The specular
 * radiance of a surface of normal n seen from v (reflection r) is ks times the blend of eq. 7
 *
 *     sum_k (n . n_k)^a L'_k(r) A_k(r) / sum_k (n . n_k)^a        (over the n_k facing n)
 *
 * The tangent of a representative normal is the anisotropy axis projected on its plane (the
 * simulator's rule for its shapes). Diffuse light: SH irradiance (Ramamoorthi and Hanrahan
 * 2001) from appearance/envmap.h's projection, bands 0..4. For the soft shadows of
 * spheres.h, the map is also held as AP_PREFILTER_SGS spherical Gaussian lobes (seed 000 eq. 6)
 * centred on even directions, each carrying the light within it. docs/appearance.md,
 * "Environment relighting". */
#pragma once

#include "appearance/envmap.h"

#define AP_PREFILTER_SGS      32 /* light lobes for the diffuse visibility */
#define AP_PREFILTER_SH_ORDER 5  /* SH bands 0..4 of the irradiance */
#define AP_PREFILTER_SH       (AP_PREFILTER_SH_ORDER * AP_PREFILTER_SH_ORDER)

struct ap_prefilter_params {
        int pairs;     /* representative normal pairs, 1..256 */
        int width;     /* width of each prefiltered map (height width / 2), 8..1024 */
        float ax, ay;  /* the Beckmann roughness along the tangent and the bitangent */
        float f0;      /* Schlick's Fresnel at normal incidence (1: none) */
        float axis[3]; /* the anisotropy axis (object frame), unit */
        int threads;   /* at least 1 */
};

struct ap_prefilter {
        struct ap_prefilter_params p;
        float *normals; /* 3 per pair: n_k (z > 0) */
        float *maps;    /* per pair width * height texels of L' (RGB) and A */
        int width, height;
        float a;                       /* eq. 7's exponent, from the normals' spacing */
        float cmin;                    /* n . n_k below which the weight is under 1e-3 (left out) */
        float sh[AP_PREFILTER_SH * 3]; /* irradiance coefficients: A_l L_lm, [m * 3 + c] */
        float sg_dir[3 * AP_PREFILTER_SGS], sg_eta, sg_mu[AP_PREFILTER_SGS];
};

/* Prefilters env with p into *out (free with ap_prefilter_free). Returns 0, -EINVAL (a
 * parameter out of range, an empty map) or -ENOMEM. */
int ap_prefilter_build(const struct ap_envmap *env, const struct ap_prefilter_params *p,
                       struct ap_prefilter *out);

/* Frees f's arrays and zeroes it. Safe on a zeroed one. */
void ap_prefilter_free(struct ap_prefilter *f);

/* The specular radiance for ks = 1 at unit normal n, reflected direction r (eq. 7's blend)
 * into out (RGB). */
void ap_prefilter_specular(const struct ap_prefilter *f, const float n[3], const float r[3],
                           float out[3]);

/* Irradiance E(n) (RGB) from the SH of the map, for unit n: pi times the radiance of a white
 * Lambert surface. */
void ap_prefilter_irradiance(const struct ap_prefilter *f, const float n[3], float out[3]);

/* The index of the representative normal (0 .. 2 pairs - 1; k + pairs is -n_k) nearest n. */
int ap_prefilter_nearest(const struct ap_prefilter *f, const float n[3]);
