/* turntable.h - the turntable axis and one camera's pose in the turntable frame, from views
 * of a board lying on the turntable at several turntable angles (known intrinsics): a
 * solvePnP per view, a plane and circle fit to the corners' trajectories for a first axis,
 * then every view refined jointly (Levenberg-Marquardt on ten parameters: the board's pose at
 * angle 0, the axis direction and its position) against the reprojection error. Also the
 * small geometry shared with laserplane.h. Frames and numbers: docs/calibration.md. */
#pragma once

#include <stddef.h>

#include "calib/cv_shim.h"
#include "dataset/ds.h"

#define CAL_TT_MIN_VIEWS    3    /* views that must show the board */
#define CAL_TT_MIN_SPAN_DEG 10.0 /* least turntable angle span */

/* A plane n.x + d = 0, |n| = 1. */
struct cal_plane {
        double n[3], d;
};

/* Least-squares plane through n >= 3 points p (3n); *rms (may be NULL) the RMS distance of
 * the points from it, *spread (may be NULL) the RMS spread of the points along their second
 * principal direction (near 0: they lie on a line). Returns 0 or -EINVAL. */
int cal_plane_fit(const double *p, size_t n, struct cal_plane *pl, double *rms, double *spread);

/* Rotation matrix R (row-major) of Rodrigues vector r. */
void cal_rodrigues(const double r[3], double R[9]);

/* Finds board b in im (up to max corners) and its pose by solvePnP with intrinsics k:
 * board to camera, x_cam = R x_board + t (R row-major). The corners' pixels go to uv (2 each)
 * and their board points to obj (3 each, z = 0). Returns the number of corners (0: the board
 * not found or fewer than 4 corners) or -errno (-EIO: OpenCV, cal_cv_last_error()). */
int cal_board_pose(const struct cal_board *b, const struct cal_intrinsics *k,
                   const struct cal_image *im, double *uv, double *obj, int max, double R[9],
                   double t[3]);

/* One view: the image and the turntable angle (degrees, counterclockwise seen from above). */
struct cal_tt_view {
        struct cal_image im;
        double angle_deg;
};

struct cal_tt_opts {
        struct cal_board board;
        struct cal_intrinsics k;
        int min_views;       /* 0: CAL_TT_MIN_VIEWS */
        double min_span_deg; /* 0: CAL_TT_MIN_SPAN_DEG */
};

/* The turntable frame: z along the axis (up: the turntable turns counterclockwise about it),
 * origin on the axis in the board's plane, x along the board's x axis at angle 0. */
struct cal_turntable {
        double axis[3];       /* the axis direction in the camera frame */
        double origin[3];     /* the frame's origin in the camera frame */
        double R[9], t[3];    /* turntable to camera: x_cam = R x_tt + t (row-major) */
        double rms_px;        /* reprojection RMS of the joint fit over every corner */
        double circle_rms_mm; /* RMS distance of the corners' trajectories from their circles */
        double tilt_deg;      /* angle between the board's normal and the axis */
        double span_deg;      /* turntable angles seen, max - min */
        int n_views, n_used;  /* views given; views where the board was found */
};

/* Solves the axis and the camera's pose from n views. Returns 0; -ENODATA (the board found
 * in fewer than min_views views, or the angles span less than min_span_deg: the turntable
 * did not turn), -EINVAL (a bad argument), -EDOM (the fit diverged) or -EIO (OpenCV), with a
 * sentence saying what was seen and what to change in err. */
int cal_turntable_solve(const struct cal_tt_view *v, size_t n, const struct cal_tt_opts *o,
                        struct cal_turntable *out, char *err, size_t errlen);

/* cal_turntable_solve on the laser-off rows of kind "image" (bracket 0) of camera in
 * dataset d, the turntable angle from each row's pose (0 when the rig has no turntable).
 * Returns as cal_turntable_solve, or -ENOENT (no images of camera), -EINVAL (camera NULL) or
 * the dataset's -errno, with err. */
int cal_turntable_solve_ds(struct ds *d, const char *camera, const struct cal_tt_opts *o,
                           struct cal_turntable *out, char *err, size_t errlen);
