/* scanrig.h - helpers of the scan tests: a rig rendering one camera (800x600, a strong
 * lens), a red line laser through the turntable axis and a white lamp, frames rendered
 * in-process by gonio-sim's renderer, and scans with the rig file's nominal calibration. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "calib/section.h"
#include "tests/render/rtest.h"

#define ST_W 800
#define ST_H 600

/* Opens the rig around the object mapping object ("{ shape: sphere, size: 100 }"), the
 * camera at elevation_deg looking at (0, 0, target_z). Exits the test on failure. */
void st_open(struct rtest *t, const char *object, double elevation_deg, double target_z);

/* Renders camera c0 at turntable angle deg with the laser on or off and the lamps of bit
 * set lamps lit (noise on, 8 bits) into f; seq seeds the noise. */
void st_render(struct rtest *t, double deg, bool laser, uint32_t lamps, uint64_t seq,
               struct gn_frame *f);

/* Scans n angles over the full turn (laser on minus off, coloured from the lamp frame) into
 * c, started with the rig's nominal calibration (scan_nominal_calib). */
void st_scan(struct rtest *t, int n, struct sec_ctx *c);

/* Signed distance of x (object frame, mm) from the 100 mm sphere on the turntable. */
double st_sphere_dist(const float x[3]);
