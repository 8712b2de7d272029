/* mesh.h - the object's shape for projective texture mapping (render.h): the dataset's
 * scanned mesh (calib/scan.h writes SCAN_FILE_MESH_PLY into the dataset folder) or, where
 * there is none, the true mesh of the simulated rig the dataset was captured with (the
 * scene object of its rig.yaml, sim/render/render.h). */
#pragma once

#include <stddef.h>

#include "appearance/raster.h"
#include "common/rigconf.h"

#define AP_MESH_SPHERE_ROWS 96 /* tessellation of an analytic sphere of the simulator */

/* Loads the mesh of dataset ds_dir into *out (free with ap_mesh_free), oriented
 * (ap_mesh_orient), and names where it came from in src ("scan PATH" or "simulator RIG"). backends
 * parse the rig file's device maps (drivers/registry.h's registry_backends). Returns 0, -ENOENT (no
 * mesh.ply and no rig.yaml, or a rig whose scene has no object) or -errno, with the cause in err.
 */
int ap_mesh_for_dataset(const char *ds_dir, const struct rig_backend *const *backends,
                        struct ap_mesh *out, char *src, size_t srclen, char *err, size_t errlen);

/* Simplifies m to about target triangles (meshoptimizer: edge collapses, then a sloppy pass
 * if those stop short), its vertices compacted, then oriented again (ap_mesh_orient); a
 * closed mesh is first wound counter-clockwise from outside, so that its winding still says
 * out where the simplified one is no longer closed. A mesh of target triangles or fewer is
 * left as it is. Returns 0, -EINVAL (target 0) or -ENOMEM. */
int ap_mesh_simplify(struct ap_mesh *m, size_t target);
