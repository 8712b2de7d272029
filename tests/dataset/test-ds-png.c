/* test-ds-png.c - the PNG codec of the dataset store: every codec choice (level, row
 * filter, zlib strategy) round-trips 8- and 16-bit, mono and RGB frames with padded rows
 * bit for bit; bad codecs are refused; and the store's level 1 writes what docs/dataset.md
 * says (every row filtered with sub), read back with zlib as any PNG reader would. */
#include <arpa/inet.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "common/cleanup.h"
#include "dataset/ds_png.h"
#include "tests/test.h"

/* A noisy gradient of the given shape, rows padded by 5 bytes. */
static void make_frame(struct gn_frame *f, int w, int h, int channels, int bits)
{
        size_t row = (size_t)w * channels * (bits / 8);
        uint32_t seed = 12345;

        *f = (struct gn_frame){.width = w, .height = h, .channels = channels, .bits = bits};
        f->stride = row + 5;
        f->data = calloc(f->stride, (size_t)h);
        CHECK(f->data);
        for (int y = 0; y < h; y++)
                for (size_t x = 0; x < row; x++) {
                        seed = seed * 1103515245u + 12345u;
                        f->data[(size_t)y * f->stride + x] = (uint8_t)(x + y + (seed >> 29));
                }
}

static void check_roundtrip(const struct gn_frame *f, const struct ds_png_codec *c)
{
        _cleanup_free_ void *png = NULL;
        struct gn_frame back = {};
        size_t len = 0, row = (size_t)f->width * f->channels * (f->bits / 8);

        CHECK_INT(ds_png_encode_codec(f, c, &png, &len), 0);
        CHECK_INT(ds_png_decode(png, len, &back), 0);
        CHECK_INT(back.width, f->width);
        CHECK_INT(back.height, f->height);
        CHECK_INT(back.channels, f->channels);
        CHECK_INT(back.bits, f->bits);
        for (int y = 0; y < f->height; y++)
                CHECK(memcmp(back.data + (size_t)y * back.stride, f->data + (size_t)y * f->stride,
                             row) == 0);
        gn_frame_free_data(&back);
}

static void test_codecs(void)
{
        static const int shapes[][2] = {{1, 8}, {3, 8}, {1, 16}, {3, 16}};
        static const int levels[] = {0, 1, 6, 9, -1};
        struct gn_frame f;

        for (size_t s = 0; s < ELEMENTSOF(shapes); s++) {
                make_frame(&f, 37, 23, shapes[s][0], shapes[s][1]);
                for (size_t l = 0; l < ELEMENTSOF(levels); l++)
                        for (int fl = DS_PNG_FILTER_NONE; fl <= DS_PNG_FILTER_ADAPTIVE; fl++)
                                for (int st = DS_PNG_STRATEGY_DEFAULT; st <= DS_PNG_STRATEGY_RLE;
                                     st++)
                                        check_roundtrip(&f,
                                                        &(struct ds_png_codec){levels[l], fl, st});
                gn_frame_free_data(&f);
        }
}

static void test_refused(void)
{
        static const struct ds_png_codec bad[] = {
                {10, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_RLE},
                {-2, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_RLE},
                {1, DS_PNG_FILTER_ADAPTIVE + 1, DS_PNG_STRATEGY_RLE},
                {1, DS_PNG_FILTER_SUB, DS_PNG_STRATEGY_RLE + 1},
        };
        void *png = NULL;
        size_t len = 0;
        struct gn_frame f;

        make_frame(&f, 8, 8, 1, 8);
        for (size_t i = 0; i < ELEMENTSOF(bad); i++)
                CHECK_INT(ds_png_encode_codec(&f, &bad[i], &png, &len), -EINVAL);
        CHECK_INT(ds_png_encode_codec(&f, NULL, &png, &len), -EINVAL);
        CHECK_INT(ds_png_encode(&f, 10, &png, &len), -EINVAL);
        CHECK(png == NULL);
        gn_frame_free_data(&f);
}

/* The filter byte of every row of png (a w x h image of bpp bytes per pixel), read with
 * zlib from the concatenated IDAT chunks; returns the filter of all rows, or -1 if mixed. */
static int row_filter(const uint8_t *png, size_t len, int w, int h, int bpp)
{
        size_t row = (size_t)w * bpp + 1, n = row * (size_t)h, idat_len = 0;
        _cleanup_free_ uint8_t *idat = malloc(len), *raw = malloc(n);
        uLongf out = n;
        int filter;

        CHECK(idat && raw);
        for (size_t i = 8; i + 12 <= len;) {
                uint32_t clen;

                memcpy(&clen, png + i, 4);
                clen = ntohl(clen);
                if (memcmp(png + i + 4, "IDAT", 4) == 0) {
                        memcpy(idat + idat_len, png + i + 8, clen);
                        idat_len += clen;
                }
                i += 12 + clen;
        }
        CHECK_INT(uncompress(raw, &out, idat, idat_len), Z_OK);
        CHECK_INT(out, n);
        filter = raw[0];
        for (int y = 1; y < h; y++)
                if (raw[(size_t)y * row] != filter)
                        return -1;
        return filter;
}

static void test_store_codec(void)
{
        _cleanup_free_ void *png1 = NULL, *png0 = NULL;
        size_t len1 = 0, len0 = 0;
        struct gn_frame f;
        struct ds_png_codec c = ds_png_codec_of_level(DS_PNG_LEVEL_DEFAULT);

        CHECK_INT(DS_PNG_LEVEL_DEFAULT, 1);
        CHECK_INT(c.filter, DS_PNG_FILTER_SUB);
        CHECK_INT(c.strategy, DS_PNG_STRATEGY_RLE);
        make_frame(&f, 64, 16, 3, 8);
        CHECK_INT(ds_png_encode(&f, 1, &png1, &len1), 0);
        CHECK_INT(row_filter(png1, len1, 64, 16, 3), 1); /* PNG filter type 1: sub */
        CHECK_INT(ds_png_encode(&f, 0, &png0, &len0), 0);
        CHECK_INT(row_filter(png0, len0, 64, 16, 3), 0); /* none */
        CHECK(len0 > (size_t)64 * 16 * 3);               /* stored: not compressed */
        CHECK(len1 < len0);
        gn_frame_free_data(&f);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"codecs", test_codecs},
                {"refused", test_refused},
                {"store-codec", test_store_codec},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
