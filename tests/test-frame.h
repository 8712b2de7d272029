/* test-frame.h - statistics of 8-bit frames for tests that compare rendered images. */
#pragma once

#include <math.h>

#include "common/frame.h"

/* Mean of every sample of f (8-bit frames). */
static inline double test_frame_mean(const struct gn_frame *f)
{
        double s = 0.0;

        for (size_t i = 0; i < gn_frame_bytes(f); i++)
                s += f->data[i];
        return s / (double)gn_frame_bytes(f);
}

/* Mean absolute difference of the samples of a and b (same shape, 8-bit). */
static inline double test_frame_mean_abs_diff(const struct gn_frame *a, const struct gn_frame *b)
{
        double s = 0.0;

        for (size_t i = 0; i < gn_frame_bytes(a); i++)
                s += fabs((double)a->data[i] - b->data[i]);
        return s / (double)gn_frame_bytes(a);
}
