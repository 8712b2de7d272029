/* texture.c - image textures for materials: PNG (8 or 16 bit, any colour type) read with
 * libspng into linear float (sRGB decoded for colour maps), bilinear lookup with wrap; the
 * dome's environment map, PNG (linear) or PFM (common/pfm.h). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <spng.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/pfm.h"
#include "internal.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(spng_ctx *, spng_ctx_free);

static float srgb_to_linear(float c)
{
        return c <= 0.04045f ? c / 12.92f : powf((c + 0.055f) / 1.055f, 2.4f);
}

static int decode(FILE *f, struct rtex *t, bool srgb)
{
        _cleanup_(spng_ctx_freep) spng_ctx *ctx = spng_ctx_new(0);
        _cleanup_free_ uint16_t *buf = NULL;
        struct spng_ihdr ih;
        size_t n;

        if (!ctx || spng_set_png_file(ctx, f) || spng_get_ihdr(ctx, &ih))
                return -EBADMSG;
        if (ih.width > 16384 || ih.height > 16384)
                return -EFBIG;
        if (spng_decoded_image_size(ctx, SPNG_FMT_RGBA16, &n))
                return -EBADMSG;
        buf = malloc(n);
        t->px = malloc((size_t)ih.width * ih.height * 3 * sizeof(float));
        if (!buf || !t->px)
                return -ENOMEM;
        if (spng_decode_image(ctx, buf, n, SPNG_FMT_RGBA16, SPNG_DECODE_TRNS))
                return -EBADMSG;
        t->w = (int)ih.width;
        t->h = (int)ih.height;
        t->channels = 3;
        for (size_t i = 0; i < (size_t)t->w * t->h; i++)
                for (int c = 0; c < 3; c++) {
                        float v = buf[i * 4 + c] / 65535.0f;
                        t->px[i * 3 + c] = srgb ? srgb_to_linear(v) : v;
                }
        return 0;
}

int rtex_load_png(const char *path, bool srgb, struct rtex **ret)
{
        _cleanup_fclose_ FILE *f = fopen(path, "rb");
        struct rtex *t;
        int r;

        if (!f)
                return -errno;
        t = calloc(1, sizeof(*t));
        if (!t)
                return -ENOMEM;
        r = decode(f, t, srgb);
        if (r < 0) {
                rtex_free(t);
                return r;
        }
        *ret = t;
        return 0;
}

int rtex_load_env(const char *path, struct rtex **ret)
{
        _cleanup_free_ void *buf = NULL;
        struct rtex *t;
        size_t len;
        int r;

        r = gn_read_file_at(AT_FDCWD, path, (size_t)1 << 31, &buf, &len);
        if (r < 0)
                return r;
        if (len < 2 || memcmp(buf, "P", 1))
                return rtex_load_png(path, false, ret);
        t = calloc(1, sizeof(*t));
        if (!t)
                return -ENOMEM;
        t->channels = 3;
        r = gn_pfm_decode(buf, len, 16384, &t->px, &t->w, &t->h);
        if (r < 0) {
                rtex_free(t);
                return r;
        }
        *ret = t;
        return 0;
}

struct rtex *rtex_free(struct rtex *t)
{
        if (t)
                free(t->px);
        free(t);
        return NULL;
}

static int wrap(int i, int n)
{
        i %= n;
        return i < 0 ? i + n : i;
}

void rtex_sample(const struct rtex *t, float u, float v, float out[3])
{
        float x = u * t->w - 0.5f, y = (1 - v) * t->h - 0.5f; /* v up, rows top down */
        float fx = floorf(x), fy = floorf(y), ax = x - fx, ay = y - fy;
        int x0 = wrap((int)fx, t->w), y0 = wrap((int)fy, t->h);
        int x1 = wrap(x0 + 1, t->w), y1 = wrap(y0 + 1, t->h);
        const float *p00 = t->px + 3 * ((size_t)y0 * t->w + x0);
        const float *p01 = t->px + 3 * ((size_t)y0 * t->w + x1);
        const float *p10 = t->px + 3 * ((size_t)y1 * t->w + x0);
        const float *p11 = t->px + 3 * ((size_t)y1 * t->w + x1);

        for (int c = 0; c < 3; c++)
                out[c] = (1 - ay) * ((1 - ax) * p00[c] + ax * p01[c]) +
                         ay * ((1 - ax) * p10[c] + ax * p11[c]);
}
