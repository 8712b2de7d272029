/* frame.c - allocation helpers for struct gn_frame. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"

int gn_frame_alloc(struct gn_frame *f, int width, int height, int channels, int bits)
{
        if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
                return -EINVAL;
        if ((channels != 1 && channels != 3) || (bits != 8 && bits != 16))
                return -EINVAL;
        memset(f, 0, sizeof(*f));
        f->width = width;
        f->height = height;
        f->channels = channels;
        f->bits = bits;
        f->stride = (size_t)width * channels * (bits / 8);
        f->data = calloc(f->stride, height);
        return f->data ? 0 : -ENOMEM;
}

void gn_frame_free_data(struct gn_frame *f)
{
        free(f->data);
        memset(f, 0, sizeof(*f));
}

const char *gn_frame_format(const struct gn_frame *f)
{
        if (f->channels == 1)
                return f->bits == 16 ? "mono16" : "mono8";
        return f->bits == 16 ? "rgb16" : "rgb8";
}
