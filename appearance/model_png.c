/* model_png.c - the weight and mask images of a model's views with libspng (model_png.h). */
#include <errno.h>
#include <spng.h>
#include <stdio.h>
#include <stdlib.h>
#include <zlib.h>

#include "appearance/model_png.h"
#include "common/cleanup.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(spng_ctx *, spng_ctx_free);

int ap_png_encode(int width, int height, int channels, const uint16_t *u16, const uint8_t *u8,
                  void **buf, size_t *len)
{
        _cleanup_(spng_ctx_freep) spng_ctx *ctx = spng_ctx_new(SPNG_CTX_ENCODER);
        struct spng_ihdr ihdr = {
                .width = (uint32_t)width,
                .height = (uint32_t)height,
                .bit_depth = channels == 4 ? 16 : 8,
                .color_type = channels == 4   ? SPNG_COLOR_TYPE_TRUECOLOR_ALPHA
                              : channels == 3 ? SPNG_COLOR_TYPE_TRUECOLOR
                                              : SPNG_COLOR_TYPE_GRAYSCALE,
        };
        const void *img = channels == 4 ? (const void *)u16 : (const void *)u8;
        size_t bytes = (size_t)width * height * (channels == 4 ? 8 : (size_t)channels);
        int r;

        if (!ctx)
                return -ENOMEM;
        r = spng_set_ihdr(ctx, &ihdr);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_ENCODE_TO_BUFFER, 1);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_IMG_COMPRESSION_LEVEL, 1);
        /* one filter (up) and run-length coding: a fifth of the time of trying every filter
         * per row with deflate's matching, files no larger (a model's weights, bench/fit) */
        if (r == 0)
                r = spng_set_option(ctx, SPNG_FILTER_CHOICE, SPNG_FILTER_CHOICE_UP);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_IMG_COMPRESSION_STRATEGY, Z_RLE);
        /* SPNG_FMT_PNG: 16-bit samples in host order, swapped to big-endian by spng */
        if (r == 0)
                r = spng_encode_image(ctx, img, bytes, SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE);
        if (r == 0)
                *buf = spng_get_png_buffer(ctx, len, &r);
        if (r != 0)
                return r == SPNG_EMEM ? -ENOMEM : -EIO;
        return 0;
}

int ap_png_decode(const void *buf, size_t len, int width, int height, uint16_t *u16, uint8_t *u8,
                  char *err, size_t errlen)
{
        _cleanup_(spng_ctx_freep) spng_ctx *ctx = spng_ctx_new(0);
        int fmt = u16 ? SPNG_FMT_RGBA16 : SPNG_FMT_G8;
        size_t bytes = (size_t)width * height * (u16 ? 8 : 1);
        struct spng_ihdr ihdr;
        int r;

        if (!ctx || spng_set_png_buffer(ctx, buf, len) != 0)
                return -ENOMEM;
        if (spng_get_ihdr(ctx, &ihdr) != 0) {
                snprintf(err, errlen, "not a PNG image");
                return -EBADMSG;
        }
        if ((int)ihdr.width != width || (int)ihdr.height != height ||
            ihdr.color_type !=
                    (u16 ? SPNG_COLOR_TYPE_TRUECOLOR_ALPHA : SPNG_COLOR_TYPE_GRAYSCALE) ||
            ihdr.bit_depth != (u16 ? 16 : 8)) {
                snprintf(err, errlen, "%ux%u, colour type %u, %u bits, expected %dx%d %s",
                         ihdr.width, ihdr.height, ihdr.color_type, ihdr.bit_depth, width, height,
                         u16 ? "RGBA 16 bits" : "grey 8 bits");
                return -EBADMSG;
        }
        r = spng_decode_image(ctx, u16 ? (void *)u16 : (void *)u8, bytes, fmt, 0);
        if (r != 0) {
                snprintf(err, errlen, "corrupt PNG data: %s", spng_strerror(r));
                return r == SPNG_EMEM ? -ENOMEM : -EBADMSG;
        }
        return 0;
}
