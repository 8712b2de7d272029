/* frame.h - an image as captured: pixels plus what was actually applied.
 *
 * Shared by camera backends, the dataset store and gonio-sim. Pixels are
 * interleaved, rows top to bottom, 16-bit samples in host byte order. */
#pragma once

#include <stddef.h>
#include <stdint.h>

struct gn_frame {
        int width, height;
        int channels;          /* 1 (mono) or 3 (RGB) */
        int bits;              /* 8 or 16 */
        size_t stride;         /* bytes per row */
        uint8_t *data;         /* owned; freed by gn_frame_free_data */
        uint64_t timestamp_ns; /* CLOCK_REALTIME at exposure start */
        int exposure_us;       /* applied */
        double gain;           /* applied */
        uint64_t seq;          /* frame counter of the source */
};

/* Allocates zeroed pixel storage for the given shape. Returns 0 or -ENOMEM/-EINVAL. */
int gn_frame_alloc(struct gn_frame *f, int width, int height, int channels, int bits);

/* Frees the pixels and zeroes the struct. Safe on a zeroed frame. */
void gn_frame_free_data(struct gn_frame *f);

/* Size of the pixel data in bytes. */
static inline size_t gn_frame_bytes(const struct gn_frame *f)
{
        return f->stride * (size_t)f->height;
}

/* "mono8", "rgb8", "mono16" or "rgb16". */
const char *gn_frame_format(const struct gn_frame *f);
