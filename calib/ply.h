/* ply.h - the scan as binary little-endian PLY files: the point cloud (calib/section.h) and
 * the mesh (calib/mesh.h), vertex x y z nx ny nz (float32, mm, object frame) and red green
 * blue (uchar), the mesh's faces as vertex_indices (uchar count, int32 indices); written
 * atomically (common/fileio). docs/scanning.md, "Triangulation" and "The mesh". */
#pragma once

#include <stddef.h>

#include "calib/mesh.h"
#include "calib/section.h"

/* Writes the n points p to dir_fd/name (dir_fd may be AT_FDCWD) atomically, replacing any
 * file there. Returns 0, -ENOMEM or the -errno of gn_write_atomic. */
int ply_write_points(int dir_fd, const char *name, const struct sec_point *p, size_t n);

/* Writes mesh m (its vertices and faces) to dir_fd/name like ply_write_points. Returns 0,
 * -ENOMEM or the -errno of gn_write_atomic. */
int ply_write_mesh(int dir_fd, const char *name, const struct cal_mesh *m);
