/* section.h - light sectioning: the laser line's centre per row (calib/laserline.h) to 3D
 * points by ray-plane triangulation with a calibrated camera and laser plane, rotated into
 * the object frame by the turntable angle, the lines of every laser and every angle merged
 * into one cloud with normals from the (angle, row) grid and colour from a texture frame.
 *
 * Frames (common/riggeom.h): world z up along the turntable axis, mm; the object frame is
 * the world rotated by minus the turntable angle about z. Plain C, no OpenCV: the line's
 * pixels are undistorted (Brown-Conrady, OpenCV's k1 k2 p1 p2 k3) by an iterative inverse.
 * docs/scanning.md, "Triangulation". */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "calib/cv_shim.h"
#include "calib/laserline.h"
#include "common/frame.h"

#define SEC_MAX_LASERS 8

/* A calibrated camera: intrinsics and distortion, and its world-to-camera pose
 * (x_cam = R x_world + t, R row-major, OpenCV camera frame as riggeom_camera_pose). */
struct sec_camera {
        struct cal_intrinsics k;
        int width, height;
        double R[9], t[3];
};

/* One point of the cloud, in the object frame. */
/* The largest second difference of the centres around a row, px: more is a step or an
 * occlusion the row's centre straddles (docs/scanning.md, "Which centres are used"). */
#define SEC_MAX_KINK_PX 1.0

struct sec_point {
        float x[3];     /* mm */
        float n[3];     /* unit normal facing the camera; 0 0 0 until sec_normals, or alone */
        uint8_t rgb[3]; /* from the texture frame; 0 without one */
        uint8_t laser;  /* index of sec_add_laser */
        int32_t row;    /* image row (column with columns) of the line's centre */
        int32_t line;   /* index of the sec_add_line call that made it */
        float u;        /* the centre along the row, px */
};

/* One sec_add_line call: the points of one frame and one laser. */
struct sec_line {
        int laser;
        double turntable_deg;
        double eye[3];       /* the camera centre in this line's object frame */
        size_t first, count; /* its points, in row order */
};

/* The triangulation context: the camera, the laser planes and the growing cloud. */
struct sec_ctx {
        struct sec_camera cam;
        double eye[3]; /* camera centre, world */
        double plane_p[SEC_MAX_LASERS][3], plane_n[SEC_MAX_LASERS][3];
        int n_lasers;
        struct sec_point *pts;
        size_t n_pts, cap_pts;
        struct sec_line *lines;
        size_t n_lines, cap_lines;
        size_t rejected;  /* centres with no usable ray (grazing, behind, undistortion failed) */
        size_t unvouched; /* centres at a run's end or a kink (sec_add_line): left out */
};

/* Starts a context for camera cam (copied). Returns 0 or -EINVAL (no positive focal length or
 * image size, a principal point or t not finite, or R not a rotation: NAN included). */
int sec_init(struct sec_ctx *c, const struct sec_camera *cam);

/* Frees the cloud and zeroes c. Safe on a zeroed context. */
void sec_free(struct sec_ctx *c);

/* Adds a laser plane through world point p with normal n (any length). Returns its index,
 * -EINVAL (n zero) or -ENOSPC (SEC_MAX_LASERS already). */
int sec_add_laser(struct sec_ctx *c, const double p[3], const double n[3]);

/* The plane of a laser of the rig file: it contains the turntable axis (z) at azimuth
 * azimuth_deg, so p = 0 and n = (-sin az, cos az, 0). Never fails. */
void sec_rig_laser_plane(double azimuth_deg, double p[3], double n[3]);

/* Triangulates every centre of r (a centre per row, or per column with columns) that its
 * neighbours vouch for (both have the line, and it is within SEC_MAX_KINK_PX of their mean:
 * others are counted in unvouched) seen by the context's camera with laser `laser` at turntable
 * angle turntable_deg, and appends the points in the object frame, coloured from texture (8 or 16
 * bits, 1 or 3 channels, the camera's size; NULL: none). Returns the number of points added,
 * -EINVAL (bad laser, r larger than the image, texture of another size) or -ENOMEM. */
int sec_add_line(struct sec_ctx *c, int laser, double turntable_deg,
                 const struct laserline_result *r, bool columns, const struct gn_frame *texture);

/* Estimates each point's normal from its grid neighbours: the rows next to it in its line,
 * and the same row in the previous and next lines of the same laser (lines added in angle
 * order), oriented towards the camera. A point without neighbours in both directions keeps
 * 0 0 0. Returns the number of points given a normal. */
size_t sec_normals(struct sec_ctx *c);

/* Undistorts pixel (u, v) of camera k to the normalised image point xy (z = 1) by iterating
 * the inverse of the Brown-Conrady model. Returns 0, or -EDOM when it does not converge to
 * 1e-6 px. */
int sec_undistort(const struct cal_intrinsics *k, double u, double v, double xy[2]);
