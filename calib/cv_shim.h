/* cv_shim.h - the one door from calib/ to OpenCV (cv_shim.cpp, the only C++ of calib/):
 * calibration-board corner detection (chessboard and ChArUco), calibrateCamera with
 * per-view errors, solvePnP and projectPoints, Hough circles (the mirror sphere), on plain
 * C arrays. No C++ type crosses this header; every OpenCV exception is caught and returned
 * as -errno, its text kept for cal_cv_last_error(). Boards follow OpenCV 4.6's board frame
 * (docs/sim-render.md): x right, y down on the printed side, origin at the top-left corner
 * of the squares, z = 0 on the board. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum cal_board_type { CAL_BOARD_CHESSBOARD, CAL_BOARD_CHARUCO };

/* A printed calibration board. squares_x/_y count squares (a board of 5x4 squares has
 * 4x3 inner corners); ChArUco markers are DICT_4X4_50 from id 0, as OpenCV's
 * CharucoBoard::create(squares_x, squares_y, square, marker, DICT_4X4_50). */
struct cal_board {
        enum cal_board_type type;
        int squares_x, squares_y;
        double square_mm;
        double marker_mm; /* ChArUco only */
};

/* True when b can be detected: at least 3x3 squares of a positive size; ChArUco: a marker
 * smaller than its square and at most 50 markers (DICT_4X4_50). */
bool cal_board_valid(const struct cal_board *b);

/* Number of inner corners of b: (squares_x - 1) * (squares_y - 1). */
int cal_board_corners(const struct cal_board *b);

/* Board-frame position (mm, z = 0) of inner corner id of b: ids run row by row from the
 * top-left inner corner, as OpenCV numbers chessboard and ChArUco corners. */
void cal_board_corner_xy(const struct cal_board *b, int id, double xy[2]);

/* An image of 1 or 3 channels (RGB), 8 or 16 bits per sample, rows stride bytes apart. */
struct cal_image {
        const uint8_t *data;
        int width, height, channels, bits;
        size_t stride;
};

/* Finds the inner corners of board b in im. A chessboard must be seen whole
 * (findChessboardCorners + cornerSubPix); a ChArUco board may be partly hidden or out of view.
 * Writes up to max corners as pixel positions uv[2k], uv[2k+1] (OpenCV convention: pixel centres at
 * integers; ChArUco corners corrected for OpenCV 4.6's +0.5 px shift, see cv_shim.cpp)
 * with their corner ids. Returns the number of corners (0: board not found), -EINVAL (bad
 * image or board) or -EIO (OpenCV failed; cal_cv_last_error()). */
int cal_cv_find_corners(const struct cal_board *b, const struct cal_image *im, double *uv, int *ids,
                        int max);

/* Intrinsics and distortion: fx fy cx cy, and k1 k2 p1 p2 k3. */
struct cal_intrinsics {
        double fx, fy, cx, cy;
        double dist[5];
};

/* Views for cal_cv_calibrate: view i has counts[i] points, its object points (x, y, z mm)
 * at obj[3 * (first point of view i)] and its pixels at uv[2 * (first point of view i)],
 * views stored one after another. */
struct cal_cv_views {
        size_t n_views;
        const int *counts;
        const double *obj;
        const double *uv;
};

/* What cal_cv_calibrate returns besides the intrinsics. */
struct cal_cv_fit {
        double rms;       /* over every point of every view, px */
        double std[4];    /* standard deviations of fx fy cx cy as OpenCV estimates them */
        double *view_rms; /* caller's array of n_views: each view's RMS, px (may be NULL) */
        double *rvecs;    /* caller's 3 * n_views: each board's rotation (Rodrigues), or NULL */
        double *tvecs;    /* caller's 3 * n_views: each board's translation (mm), or NULL */
};

/* calibrateCamera on views of images width x height (full 5-coefficient model). Returns 0,
 * -EINVAL (fewer than 1 view or 4 points in a view) or -EIO (OpenCV failed). */
int cal_cv_calibrate(const struct cal_cv_views *v, int width, int height, struct cal_intrinsics *k,
                     struct cal_cv_fit *fit);

/* solvePnP (iterative) of n >= 4 points: rvec, tvec of the object frame in the camera
 * frame. Returns 0, -EINVAL or -EIO. */
int cal_cv_solve_pnp(const double *obj, const double *uv, int n, const struct cal_intrinsics *k,
                     double rvec[3], double tvec[3]);

/* projectPoints of n object points into uv (2n). Returns 0, -EINVAL or -EIO. */
int cal_cv_project(const double *obj, int n, const double rvec[3], const double tvec[3],
                   const struct cal_intrinsics *k, double *uv);

/* undistortPoints of n pixels uv (2n) into normalised image coordinates xy (2n: x/z, y/z
 * of the ray in the camera frame), iterated to 1e-12. Returns 0, -EINVAL or -EIO. */
int cal_cv_undistort(const double *uv, int n, const struct cal_intrinsics *k, double *xy);

/* Circles in im by the Hough gradient transform (the gray image smoothed, OpenCV's
 * HOUGH_GRADIENT) of radius min_r..max_r px: up to max as centre x, y and radius in xyr (3
 * each), most votes first. Candidates only: the caller refines and checks them. Returns the
 * number found, -EINVAL or -EIO. */
int cal_cv_find_circles(const struct cal_image *im, double min_r, double max_r, double *xyr,
                        int max);

/* The text of the last OpenCV exception caught on this thread, "" if none. */
const char *cal_cv_last_error(void);

#ifdef __cplusplus
}
#endif
