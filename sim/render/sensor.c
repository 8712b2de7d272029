/* sensor.c - the image sensor: photo-electrons to digital numbers with shot noise
 * (Poisson by inversion below 16 e-; above, shot and read noise together as one Gaussian
 * of variance e + read^2), read noise, full-well saturation, gain, black level and
 * rounding.
 *
 * Noise comes from a counter-based hash of (seed, frame, camera, pixel), so a frame's
 * bytes do not depend on the thread count or schedule. Normal deviates are read from a
 * table of 65536 normal quantiles (Acklam's inverse CDF) with 16 hash bits each, one 64-bit
 * hash per pixel: cheap enough for 30 frames/s, exact in distribution to within the
 * quantisation of the quantiles (tails clipped at +-4.3 sigma). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "internal.h"

#define NQ 4096

static uint64_t mix64(uint64_t z)
{
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        return z ^ (z >> 31);
}

/* Acklam's rational approximation of the inverse normal CDF (|error| < 1.2e-9). */
static double norm_quantile(double p)
{
        static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                   -2.759285104469687e+02, 1.383577518672690e+02,
                                   -3.066479806614716e+01, 2.506628277459239e+00};
        static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                   -1.556989798598866e+02, 6.680131188771972e+01,
                                   -1.328068155288572e+01};
        static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                                   -2.400758277161838e+00, -2.549732539343734e+00,
                                   4.374664141464968e+00,  2.938163982698783e+00};
        static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                                   2.445134137142996e+00, 3.754408661907416e+00};
        double q, r;

        if (p < 0.02425 || p > 1 - 0.02425) {
                q = sqrt(-2 * log(p < 0.5 ? p : 1 - p));
                r = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
                    ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
                return p < 0.5 ? r : -r;
        }
        q = p - 0.5;
        r = q * q;
        return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
               (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

int sensor_table(float **ret)
{
        float *q = malloc(NQ * sizeof(float));
        double sum2 = 0;

        if (!q)
                return -ENOMEM;
        for (int i = 0; i < NQ; i++) {
                q[i] = (float)norm_quantile((i + 0.5) / NQ);
                sum2 += (double)q[i] * q[i];
        }
        for (int i = 0; i < NQ; i++) /* unit variance after clipping the tails */
                q[i] = (float)(q[i] / sqrt(sum2 / NQ));
        *ret = q;
        return 0;
}

uint64_t sensor_frame_key(uint64_t seed, uint64_t seq, uint32_t cam)
{
        return mix64(seed ^ mix64(seq + 0x632be59bd9b4e019ULL) ^ mix64((uint64_t)cam << 40));
}

/* Poisson deviate of small mean by inversion of the CDF. */
static int poisson_small(uint64_t h, double mean)
{
        double u = (h >> 11) * (1.0 / 9007199254740992.0), p = exp(-mean), f = p;
        int k = 0;

        while (u > f && k < 200) {
                k++;
                p *= mean / k;
                f += p;
        }
        return k;
}

/* One sample: electrons x, normal deviate g, hash h for the Poisson branch. Float and
 * without data-dependent branches on the common paths: this runs for every sample. */
static uint16_t sample_dn(const struct sensor_rt *rt, float x, float g, uint64_t h)
{
        float fw = rt->full_well, xs = x < fw ? x : fw, var, v;

        var = rt->shot_noise && x < fw ? xs : 0; /* shot and read noise: one Gaussian */
        if (rt->shot_noise && x > 0 && x < 16 && !rt->ideal) {
                xs = (float)poisson_small(mix64(h), x);
                var = 0;
        }
        v = (rt->ideal ? xs : xs + sqrtf(var + rt->read2) * g) * rt->k + rt->b;
        return v <= 0 ? 0 : v >= rt->maxdn ? (uint16_t)rt->maxdn : (uint16_t)(v + 0.5f);
}

void sensor_pixels(const struct sensor_rt *rt, const uint64_t *pix, const float *e, int n, int nch,
                   uint16_t *dn)
{
        uint64_t h[SENSOR_MAX_PIXELS];

        for (int i = 0; i < n; i++) /* independent hashes first: they overlap in the core */
                h[i] = mix64(rt->key ^ (pix[i] * 0x9e3779b97f4a7c15ULL));
        for (int i = 0; i < n; i++)
                for (int c = 0; c < nch; c++)
                        dn[i * nch + c] =
                                sample_dn(rt, e[i * nch + c], rt->q[(h[i] >> (16 * c)) & (NQ - 1)],
                                          h[i] + 1 + c);
}

void sensor_setup(struct sensor_rt *rt, const struct sensor *se, const float *q, uint64_t key,
                  double gain, int bits, bool ideal)
{
        rt->q = q;
        rt->key = key;
        rt->maxdn = bits == 8 ? 255 : 65535;
        rt->k = (float)(gain * rt->maxdn / se->full_well);
        rt->b = (float)(se->black * rt->maxdn);
        rt->full_well = (float)se->full_well;
        rt->read2 = (float)(se->read_noise * se->read_noise);
        rt->shot_noise = se->shot_noise;
        rt->ideal = ideal;
}
