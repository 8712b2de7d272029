/* laserline.c - the laser line's sub-pixel centre per row of a frame (see laserline.h).
 *
 * DESIGN. Each row (or column) is read once: d[x] = max(on[x] - off[x], 0) in the laser's
 * channel, into a stack buffer, with the maximum of every block of LL_BLOCK samples (the only
 * full passes; both are vectorised, compiled for AVX2 and plain x86-64 by target_clones). With
 * an off frame, a row whose on samples (every channel) all lie under min_peak is skipped first,
 * its off row unread.
 * Candidates are then taken from the brightest block down. From a candidate's top (or its run
 * of clipped samples) the profile is followed down each side to its foot, at most max_width
 * px; the higher foot is the local baseline (it removes ambient light in one-frame mode). The
 * height above it must reach min_peak and snr times the noise measured in two windows beside
 * the peak, and the width at half height must lie in [min_width, max_width]; otherwise the
 * candidate (speckle, a step, a patch of light) is left out of the search and the next one
 * is tried. A second plausible peak at least `ambiguity` as high as the first rejects the
 * row. Clipped peaks are centred by the centre of mass of the run and its flanks (the
 * clipped profile is symmetric about the centre); others by the chosen estimator, by default
 * the centre of mass, refined by a kernel-weighted centroid where the noise beside the peak
 * (ambient light's shot noise) is not negligible. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "laserline.h"

#define LL_BLOCK      64  /* samples per block of the candidate search */
#define LL_CANDIDATES 16  /* candidates tried per row */
#define LL_NOISE_GAP  24  /* px between a peak's top and the windows its noise comes from */
#define LL_NOISE_LEN  16  /* px in each of those windows */
#define LL_KERNEL     1.1 /* LASERLINE_WEIGHTED: the kernel's sigma, in units of the line's, */
#define LL_KERNEL_MIN 1.5 /*   and at least this (px): a narrower kernel is biased by sampling */
#define LL_REFINE     2   /* LASERLINE_WEIGHTED: iterations */
#define LL_NOISY      200 /* LASERLINE_WEIGHTED: weighted where the noise is 1/200 of the height */

struct line {
        const uint8_t *on8; /* the on frame's samples (one of on8, on16) */
        const uint16_t *on16;
        size_t first, step; /* sample index of the line's first pixel, samples between pixels */
        int n, nb;          /* pixels, blocks */
        int sat;            /* clipped sample value (DN) */
        double floor;       /* least peak height: min_peak (DN) */
        int cap;            /* a step counts at most this much in the noise (speckle) */
        int spans, span_lo[LL_CANDIDATES], span_hi[LL_CANDIDATES]; /* tried: not searched */
        uint16_t d[LL_BLOCK * ((LASERLINE_MAX_LEN + LL_BLOCK - 1) / LL_BLOCK)];
        uint16_t bmax[(LASERLINE_MAX_LEN + LL_BLOCK - 1) / LL_BLOCK];
};

struct peak {
        double centre, strength, width;
        double noise; /* mean |d[x] - d[x-1]| beside the peak (DN) */
};

void laserline_opts_default(struct laserline_opts *o, int channel)
{
        *o = (struct laserline_opts){
                .channel = channel,
                .estimator = LASERLINE_WEIGHTED,
                .min_peak = 0.03,
                .snr = 8,
                .min_width = 1.5,
                .max_width = 8,
                .saturation = 0.98,
                .ambiguity = 0.5,
                .window = 0,
        };
}

/* d = max(on - off, 0) over n pixels step samples apart; STEP is a constant where it helps. */
#define DIFF_LOOP(on, off, step, n, d)                                                             \
        do {                                                                                       \
                if (off)                                                                           \
                        for (int x = 0; x < (n); x++) {                                            \
                                int v_ = (int)(on)[x * (step)] - (int)(off)[x * (step)];           \
                                (d)[x] = (uint16_t)(v_ > 0 ? v_ : 0);                              \
                        }                                                                          \
                else                                                                               \
                        for (int x = 0; x < (n); x++)                                              \
                                (d)[x] = (on)[x * (step)];                                         \
        } while (0)

__attribute__((target_clones("avx2", "default"))) static void
diff8(const uint8_t *on, const uint8_t *off, size_t step, int n, uint16_t *d)
{
        if (step == 3)
                DIFF_LOOP(on, off, 3, n, d);
        else if (step == 1)
                DIFF_LOOP(on, off, 1, n, d);
        else
                DIFF_LOOP(on, off, step, n, d);
}

__attribute__((target_clones("avx2", "default"))) static void
diff16(const uint16_t *on, const uint16_t *off, size_t step, int n, uint16_t *d)
{
        if (step == 3)
                DIFF_LOOP(on, off, 3, n, d);
        else if (step == 1)
                DIFF_LOOP(on, off, 1, n, d);
        else
                DIFF_LOOP(on, off, step, n, d);
}

/* The largest of n contiguous samples (every channel of a row): a bound on the laser channel's
 * peak that reads the row at memory speed. */
__attribute__((target_clones("avx2", "default"))) static unsigned max8(const uint8_t *p, size_t n)
{
        uint8_t m = 0;

        for (size_t i = 0; i < n; i++)
                m = p[i] > m ? p[i] : m;
        return m;
}

__attribute__((target_clones("avx2", "default"))) static unsigned max16(const uint16_t *p, size_t n)
{
        uint16_t m = 0;

        for (size_t i = 0; i < n; i++)
                m = p[i] > m ? p[i] : m;
        return m;
}

/* Block maxima of d (the tail block padded with the last sample). */
__attribute__((target_clones("avx2", "default"))) static void block_maxima(struct line *l)
{
        for (int x = l->n; x < l->nb * LL_BLOCK; x++)
                l->d[x] = l->d[l->n - 1];
        for (int b = 0; b < l->nb; b++) {
                const uint16_t *d = l->d + b * LL_BLOCK;
                uint16_t m = 0;
                for (int i = 0; i < LL_BLOCK; i++)
                        m = d[i] > m ? d[i] : m;
                l->bmax[b] = m;
        }
}

/* Sum of |d[x] - d[x-1]| over LL_NOISE_LEN samples from x, each term at most l->cap so
 * that speckle does not count as noise; 0 where the window leaves the line. */
static uint32_t noise_at(const struct line *l, int x)
{
        uint32_t sad = 0;

        for (int i = x + 1; x >= 0 && x + LL_NOISE_LEN <= l->n && i < x + LL_NOISE_LEN; i++) {
                int a = abs((int)l->d[i] - (int)l->d[i - 1]);
                sad += (uint32_t)(a < l->cap ? a : l->cap);
        }
        return sad;
}

/* The noise beside a peak whose top spans s0..s1: the mean |d[x] - d[x-1]| of the noisier of
 * two windows LL_NOISE_GAP px beyond the top. */
static double noise_beside(const struct line *l, int s0, int s1)
{
        uint32_t lo = noise_at(l, s0 - LL_NOISE_GAP - LL_NOISE_LEN),
                 hi = noise_at(l, s1 + LL_NOISE_GAP);

        return (double)(lo > hi ? lo : hi) / (LL_NOISE_LEN - 1);
}

static int top_block(const struct line *l)
{
        int best = 0;

        for (int b = 1; b < l->nb; b++)
                if (l->bmax[b] > l->bmax[best])
                        best = b;
        return best;
}

static bool tried(const struct line *l, int x)
{
        for (int i = 0; i < l->spans; i++)
                if (x >= l->span_lo[i] && x <= l->span_hi[i])
                        return true;
        return false;
}

/* The highest sample of block b not in a tried span, or -1. */
static int block_argmax(const struct line *l, int b)
{
        int x = -1;

        for (int i = b * LL_BLOCK; l->spans == 0 && i < (b + 1) * LL_BLOCK && i < l->n; i++)
                if (l->d[i] == l->bmax[b]) /* nothing tried yet: the first sample at the maximum */
                        return i;
        for (int i = b * LL_BLOCK; i < (b + 1) * LL_BLOCK && i < l->n; i++)
                if ((x < 0 || l->d[i] > l->d[x]) && !tried(l, i))
                        x = i;
        return x;
}

/* Leaves d[lo..hi] out of the search and updates the maxima of the blocks it touched. */
static void exclude_span(struct line *l, int lo, int hi)
{
        l->span_lo[l->spans] = lo;
        l->span_hi[l->spans++] = hi;
        for (int b = lo / LL_BLOCK; b <= hi / LL_BLOCK; b++) {
                int x = block_argmax(l, b);
                l->bmax[b] = x < 0 ? 0 : l->d[x];
        }
}

static bool clipped(const struct line *l, int x)
{
        size_t i = l->first + (size_t)x * l->step;

        return (l->on8 ? l->on8[i] : l->on16[i]) >= l->sat;
}

/* From x, follows d down (non-increasing) towards dir for at most lim px: the foot. */
static int descend(const struct line *l, int x, int dir, int lim)
{
        for (int k = 0; k < lim; k++) {
                int nx = x + dir;
                if (nx < 0 || nx >= l->n || l->d[nx] > l->d[x])
                        break;
                x = nx;
        }
        return x;
}

/* Where d, walking from x towards foot, first falls below level (linear interpolation). */
static double crossing(const struct line *l, int x, int foot, double level)
{
        int dir = foot < x ? -1 : 1;

        for (; x != foot && l->d[x + dir] >= level; x += dir)
                ;
        if (x == foot)
                return x;
        return x + dir * (l->d[x] - level) / (l->d[x] - l->d[x + dir]);
}

/* The baseline under x: linear between the feet. */
static void baseline(const struct line *l, int lo, int hi, double *b0, double *slope)
{
        *slope = hi > lo ? (double)(l->d[hi] - l->d[lo]) / (hi - lo) : 0;
        *b0 = l->d[lo] - *slope * lo;
}

static double base_at(const struct line *l, int lo, int hi, double x)
{
        double b0, slope;

        baseline(l, lo, hi, &b0, &slope);
        return b0 + slope * x;
}

static double centre_com(const struct line *l, int x, int w, int lo, int hi)
{
        double s = 0, sx = 0, b0, slope;

        baseline(l, lo, hi, &b0, &slope);
        for (int u = x - w < 0 ? 0 : x - w; u <= x + w && u < l->n; u++) {
                double v = l->d[u] - b0 - slope * u;
                if (v > 0) {
                        s += v;
                        sx += v * u;
                }
        }
        return s > 0 ? sx / s : x;
}

/* Refines c, the centre of a line of width (at half height) fwhm, by a centroid weighted with a
 * triweight kernel (1 - t^2)^3, t = (u - c) / (3 sigma_k), close to a Gaussian of sigma_k =
 * LL_KERNEL times the line's: a matched filter, so that the samples far from the centre, where
 * there is noise but little line, weigh little. The weighted centroid of a Gaussian line lies
 * sigma_k^2 / (sigma^2 + sigma_k^2) of the way from c to the line's centre: each step is scaled
 * up by the inverse. A symmetric kernel on a symmetric line is unbiased at the fixed point.
 * Keeps c if a step would leave the line (no signal under the kernel). */
static double centre_weighted(const struct line *l, double c, double fwhm, int lo, int hi)
{
        double sigma = fwhm / 2.3548, kernel = fmax(LL_KERNEL * sigma, LL_KERNEL_MIN);
        double reach = 3 * kernel, gain = 1 + sigma * sigma / (kernel * kernel);
        double r2 = 1 / (reach * reach), b0, slope;

        baseline(l, lo, hi, &b0, &slope);
        for (int k = 0; k < LL_REFINE; k++) {
                double s = 0, su = 0, step;
                int u0 = (int)ceil(c - reach), u1 = (int)floor(c + reach);
                for (int u = u0 < 0 ? 0 : u0; u <= u1 && u < l->n; u++) {
                        double t = 1 - (u - c) * (u - c) * r2;
                        double v = t * t * t * (l->d[u] - b0 - slope * u);
                        s += v;
                        su += v * (u - c);
                }
                step = s > 0 ? gain * su / s : INFINITY;
                if (!(fabs(step) < fwhm / 2))
                        break;
                c += step;
        }
        return c;
}

/* Sub-pixel centre of the unclipped peak p whose top sample is x (0 < x < n - 1); w: the centre
 * of mass's half window. LASERLINE_WEIGHTED: the centre of mass where the noise beside the peak
 * is low, else the weighted centroid. */
static double centre_of(const struct line *l, const struct laserline_opts *o, int x, int w,
                        const struct peak *p, int lo, int hi)
{
        double b = base_at(l, lo, hi, x);
        double a = l->d[x - 1] - b, m = l->d[x] - b, c = l->d[x + 1] - b, den;

        if (o->estimator == LASERLINE_COM ||
            (o->estimator == LASERLINE_WEIGHTED && p->noise * LL_NOISY < p->strength))
                return centre_com(l, x, w, lo, hi);
        if (o->estimator == LASERLINE_GAUSS3 && a > 0 && c > 0) {
                den = log(a) - 2 * log(m) + log(c);
                if (den < 0)
                        return x + 0.5 * (log(a) - log(c)) / den;
        }
        den = a - 2 * m + c;
        b = den < 0 ? x + 0.5 * (a - c) / den : x; /* the parabola */
        return o->estimator == LASERLINE_WEIGHTED ? centre_weighted(l, b, p->width, lo, hi) : b;
}

/* Measures the candidate whose top sample is x: *lo, *hi get its feet. Returns whether it is
 * a plausible line (height, width, not at the border), filling p. */
static bool peak_eval(const struct line *l, const struct laserline_opts *o, int x, struct peak *p,
                      int *lo, int *hi)
{
        int lim = (int)ceil(o->max_width), s0 = x, s1 = x, mid;
        bool clip = clipped(l, x);
        double base, level, left, right;

        while (clip && s0 > 0 && clipped(l, s0 - 1))
                s0--;
        while (clip && s1 < l->n - 1 && clipped(l, s1 + 1))
                s1++;
        *lo = descend(l, s0, -1, lim);
        *hi = descend(l, s1, 1, lim);
        base = l->d[*lo] > l->d[*hi] ? l->d[*lo] : l->d[*hi];
        p->strength = l->d[x] - base;
        level = base + p->strength / 2;
        left = crossing(l, s0, *lo, level);
        right = crossing(l, s1, *hi, level);
        p->width = right - left;
        p->noise = noise_beside(l, s0, s1);
        if (p->strength < fmax(l->floor, o->snr * p->noise) || p->width < o->min_width ||
            p->width > o->max_width || s0 == 0 || s1 == l->n - 1)
                return false;
        mid = (s0 + s1) / 2; /* clipped: the run and its flanks, symmetric about the centre */
        if (clip)
                p->centre =
                        centre_com(l, mid, mid - *lo > *hi - mid ? mid - *lo : *hi - mid, *lo, *hi);
        else
                p->centre =
                        centre_of(l, o, x, o->window > 0 ? o->window : (int)ceil(1.3 * p->width), p,
                                  *lo, *hi);
        return true;
}

/* The line's peak in l->d, or false (no plausible peak, or two: *ambiguous set). */
static bool line_peak(struct line *l, const struct laserline_opts *o, struct peak *best,
                      bool *ambiguous)
{
        bool have = false;
        struct peak p = {0};

        *ambiguous = false;
        l->spans = 0;
        for (int k = 0; k < LL_CANDIDATES; k++) {
                int b = top_block(l), x, lo, hi;
                bool ok;

                if (l->bmax[b] < (have ? o->ambiguity * best->strength : l->floor))
                        break;
                x = block_argmax(l, b);
                if (x < 0)
                        break;
                ok = peak_eval(l, o, x, &p, &lo, &hi);
                exclude_span(l, lo, hi);
                if (ok && have && p.strength >= o->ambiguity * best->strength) {
                        *ambiguous = true;
                        return false;
                }
                if (ok && !have) {
                        *best = p;
                        have = true;
                }
        }
        return have;
}

static int check_args(const struct gn_frame *on, const struct gn_frame *off,
                      const struct laserline_opts *o, const struct laserline_result *out)
{
        int lines, len;

        if (!on || !o || !out || !on->data || !out->centre)
                return -EINVAL;
        lines = o->columns ? on->width : on->height;
        len = o->columns ? on->height : on->width;
        if ((on->bits != 8 && on->bits != 16) || (on->channels != 1 && on->channels != 3) ||
            o->channel < 0 || o->channel >= on->channels || out->n < lines || len < 3)
                return -EINVAL;
        if (off && (off->width != on->width || off->height != on->height ||
                    off->channels != on->channels || off->bits != on->bits ||
                    off->stride != on->stride || !off->data))
                return -EINVAL;
        return len > LASERLINE_MAX_LEN ? -E2BIG : 0;
}

/* Whether row i of the on frame is too dark for a line (every sample of every channel under
 * the least peak height, so no difference can reach it): such a row is not loaded and its
 * off row never read. */
static bool row_dark(const struct line *l, const struct gn_frame *on, int i)
{
        size_t n = (size_t)on->width * on->channels;

        if (l->on8)
                return max8(on->data + (size_t)i * on->stride, n) < l->floor;
        return max16((const uint16_t *)(on->data + (size_t)i * on->stride), n) < l->floor;
}

/* Loads line i of the frames into l: d and its block maxima. Returns false for a dark row (not
 * loaded: it has no line). */
static bool line_load(struct line *l, const struct gn_frame *on, const struct gn_frame *off,
                      const struct laserline_opts *o, int i)
{
        size_t row = on->stride / (size_t)(on->bits / 8);

        if (off && !o->columns && row_dark(l, on, i))
                return false;
        l->first =
                o->columns ? (size_t)i * on->channels + o->channel : (size_t)i * row + o->channel;
        l->step = o->columns ? row : (size_t)on->channels;
        if (l->on8)
                diff8(l->on8 + l->first, off ? off->data + l->first : NULL, l->step, l->n, l->d);
        else
                diff16(l->on16 + l->first, off ? (const uint16_t *)off->data + l->first : NULL,
                       l->step, l->n, l->d);
        block_maxima(l);
        return true;
}

int laserline_extract(const struct gn_frame *on, const struct gn_frame *off,
                      const struct laserline_opts *o, struct laserline_result *out)
{
        struct line l;
        struct peak p = {0};
        bool amb;
        int r = check_args(on, off, o, out);

        if (r < 0)
                return r;
        l.on8 = on->bits == 8 ? on->data : NULL;
        l.on16 = on->bits == 16 ? (const uint16_t *)on->data : NULL;
        l.n = o->columns ? on->height : on->width;
        l.nb = (l.n + LL_BLOCK - 1) / LL_BLOCK;
        l.sat = (int)ceil(o->saturation * (on->bits == 8 ? 255 : 65535));
        l.floor = o->min_peak * (on->bits == 8 ? 255 : 65535);
        l.cap = (int)ceil(l.floor);
        out->n = o->columns ? on->width : on->height;
        out->points = out->ambiguous = 0;
        for (int i = 0; i < out->n; i++) {
                amb = false;
                bool found = line_load(&l, on, off, o, i) && line_peak(&l, o, &p, &amb);
                out->centre[i] = found ? (float)p.centre : NAN;
                if (out->strength)
                        out->strength[i] = found ? (float)p.strength : 0;
                if (out->width)
                        out->width[i] = found ? (float)p.width : 0;
                out->points += found;
                out->ambiguous += amb;
        }
        return out->points;
}
