/* ds-util.h - helpers shared by the dataset store tests: scratch directories,
 * synthetic frames, captures and file counting. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

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

/* Turns the index of the closed dataset at path into the first schema (angles NOT NULL,
 * no lamp_bits, no names table, user_version 0), keeping no rows, then runs extra_sql
 * (may be NULL) on it. Exits on failure. */
void tu_make_schema1(const char *path, const char *extra_sql);

/* Number of files ending in ".tmp" anywhere in the dataset dir (top and images/). */
int tu_count_tmp(const char *dataset);

/* Runs sql on the index of the dataset at path with a second connection; exits on
 * failure. */
void tu_sql(const char *path, const char *sql);

/* The first column of the first row of a query on the index of the dataset at path;
 * exits on failure. */
int64_t tu_sql_int(const char *path, const char *sql);

/* Turns the index of the closed dataset at path into schema 3 (no session columns, no
 * sessions or plan tables, user_version 3), keeping its rows. Exits on failure. */
void tu_make_schema3(const char *path);
