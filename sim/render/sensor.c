/* sensor.c - the image sensor: photo-electrons to digital numbers with shot noise
 * (Poisson, Gaussian above 64 e-), read noise, full-well saturation, gain, black level
 * and quantisation. Noise comes from a counter-based hash of (seed, frame, camera,
 * pixel, channel), so a frame's bytes do not depend on thread scheduling. */
#include <math.h>

#include "internal.h"

static uint64_t mix64(uint64_t z)
{
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        return z ^ (z >> 31);
}

/* Uniform in (0, 1) from stream state *st (advanced). */
static double uniform(uint64_t *st)
{
        *st += 0x9e3779b97f4a7c15ULL;
        return ((mix64(*st) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static double gauss(uint64_t *st)
{
        double u1 = uniform(st), u2 = uniform(st);

        return sqrt(-2 * log(u1)) * cos(2 * M_PI * u2);
}

static double poisson(uint64_t *st, double mean)
{
        double l, p = 1;
        int k = 0;

        if (mean > 64)
                return fmax(0, mean + sqrt(mean) * gauss(st));
        l = exp(-mean);
        do {
                k++;
                p *= uniform(st);
        } while (p > l);
        return k - 1;
}

double sensor_dn(const struct sensor *se, const struct noise_key *k, uint64_t idx, int ch,
                 double electrons, double gain, double maxdn, bool ideal)
{
        double e = electrons, dn;

        if (!ideal) {
                uint64_t st = mix64(k->seed ^ mix64(k->seq + 0x632be59bd9b4e019ULL) ^
                                    mix64(((uint64_t)k->cam << 56) ^ (idx << 2) ^ (uint64_t)ch));
                if (se->shot_noise && e > 0)
                        e = poisson(&st, e);
                e = fmin(e, se->full_well);
                e += se->read_noise * gauss(&st);
        } else {
                e = fmin(e, se->full_well);
        }
        dn = (e * gain / se->full_well + se->black) * maxdn;
        dn = floor(dn + 0.5);
        return dn < 0 ? 0 : dn > maxdn ? maxdn : dn;
}
