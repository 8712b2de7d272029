/* laserplane.h - a laser's plane in one camera's frame, from views of the laser line on a
 * calibration board at several poses (known intrinsics): the line's centre per row
 * (laserline.h, laser-on minus laser-off), the board's plane from solvePnP on the laser-off
 * frame, each centre's ray cut with that plane (points on the board's squares only), then a
 * robust plane fit (RANSAC, then least squares on the inliers). Several lasers: each fitted
 * so, then compared with each other and with the turntable axis, and refined jointly on a scan
 * so that their surfaces agree (laserplane_joint.c). docs/calibration.md. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "calib/laserline.h"
#include "calib/section.h"
#include "calib/turntable.h"
#include "common/frame.h"

#define CAL_LP_MIN_VIEWS  2   /* views with the line on the board */
#define CAL_LP_MIN_POINTS 20  /* points on the board for a view to count */
#define CAL_LP_INLIER_MM  0.3 /* RANSAC inlier distance */

/* One pose of the board: the same view with the laser on, and with it off under the same
 * light (subtracted: on minus off; NULL: the laser frame alone, for a dark room or a laser
 * frame taken with the lamps off); the board's pose from `board` (the board lit; NULL: off). */
struct cal_lp_view {
        const struct gn_frame *off, *on, *board;
};

struct cal_lp_opts {
        struct cal_board board;
        struct cal_intrinsics k;
        int channel;      /* the laser's channel (rig_config.laser_channel) */
        uint32_t lasers;  /* cal_laser_solve_ds: the rows lit by exactly these lasers (bit set
                           * by rig-file index, as gn_pose.lasers); 0: any laser */
        int min_views;    /* 0: CAL_LP_MIN_VIEWS */
        int min_points;   /* 0: CAL_LP_MIN_POINTS */
        double inlier_mm; /* 0: CAL_LP_INLIER_MM */
};

struct cal_laser {
        struct cal_plane
                plane;    /* in the camera frame (mm); n points away from the camera (d <= 0) */
        double rms_mm;    /* RMS distance of the inliers from the plane */
        double spread_mm; /* RMS extent of the points across the line they would form */
        size_t points, inliers;
        int n_views, n_used; /* views given; views with enough points on the board */
        char unused[512];    /* the views not used and why: "view 3 (board not found), ..." */
};

/* Fits the laser plane from n views. Returns 0; -ENODATA (the line on the board in fewer
 * than min_views views: the laser off or out of view, or the board not found; or the points
 * all on one line: the board never tilted), -EINVAL or -EIO, with what was seen per view and
 * what to change in err. */
int cal_laser_solve(const struct cal_lp_view *v, size_t n, const struct cal_lp_opts *o,
                    struct cal_laser *out, char *err, size_t errlen);

/* cal_laser_solve on camera's rows of kind "image" or "laser" (bracket 0) in dataset d: each
 * row with o->lasers on (any laser when 0) paired with the nearest (by row order) laser-off row of
 * the same pose (angles within 0.01 deg, same lamps); a laser row with no lamp lit and no such
 * partner (a session's laser frame) is used alone with the board found in the nearest lit laser-off
 * row of the same angles. Returns as cal_laser_solve, or -ENODATA (no such pair: what was seen in
 * err), -ENOENT (no images of camera), -EINVAL (camera NULL) or the dataset's -errno. */
int cal_laser_solve_ds(struct ds *d, const char *camera, const struct cal_lp_opts *o,
                       struct cal_laser *out, char *err, size_t errlen);

/* How far plane p is from containing the axis of tt (both in the camera frame): the angle
 * (deg) between the axis and the plane, and the distance (mm) of the axis origin from it. */
void cal_laser_vs_axis(const struct cal_plane *p, const struct cal_turntable *tt, double *angle_deg,
                       double *dist_mm);

/* Agreement of two lasers' planes a and b: the angle between them (deg) and, when tt is not
 * NULL, the distance (mm) between where their common line and the axis pass the axis origin's
 * height (0 when both contain the axis: they then meet on it). */
void cal_laser_agreement(const struct cal_plane *a, const struct cal_plane *b,
                         const struct cal_turntable *tt, double *angle_deg, double *dist_mm);

/* Plane cam (camera frame) in the turntable frame of tt (x_cam = R x_tt + t): n' = R^T n,
 * d' = d + n.t. The turntable frame is the world of calib/section.h at turntable angle 0. */
void cal_plane_to_turntable(const struct cal_plane *cam, const struct cal_turntable *tt,
                            struct cal_plane *out);

#define CAL_LR_MATCH_MM   4.0 /* a point's match on another laser's cloud: at most this far */
#define CAL_LR_ITERATIONS 20

struct cal_lr_opts {
        double match_mm;   /* 0: CAL_LR_MATCH_MM (about the spacing of a laser's lines) */
        int iterations;    /* 0: CAL_LR_ITERATIONS */
        int reference;     /* the laser that stays (the best calibrated); the others move */
        bool through_axis; /* the rig's lasers contain the turntable axis: every plane is moved
                            * to the nearest that does, then turns only about it */
};

/* What cal_lasers_refine changed, and how well the lasers' surfaces agree before and after:
 * over the points matched to another laser's surface (the nearest point within match_mm with
 * a normal within 37 deg, distances beyond 3 robust sigmas left out). */
struct cal_lr_result {
        int n_lasers;
        double angle_deg[SEC_MAX_LASERS]; /* how far each plane's normal turned */
        double shift_mm[SEC_MAX_LASERS];  /* how far it moved at the centre of its points */
        /* each laser's mean signed distance from the others' surfaces (mm, + outside) */
        double offset_before[SEC_MAX_LASERS], offset_after[SEC_MAX_LASERS];
        double rms_before, rms_after; /* RMS distance between the surfaces (mm) */
        size_t pairs_before, pairs_after;
        int iterations;
};

/* Refines the planes of the two or more lasers of scan c (world frame, as sec_add_laser) so
 * that their surfaces agree: each point moves along its camera ray as its plane changes, and
 * the distance from each laser's points to the other lasers' surfaces is minimised by
 * changing every plane but the reference laser's (o NULL: laser 0), all together
 * (Gauss-Newton, matches redone each iteration). Needs the normals (sec_normals) first; they
 * are not updated (call sec_normals again). On success c's planes and points are the refined
 * ones; on failure c is unchanged. Returns 0; -EINVAL (fewer than two lasers, no such
 * reference), -ENODATA (fewer than 100 matched points: the clouds do not overlap, or no
 * normals), -EDOM (a plane would change by more than 1 deg or 2 mm: a bad calibration, not a
 * small error) or -ENOMEM, with a sentence in err. One thread; allocates its work arrays. */
int cal_lasers_refine(struct sec_ctx *c, const struct cal_lr_opts *o, struct cal_lr_result *out,
                      char *err, size_t errlen);

/* How well the surfaces of the two or more lasers of scan c agree, as cal_lasers_refine
 * measures it (its rms_before, offset_before), changing nothing: *rms (mm) over *pairs
 * matched points, each laser's mean signed distance from the others' surfaces in offset
 * (NULL: not wanted). match_mm 0: CAL_LR_MATCH_MM. Needs the normals (sec_normals). Returns
 * 0, -EINVAL (fewer than two lasers), -ENODATA (fewer than 100 matched points) or -ENOMEM. */
int cal_lasers_agreement(const struct sec_ctx *c, double match_mm, double *rms, size_t *pairs,
                         double offset[SEC_MAX_LASERS]);

/* Sets the plane of laser `laser` of scan c to p (world frame) and moves its points along
 * their camera rays onto it (their normals kept). Returns 0, -EINVAL (no such laser, p's
 * normal zero), -EDOM (a ray along the plane) or -ENOMEM. */
int cal_laser_replane(struct sec_ctx *c, int laser, const struct cal_plane *p);
