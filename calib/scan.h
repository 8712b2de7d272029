/* scan.h - a dataset's laser captures to a point cloud and a mesh, offline: for one camera,
 * each row with one laser on (any of the rig's lasers, each on its own plane), minus the laser-off
 * row of the same view with no lamp lit when there is one (else alone: a dark room), coloured from
 * a lamp-lit row of the same view (else the off frame), in turntable-angle order; the line found
 * (calib/laserline.h), triangulated with a calibration (calib/section.h), meshed and simplified
 * (calib/mesh.h), written into the dataset folder as scan.ply, mesh.ply and mesh.obj. With two or
 * more lasers, their points make one cloud and their grids one mesh, and the summary says how well
 * their surfaces agree (cal_lasers_agreement). Reads through the dataset library only; never
 * touches devices. docs/scanning.md, "Reconstruction from a dataset". */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#include "calib/mesh.h"
#include "calib/section.h"
#include "common/rigconf.h"
#include "dataset/ds.h"

#define SCAN_TRIANGLES_DEFAULT 200000 /* simplification target */
#define SCAN_MAX_ERROR_MM      0.05   /* simplification limit: no face moves farther, mm */

/* The files a scan writes into the dataset folder. */
#define SCAN_FILE_POINTS   "scan.ply"
#define SCAN_FILE_MESH_PLY "mesh.ply"
#define SCAN_FILE_MESH_OBJ "mesh.obj"

/* The calibration a scan triangulates with: the camera (intrinsics, distortion, its
 * world-to-camera pose) and the laser planes in the world (turntable) frame, plane i that of
 * the rig's laser i (rig-file order): a row lit by laser i alone uses plane i. */
struct scan_calib {
        struct sec_camera cam;
        int n_lasers;
        double plane_p[SEC_MAX_LASERS][3], plane_n[SEC_MAX_LASERS][3];
        uint32_t nominal; /* bit i: plane i is the rig file's (no calibration of laser i) */
};

struct scan_opts {
        const char *camera;  /* NULL: the first of the rig's cameras with laser rows */
        size_t triangles;    /* simplification target (faces) */
        double max_error_mm; /* simplification limit */
        bool force;          /* replace scan files already in the dataset folder */
        struct cal_mesh_opts mesh;
};

/* What a scan did. */
struct scan_result {
        char camera[DS_NAME_MAX];
        size_t laser_rows; /* the camera's rows with a laser on */
        size_t used;       /* of those, triangulated (one line each) */
        size_t paired;     /*   with a laser-off frame of the same view (on minus off) */
        size_t textured;   /*   coloured from a lamp-lit frame (else the off frame, or none) */
        size_t no_line;    /*   in which no line was found */
        size_t unreadable; /* skipped: a frame that could not be loaded */
        size_t wrong_size; /* skipped: a frame of another size than the calibrated camera */
        size_t other_view; /* skipped: taken at another camera-arm angle than the first */
        size_t shared;     /* skipped: two or more lasers lit together (which line is whose?),
                            * or a laser the calibration has no plane for */
        int n_lasers;      /* lasers with points */
        size_t laser_points[SEC_MAX_LASERS]; /* points of each laser (rig-file index) */
        /* how well the lasers' surfaces agree (cal_lasers_agreement), with two or more
         * lasers with points: RMS distance (mm) over the matched points; NAN otherwise */
        double agree_rms_mm;
        size_t agree_pairs;
        double agree_offset_mm[SEC_MAX_LASERS]; /* each laser's mean distance from the others */
        size_t points;                          /* in the cloud */
        size_t rejected;  /* line centres without a usable ray (sec_ctx.rejected) */
        size_t unvouched; /* line centres at runs' ends and steps (sec_ctx.unvouched) */
        size_t triangles; /* joined over the grid */
        size_t triangles_simplified;
        double error_mm;  /* the simplification's deviation */
        size_t folds;     /* faces dropped as folds after it (cal_mesh_simplify) */
        int seams_closed; /* 1 when the scan covered the full turn and the mesh closed it */
        double seconds;   /* wall time of the whole reconstruction */
};

/* Fills o with the defaults: camera NULL, SCAN_TRIANGLES_DEFAULT, SCAN_MAX_ERROR_MM, no
 * force, cal_mesh_opts_default. Never fails. */
void scan_opts_default(struct scan_opts *o);

/* Loads the dataset's rig.yaml (the rig it was captured with) into *rc, its device maps
 * parsed by backends (drivers/registry.h's registry_backends). Returns 0 or -errno with
 * the cause in err; free *rc with rigconf_free. */
int scan_load_rig(struct ds *d, const struct rig_backend *const *backends, struct rig_config **rc,
                  char *err, size_t errlen);

/* The nominal calibration of camera `camera` of rig rc with the camera arm at
 * camera_arm_deg (NAN: none): intrinsics from the rig file, the pose of
 * riggeom_camera_pose, each laser's plane through the turntable axis at its azimuth
 * (sec_rig_laser_plane). Returns 0, -ENOENT (no such camera) or -ENODATA (no laser). */
int scan_nominal_calib(const struct rig_config *rc, const char *camera, double camera_arm_deg,
                       struct scan_calib *out);

/* The first half of scan_dataset: triangulates the laser rows of dataset d (o->camera's, or
 * the first camera's with laser rows) into c (sec_init'ed here, with the normals; free with
 * sec_free, also on failure), counting into *out (zeroed first). Returns as scan_dataset,
 * without -EEXIST and the writes' errors. Call from a worker (blocking I/O). */
int scan_section(struct ds *d, const struct rig_config *rc, const struct scan_opts *o,
                 const struct scan_calib *cal, struct sec_ctx *c, struct scan_result *out,
                 char *err, size_t errlen);

/* Reconstructs the scan of dataset d, captured with rig rc (the laser's channel, the camera
 * names; the nominal calibration when cal is NULL), and writes SCAN_FILE_POINTS (the cloud,
 * normals from the grid) and the simplified mesh as SCAN_FILE_MESH_PLY and
 * SCAN_FILE_MESH_OBJ into its folder. Rows that cannot be used are skipped and counted in
 * *out, never fatal. Returns 0 or -errno with the cause in err: -ENODATA (no laser rows of
 * the camera, or no line in any of them), -ENOENT (no such camera), -EEXIST (a scan file
 * there already and not o->force), -EINVAL (a calibration that sec_init refuses), -ENOMEM,
 * or a write's -errno. Call from a worker (blocking I/O). */
int scan_dataset(struct ds *d, const struct rig_config *rc, const struct scan_opts *o,
                 const struct scan_calib *cal, struct scan_result *out, char *err, size_t errlen);
