/* sh.h - real spherical harmonics, orthonormal on the unit sphere, bands 0..P-1 of order P
 * (M = P^2 functions, index l * l + l + m for band l and -l <= m <= l), as the appearance
 * fit, the renderers and the environment-map projection use them. */
#pragma once

/* Fills y[0 .. order^2 - 1] with the basis at the unit direction d (x, y, z). */
void ap_sh_eval(int order, const double d[3], double *y);

/* Same in single precision, for the per-pixel loops of the renderers. */
void ap_sh_evalf(int order, const float d[3], float *y);
