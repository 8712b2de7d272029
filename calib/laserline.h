/* laserline.h - the laser line in a camera frame: a sub-pixel centre per image row (or
 * column), from a laser-on frame minus a laser-off frame, or from one frame in a dark room.
 *
 * Plain C, one pass over each row, no allocation: the caller owns the result arrays. Pure
 * (no devices, no global state): safe to call from several threads on distinct results.
 * Estimators, options and measured accuracy: docs/scanning.md. */
#pragma once

#include <stdbool.h>

#include "common/frame.h"

/* Longest row (or column) laserline_extract() accepts, in pixels. */
#define LASERLINE_MAX_LEN 8192

/* Sub-pixel estimator of the centre of an unsaturated peak. */
enum laserline_estimator {
        LASERLINE_GAUSS3,   /* Gaussian through the top 3 samples (log-parabola) */
        LASERLINE_COM,      /* centre of mass above the local baseline, window of +-window px */
        LASERLINE_PARABOLA, /* parabola through the top 3 samples */
        LASERLINE_WEIGHTED, /* LASERLINE_COM refined by a centroid weighted with a kernel as wide
                             * as the line itself (its sigma from the width at half height) */
};

struct laserline_opts {
        int channel;  /* the laser's channel of an RGB frame (rig laser `channel`); mono: 0 */
        bool columns; /* a centre per column instead of per row */
        enum laserline_estimator estimator;
        double min_peak;   /* least peak height above the local baseline, fraction of full scale */
        double snr;        /* least peak height in units of the noise (mean |d[x]-d[x-1]|) nearby */
        double min_width;  /* plausible full width at half maximum, px: narrower is speckle */
        double max_width;  /*   wider is ambient light or a blur, not the line */
        double saturation; /* an on-frame sample at or above this fraction of full scale is clipped
                            */
        double ambiguity;  /* a second plausible peak this fraction as high rejects the row */
        int window; /* LASERLINE_COM (and LASERLINE_WEIGHTED's first estimate) half window, px;
                     * 0: 1.3 x the width at half height (3 sigma) */
};

/* Per row (or column) results, arrays owned by the caller, each of n elements. */
struct laserline_result {
        float *centre; /* sub-pixel position along the row, pixel centres at integers; NAN: none */
        float *strength; /* peak height above the local baseline (DN), 0 where none; may be NULL */
        float *width;    /* full width at half maximum (px), 0 where none; may be NULL */
        int n;           /* in: capacity; out: rows (or columns) processed */
        int points;      /* out: rows with a centre */
        int ambiguous;   /* out: rows rejected for two plausible peaks */
};

/* The defaults (docs/scanning.md) for a laser in channel `channel` (0 red, 1 green, 2 blue;
 * rig_config.laser_channel). Never fails. */
void laserline_opts_default(struct laserline_opts *o, int channel);

/* Extracts the line of frame `on` minus frame `off` (negative differences clamped to 0); off
 * NULL: `on` alone, the baseline taken per peak from the row itself. Frames of 8 or 16 bits,
 * 1 or 3 channels, off of the same shape as on. Fills out's arrays for every row (every
 * column with o->columns). Returns the number of points, -EINVAL for a bad argument (shapes
 * that differ, a channel out of range, out->n too small), -E2BIG for a row longer than
 * LASERLINE_MAX_LEN. */
int laserline_extract(const struct gn_frame *on, const struct gn_frame *off,
                      const struct laserline_opts *o, struct laserline_result *out);
