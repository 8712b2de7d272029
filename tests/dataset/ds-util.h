/* ds-util.h - helpers shared by the dataset store tests: scratch directories,
 * synthetic frames, captures and file counting. */
#pragma once

#include <stdbool.h>

#include "common/frame.h"
#include "dataset/ds.h"

/* A new empty directory under $TMPDIR or /tmp; exits on failure. Free the string. */
char *tu_tmpdir(void);

/* Removes path and everything below it (no symlinks followed). */
void tu_rm_rf(const char *path);

/* Allocates a w x h frame filled with seeded noise over the full sample range. With
 * pad, rows carry 7 extra bytes (stride > packed row). Exits on failure. */
void tu_frame(struct gn_frame *f, int w, int h, int channels, int bits, unsigned seed, bool pad);

/* True if both frames have the same shape and pixels (padding ignored). */
bool tu_frames_equal(const struct gn_frame *a, const struct gn_frame *b);

/* Fills c with a plausible capture of camera and lamps, pose derived from i. */
void tu_capture(struct ds_capture *c, const char *camera, const char *lamps, int i);

/* Number of entries of dir whose name ends with suffix ("" for all but . and ..). */
int tu_count(const char *dir, const char *suffix);

/* Number of files ending in ".tmp" anywhere in the dataset dir (top and images/). */
int tu_count_tmp(const char *dataset);
