/* brdf.c - the BRDF model's evaluation (brdf.h): Lambert plus the anisotropic Beckmann lobe
 * with height-correlated Smith shadowing (Walter et al. 2007's fit of Lambda) and Schlick's
 * Fresnel term, the same arithmetic in single precision as gonio-sim's SPEC_BECKMANN
 * (sim/render/material.c), so that a fitted texel predicts the simulator's pixels. */
#include <math.h>

#include "appearance/brdf.h"

static float dot3(const float a[3], const float b[3])
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static float schlick(float f0, float c)
{
        float m = 1 - fminf(fmaxf(c, 0), 1), m2 = m * m;

        return f0 + (1 - f0) * m2 * m2 * m;
}

/* Smith Lambda of direction w with components (wn, wt, wb) in the frame (n, t, b). */
static float lambda(float ax, float ay, float wn, float wt, float wb)
{
        float den = sqrtf(wt * wt * ax * ax + wb * wb * ay * ay), a;

        if (den <= 0)
                return 0;
        a = wn / den;
        if (a >= 1.6f)
                return 0;
        return (1 - 1.259f * a + 0.396f * a * a) / (3.535f * a + 2.181f * a * a);
}

/* The specular lobe D G F / (4 cos_v) of x at unit l, v (both above the horizon). */
static float lobe(const struct ap_brdf_texel *x, const float b[3], const float l[3],
                  const float v[3], float nl, float nv)
{
        float h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]}, len = sqrtf(dot3(h, h));
        float hn, ht, hb, c2, d, g;

        if (len > 0)
                for (int i = 0; i < 3; i++)
                        h[i] /= len;
        hn = dot3(h, x->normal), ht = dot3(h, x->tangent), hb = dot3(h, b);
        if (hn <= 0)
                return 0;
        c2 = hn * hn;
        d = expf(-(ht * ht / (x->ax * x->ax) + hb * hb / (x->ay * x->ay)) / c2) /
            ((float)M_PI * x->ax * x->ay * c2 * c2);
        g = 1 / (1 + lambda(x->ax, x->ay, nl, dot3(l, x->tangent), dot3(l, b)) +
                 lambda(x->ax, x->ay, nv, dot3(v, x->tangent), dot3(v, b)));
        return d * g * schlick(x->f0, dot3(l, h)) / (4 * nv);
}

void ap_brdf_eval(const struct ap_brdf_texel *x, const float l[3], const float v[3], float out[3])
{
        const float *n = x->normal, *t = x->tangent;
        float nl = dot3(n, l), nv = dot3(n, v), kd, spec = 0;
        float b[3] = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2],
                      n[0] * t[1] - n[1] * t[0]};

        if (nl <= 0 || nv <= 0) {
                out[0] = out[1] = out[2] = 0;
                return;
        }
        kd = (1 - x->ks) * nl * (float)M_1_PI;
        if (x->ks > 0)
                spec = x->ks * lobe(x, b, l, v, nl, nv);
        for (int i = 0; i < 3; i++)
                out[i] = kd * x->albedo[i] + spec;
}
