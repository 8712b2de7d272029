/* ds_png.c - PNG encode/decode of gn_frame images with libspng (see ds_png.h). */
#include <errno.h>
#include <spng.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <zlib.h>

#include "common/cleanup.h"
#include "ds_png.h"

/* Largest image accepted by the decoder, the same bound as gn_frame_alloc(). */
#define PNG_MAX_DIM   16384
#define PNG_MAX_CHUNK (64u << 20)

DEFINE_TRIVIAL_CLEANUP_FUNC(spng_ctx *, spng_ctx_free);

static size_t packed_row(const struct gn_frame *f)
{
        return (size_t)f->width * f->channels * (f->bits / 8);
}

static bool frame_valid(const struct gn_frame *f)
{
        return f && f->data && f->width > 0 && f->height > 0 && f->width <= PNG_MAX_DIM &&
               f->height <= PNG_MAX_DIM && (f->channels == 1 || f->channels == 3) &&
               (f->bits == 8 || f->bits == 16) && f->stride >= packed_row(f);
}

static int spng_to_errno(int r)
{
        return r == SPNG_EMEM ? -ENOMEM : -EIO;
}

static int encode_setup(spng_ctx *ctx, const struct gn_frame *f, const struct ds_png_codec *c)
{
        static const int filters[] = {
                [DS_PNG_FILTER_NONE] = SPNG_FILTER_CHOICE_NONE,
                [DS_PNG_FILTER_SUB] = SPNG_FILTER_CHOICE_SUB,
                [DS_PNG_FILTER_UP] = SPNG_FILTER_CHOICE_UP,
                [DS_PNG_FILTER_ADAPTIVE] = SPNG_FILTER_CHOICE_ALL,
        };
        static const int strategies[] = {
                [DS_PNG_STRATEGY_DEFAULT] = Z_DEFAULT_STRATEGY,
                [DS_PNG_STRATEGY_FILTERED] = Z_FILTERED,
                [DS_PNG_STRATEGY_HUFFMAN] = Z_HUFFMAN_ONLY,
                [DS_PNG_STRATEGY_RLE] = Z_RLE,
        };
        struct spng_ihdr ihdr = {
                .width = (uint32_t)f->width,
                .height = (uint32_t)f->height,
                .bit_depth = (uint8_t)f->bits,
                .color_type =
                        f->channels == 3 ? SPNG_COLOR_TYPE_TRUECOLOR : SPNG_COLOR_TYPE_GRAYSCALE,
        };
        int r;

        r = spng_set_ihdr(ctx, &ihdr);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_ENCODE_TO_BUFFER, 1);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_IMG_COMPRESSION_LEVEL, c->level);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_FILTER_CHOICE, filters[c->filter]);
        if (r == 0)
                r = spng_set_option(ctx, SPNG_IMG_COMPRESSION_STRATEGY, strategies[c->strategy]);
        if (r == 0)
                r = spng_encode_image(ctx, NULL, 0, SPNG_FMT_PNG,
                                      SPNG_ENCODE_PROGRESSIVE | SPNG_ENCODE_FINALIZE);
        return r;
}

static bool codec_valid(const struct ds_png_codec *c)
{
        return c && c->level >= -1 && c->level <= 9 && c->filter >= DS_PNG_FILTER_NONE &&
               c->filter <= DS_PNG_FILTER_ADAPTIVE && c->strategy >= DS_PNG_STRATEGY_DEFAULT &&
               c->strategy <= DS_PNG_STRATEGY_RLE;
}

int ds_png_encode_codec(const struct gn_frame *frame, const struct ds_png_codec *codec,
                        void **ret_buf, size_t *ret_len)
{
        _cleanup_(spng_ctx_freep) spng_ctx *ctx = NULL;
        size_t row = 0, len = 0;
        void *buf;
        int r;

        if (!frame_valid(frame) || !codec_valid(codec) || !ret_buf || !ret_len)
                return -EINVAL;
        ctx = spng_ctx_new(SPNG_CTX_ENCODER);
        if (!ctx)
                return -ENOMEM;
        r = encode_setup(ctx, frame, codec);
        if (r != 0)
                return spng_to_errno(r);

        /* spng swaps 16-bit host-order samples to big-endian for SPNG_FMT_PNG. */
        row = packed_row(frame);
        for (int y = 0; y < frame->height; y++) {
                r = spng_encode_row(ctx, frame->data + (size_t)y * frame->stride, row);
                if (r != 0 && !(r == SPNG_EOI && y == frame->height - 1))
                        return spng_to_errno(r);
        }

        buf = spng_get_png_buffer(ctx, &len, &r);
        if (!buf)
                return spng_to_errno(r);
        *ret_buf = buf;
        *ret_len = len;
        return 0;
}

struct ds_png_codec ds_png_codec_of_level(int level)
{
        if (level == 0)
                return (struct ds_png_codec){0, DS_PNG_FILTER_NONE, DS_PNG_STRATEGY_DEFAULT};
        if (level == 1)
                return (struct ds_png_codec){1, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_RLE};
        return (struct ds_png_codec){level, DS_PNG_FILTER_ADAPTIVE, DS_PNG_STRATEGY_FILTERED};
}

int ds_png_encode(const struct gn_frame *frame, int level, void **ret_buf, size_t *ret_len)
{
        struct ds_png_codec c = ds_png_codec_of_level(level);

        return ds_png_encode_codec(frame, &c, ret_buf, ret_len);
}

static int channels_of(const struct spng_ihdr *ihdr)
{
        if (ihdr->bit_depth != 8 && ihdr->bit_depth != 16)
                return -EOPNOTSUPP;
        if (ihdr->color_type == SPNG_COLOR_TYPE_GRAYSCALE)
                return 1;
        if (ihdr->color_type == SPNG_COLOR_TYPE_TRUECOLOR)
                return 3;
        return -EOPNOTSUPP;
}

int ds_png_decode(const void *buf, size_t len, struct gn_frame *out)
{
        _cleanup_(spng_ctx_freep) spng_ctx *ctx = NULL;
        struct spng_ihdr ihdr;
        struct gn_frame f = {};
        int r, channels;

        if (!buf || !out)
                return -EINVAL;
        ctx = spng_ctx_new(0);
        if (!ctx)
                return -ENOMEM;
        if (spng_set_image_limits(ctx, PNG_MAX_DIM, PNG_MAX_DIM) != 0 ||
            spng_set_chunk_limits(ctx, PNG_MAX_CHUNK, PNG_MAX_CHUNK) != 0 ||
            spng_set_png_buffer(ctx, buf, len) != 0)
                return -ENOMEM;
        if (spng_get_ihdr(ctx, &ihdr) != 0)
                return -EBADMSG;
        channels = channels_of(&ihdr);
        if (channels < 0)
                return channels;

        r = gn_frame_alloc(&f, (int)ihdr.width, (int)ihdr.height, channels, ihdr.bit_depth);
        if (r < 0)
                return r;
        /* SPNG_FMT_PNG: the PNG's own layout with 16-bit samples in host order. */
        r = spng_decode_image(ctx, f.data, gn_frame_bytes(&f), SPNG_FMT_PNG, 0);
        if (r != 0) {
                gn_frame_free_data(&f);
                return r == SPNG_EMEM ? -ENOMEM : -EBADMSG;
        }
        *out = f;
        return 0;
}
