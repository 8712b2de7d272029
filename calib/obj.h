/* obj.h - the scan's mesh (calib/mesh.h) as a Wavefront OBJ file: v x y z r g b (mm, object
 * frame; the colour as the common vertex-colour extension, 0 to 1), vn, and f v//vn with
 * 1-based indices, counter-clockwise seen from outside; written atomically
 * (common/fileio). docs/scanning.md, "The mesh". */
#pragma once

#include "calib/mesh.h"

/* Writes mesh m to dir_fd/name (dir_fd may be AT_FDCWD) atomically, replacing any file
 * there. Returns 0, -ENOMEM or the -errno of gn_write_atomic. */
int obj_write_mesh(int dir_fd, const char *name, const struct cal_mesh *m);
