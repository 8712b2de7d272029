/* lltest.h - a rendered scene for the laser line tests and bench: the laser on a uniform
 * plate, a ball that hides part of the line from the camera, an optional lamp; the
 * analytic line centre per row and which rows must have a point and which none. */
#pragma once

#include <stdbool.h>

#include "calib/laserline.h"
#include "tests/render/rtest.h"

enum ll_row {
        LL_VISIBLE, /* the line crosses the row on the plate, seen: a point within the RMS */
        LL_GAP,     /* no laser light in the row (the ball hides it, or off the plate): none */
        LL_EDGE,    /* the ball's silhouette is near the line: not scored */
};

struct llscene {
        struct rtest t;
        int w, h;
        double *u;        /* analytic centre per row (NAN where there is none) */
        enum ll_row *row; /* class of each row */
};

/* Renders (once, for the truth) a w x h camera on the plate lit by a laser of the given
 * power; lamp_intensity 0: no lamp. Exits the test on failure. */
void ll_open(struct llscene *s, int w, int h, double laser_power, double lamp_intensity);

void ll_close(struct llscene *s);

/* Renders a frame (noise on) with the laser and the lamp as given, 8 or 16 bits. */
void ll_render(struct llscene *s, bool laser, bool lamp, int bits, uint64_t seq,
               struct gn_frame *f);

/* Scores r against the analytic line: returns the RMS error (px) over the visible rows with
 * a point; counts the visible rows, the visible rows without a point (missed) and the
 * points on gap rows or more than 1 px off the line (spurious). */
double ll_score(const struct llscene *s, const struct laserline_result *r, int *visible,
                int *missed, int *spurious);
