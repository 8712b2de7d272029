/* ds_png.h - PNG encoding and decoding of gn_frame images for the dataset store
 * (libspng): 8- or 16-bit, mono (grey) or RGB, lossless.
 *
 * 16-bit samples are in host order in a gn_frame and big-endian in the PNG, as
 * the PNG specification requires; the conversion happens here. */
#pragma once

#include <stddef.h>

#include "common/frame.h"

/* zlib level used by the store unless told otherwise: level 1, the fast codec (see
 * ds_png_codec_of_level). */
#define DS_PNG_LEVEL_DEFAULT 1

/* PNG row filters the encoder may choose from. */
enum ds_png_filter {
        DS_PNG_FILTER_NONE,     /* rows stored as they are */
        DS_PNG_FILTER_SUB,      /* difference to the pixel on the left */
        DS_PNG_FILTER_UP,       /* difference to the pixel above */
        DS_PNG_FILTER_ADAPTIVE, /* the best of the five filters for each row */
};

/* zlib strategies (deflateInit2). */
enum ds_png_strategy {
        DS_PNG_STRATEGY_DEFAULT,  /* string matching and Huffman coding */
        DS_PNG_STRATEGY_FILTERED, /* zlib's tuning for filtered image data */
        DS_PNG_STRATEGY_HUFFMAN,  /* Huffman coding only, no string matching */
        DS_PNG_STRATEGY_RLE,      /* matches of the previous byte only */
};

/* How an image is compressed; every choice is lossless and any PNG reader reads it. */
struct ds_png_codec {
        int level; /* zlib level 0-9, or -1 for zlib's default */
        enum ds_png_filter filter;
        enum ds_png_strategy strategy;
};

/* The codec of a zlib level (docs/dataset.md, "Image codec", measured with bench/pipeline
 * --codecs). 0: rows stored uncompressed. 1: every row filtered with sub, then Z_RLE; on
 * the simulated rig's frames smaller than level 6 with adaptive filters, for a third of
 * the CPU of level 1 with them. 2-9 and -1 (zlib's 6): the best filter of each row and
 * Z_FILTERED, slower; smaller only on smooth (noise-free) images. Other levels give a
 * codec that ds_png_encode_codec refuses. */
struct ds_png_codec ds_png_codec_of_level(int level);

/* Encodes frame (1 or 3 channels, 8 or 16 bits, any stride >= the packed row) as PNG
 * with the codec of zlib level (0-9, or -1 for zlib's default; ds_png_codec_of_level).
 * On success *ret_buf is a malloc'ed buffer of *ret_len bytes that the caller frees.
 * Returns 0, -EINVAL (bad frame or level), -ENOMEM or -EIO (encoder failure). Any thread. */
int ds_png_encode(const struct gn_frame *frame, int level, void **ret_buf, size_t *ret_len);

/* Like ds_png_encode with every compression choice given by codec (bench/pipeline
 * compares them). Returns 0, -EINVAL (bad frame or codec), -ENOMEM or -EIO. Any thread. */
int ds_png_encode_codec(const struct gn_frame *frame, const struct ds_png_codec *codec,
                        void **ret_buf, size_t *ret_len);

/* Decodes a PNG held in memory into out (allocated with gn_frame_alloc; the caller
 * frees it with gn_frame_free_data). Accepts greyscale and RGB, 8 or 16 bits, without
 * alpha. Returns 0, -EBADMSG (not a valid PNG), -EOPNOTSUPP (other colour types or
 * depths) or -ENOMEM. Any thread. */
int ds_png_decode(const void *buf, size_t len, struct gn_frame *out);
