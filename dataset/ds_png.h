/* ds_png.h - PNG encoding and decoding of gn_frame images for the dataset store
 * (libspng): 8- or 16-bit, mono (grey) or RGB, lossless.
 *
 * 16-bit samples are in host order in a gn_frame and big-endian in the PNG, as
 * the PNG specification requires; the conversion happens here. */
#pragma once

#include <stddef.h>

#include "common/frame.h"

/* zlib level used by the store unless told otherwise: level 1 encodes noisy camera
 * images about twice as fast as level 6 for a few percent more bytes. */
#define DS_PNG_LEVEL_DEFAULT 1

/* Encodes frame (1 or 3 channels, 8 or 16 bits, any stride >= the packed row) as PNG
 * with zlib compression level (0-9, or -1 for zlib's default). On success *ret_buf
 * is a malloc'ed buffer of *ret_len bytes that the caller frees. Returns 0, -EINVAL
 * (bad frame or level), -ENOMEM or -EIO (encoder failure). Any thread. */
int ds_png_encode(const struct gn_frame *frame, int level, void **ret_buf, size_t *ret_len);

/* Decodes a PNG held in memory into out (allocated with gn_frame_alloc; the caller
 * frees it with gn_frame_free_data). Accepts greyscale and RGB, 8 or 16 bits, without
 * alpha. Returns 0, -EBADMSG (not a valid PNG), -EOPNOTSUPP (other colour types or
 * depths) or -ENOMEM. Any thread. */
int ds_png_decode(const void *buf, size_t len, struct gn_frame *out);
