/* camera.h - camera intrinsics and distortion from views of a calibration board
 * (chessboard or ChArUco) captured into a dataset, read through the dataset library only,
 * with per-view reprojection errors and outlier views rejected with a reason; and the
 * calibration file (calibration.yaml, docs/calibration.md) that keeps one section per
 * camera and is never overwritten by a worse result unless forced. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "calib/cv_shim.h"
#include "dataset/ds.h"

#define CAL_MIN_VIEWS_DEFAULT   3   /* views that must show the board */
#define CAL_MIN_CORNERS_DEFAULT 6   /* corners a view must show (partial ChArUco views) */
#define CAL_OUTLIER_FACTOR      3.0 /* a view's RMS above this times the median... */
#define CAL_OUTLIER_FLOOR_PX    0.5 /* ...and above this is an outlier */
#define CAL_REASON_MAX          160

/* A new result is worse than an old one when its RMS is above 1.1 x the old RMS + 0.01 px. */
#define CAL_WORSE(new_rms, old_rms) ((new_rms) > 1.1 * (old_rms) + 0.01)

/* One view (dataset row) offered to the solve. */
struct cal_view {
        int64_t row_id;
        char file[256]; /* relative to the dataset */
        int corners;    /* corners found, 0 when the board was not found */
        double rms;     /* reprojection RMS in the final fit, px; for a view rejected as an outlier,
                         * its RMS against that fit (pose by solvePnP); NAN without corners */
        bool used;      /* in the final fit */
        char reason[CAL_REASON_MAX]; /* why not used, "" when used */
};

/* What to solve. Zero fields take the defaults above. */
struct cal_camera_opts {
        struct cal_board board;
        const char *camera; /* NULL: the dataset's only camera */
        int min_views, min_corners;
        double outlier_factor, outlier_floor_px;
};

/* A camera's calibration with its error figures. */
struct cal_camera {
        char camera[DS_NAME_MAX];
        struct cal_board board;
        int width, height;
        struct cal_intrinsics k;
        double std[4];   /* standard deviations of fx fy cx cy (px) */
        double rms;      /* over every corner of the views used, px */
        char solved[32]; /* ISO 8601 UTC, set by the solve */
        char dataset[256];
        size_t n_views, n_used;
        struct cal_view *views; /* n_views, in row order; malloc'd (cal_camera_clear) */
};

/* Parses a board description: "chessboard:9x7:20" (squares across x down, square side in
 * mm) or "charuco:8x6:20:15" (and the marker side). Returns 0, or -EINVAL for a malformed
 * or impossible board (cal_board_valid). */
int cal_board_parse(const char *spec, struct cal_board *b);

/* Solves the intrinsics of one camera from its dataset rows of kind "image", bracket 0: finds
 * the board in each, calibrates, rejects outlier views one at a time (worst first, while its
 * RMS is above max(outlier_factor x median, outlier_floor_px) and enough views remain) and
 * fills out (cleared first; free with cal_camera_clear). Returns 0; -ENOENT (no such camera,
 * or it has no rows), -EINVAL (no camera named and the dataset has several, or a bad board),
 * -ENODATA (the board is never found, or in fewer than min_views views), -EIO (OpenCV) or
 * the dataset's -errno, with a sentence saying what was seen and what to change in err. On
 * -ENODATA, out->views still tells what each view showed. */
int cal_camera_solve(struct ds *d, const struct cal_camera_opts *o, struct cal_camera *out,
                     char *err, size_t errlen);

/* Frees c->views and zeroes c. */
void cal_camera_clear(struct cal_camera *c);

/* Writes c as the section cameras.<c->camera> of the calibration file at path (calfile.h),
 * keeping the file's other sections, atomically (common/fileio). When the file already holds a
 * section for this camera that is better (CAL_WORSE: c's RMS above 1.1 x its RMS + 0.01 px),
 * that section is kept and -EEXIST returned with both results in err, unless force. Returns 0,
 * -EEXIST, -EBADMSG (the existing file is not a calibration file: err says where) or
 * -errno. */
int cal_camera_write(const char *path, const struct cal_camera *c, bool force, char *err,
                     size_t errlen);

/* Reads the section of camera name from the calibration file at path into out (views not
 * read: out->views is NULL, n_views and n_used as recorded). Returns 0, -ENOENT (no file
 * or no such section), -EBADMSG (malformed; err says where) or -errno. */
int cal_camera_read(const char *path, const char *name, struct cal_camera *out, char *err,
                    size_t errlen);
