/* ply.h - the scanned point cloud (calib/section.h) as a binary little-endian PLY file:
 * vertex x y z nx ny nz (float32, mm, object frame) and red green blue (uchar), written
 * atomically (common/fileio). docs/scanning.md, "Triangulation". */
#pragma once

#include <stddef.h>

#include "calib/section.h"

/* Writes the n points p to dir_fd/name (dir_fd may be AT_FDCWD) atomically, replacing any
 * file there. Returns 0, -ENOMEM or the -errno of gn_write_atomic. */
int ply_write_points(int dir_fd, const char *name, const struct sec_point *p, size_t n);
