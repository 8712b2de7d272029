/* lamps.h - lamp positions from their highlights on a mirror sphere lying on the turntable,
 * seen by one or several calibrated cameras at several turntable angles, one lamp lit per
 * frame. Per view: the sphere's silhouette (Hough candidates refined on radial edges, the
 * cone of rays tangent to the sphere fitted to them by RANSAC and least squares), the one
 * bright highlight inside it (its sub-pixel centroid), the highlight's camera ray reflected on
 * the sphere. The sphere's centre is triangulated across views from the cones' axes (it turns
 * with the turntable; one view alone takes its distance from the known diameter). Per lamp:
 * the point closest to its reflected rays (least squares, outlier rays rejected, refit).
 * Then the sphere's centre and every lamp are refined jointly on the highlights' positions
 * (lamps_ba.c), and each lamp is reported against the rig file's nominal position. Plain C but
 * for the Hough candidates (cv_shim.h).
 *
 * Frames (common/riggeom.h): the world is the turntable frame at angle 0, mm; an object-frame
 * point p is at Rz(turntable angle) p in the world; a lamp turns with the light arm about z,
 * and its position is given with the arm at 0. docs/calibration.md, "Lamp positions". */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "calib/calfile.h"
#include "calib/camera.h"
#include "calib/cv_shim.h"
#include "calib/section.h"
#include "common/rigconf.h"
#include "dataset/ds.h"

#define CAL_LAMPS_MIN_VIEWS        3   /* reflected rays a lamp needs */
#define CAL_LAMPS_MIN_SPREAD_DEG   3.0 /* least angular spread of a lamp's rays */
#define CAL_LAMPS_REACH_MM         300 /* the sphere lies this close to the turntable centre */
#define CAL_LAMPS_OUTLIER_FACTOR   3.0 /* a ray farther than this times the median... */
#define CAL_LAMPS_OUTLIER_FLOOR_MM 1.0 /* ...and than this from the lamp is an outlier */

/* A calibrated camera of the solve. */
struct cal_lamps_camera {
        char name[DS_NAME_MAX];
        struct sec_camera cal; /* world (turntable at angle 0) to camera */
};

/* The sphere's image in one view. */
struct cal_sphere_image {
        double u, v, r;  /* the silhouette's circle in the image, px */
        double axis[3];  /* unit ray from the camera to the sphere's centre, camera frame */
        double half_deg; /* half-angle of the cone of rays tangent to the sphere */
        double rms_px;   /* RMS distance of the silhouette's edge points from the cone */
        int n_edges;     /* edge points used, of CAL_SPHERE_DIRS directions */
};

#define CAL_SPHERE_DIRS 180

/* One frame offered to the solve: its image, camera, lit lamp and angles (input), and what
 * the solve made of it (output). */
struct cal_lamp_view {
        struct cal_image im;
        int camera;                     /* index into cal_lamps_opts.cams */
        int lamp;                       /* index of the lit lamp in the rig file */
        double turntable_deg;           /* NAN counts as 0 */
        double light_arm_deg;           /* NAN counts as 0 (no light arm) */
        int64_t row_id;                 /* the dataset row (cal_lamps_solve_ds), else as given */
        struct cal_sphere_image sphere; /* n_edges 0: not found */
        bool sphere_used;               /* its silhouette is in the sphere's fit */
        double highlight[2];            /* px, NAN when none */
        double offset[2]; /* the highlight's centroid minus the reflection of its lamp's
                           * centre (px; lamp_radius_mm, once refined; else 0) */
        double miss_mm;   /* distance of its reflected ray from its lamp's position, NAN */
        bool used;        /* its ray is in its lamp's fit */
        char reason[CAL_REASON_MAX]; /* why not used, "" when used */
};

/* What to solve. Zero numbers take the defaults above. */
struct cal_lamps_opts {
        const struct rig_config *rc; /* the lamps: names and nominal positions */
        const struct cal_lamps_camera *cams;
        size_t n_cams;
        double sphere_mm;      /* the mirror sphere's diameter */
        double lamp_radius_mm; /* the lamps' radius: their reflections' centroids are offset
                                * from the reflection of their centres (0: ignored) */
        int min_views;
        double min_spread_deg, reach_mm;
};

/* The solve's result: one entry per lamp of the rig lit in some view, in rig-file order. */
struct cal_lamps {
        size_t n_lamps;
        struct cal_lamp_pos lamps[RIG_MAX_LAMPS]; /* pos NAN and n_obs 0 where not solved */
        int index[RIG_MAX_LAMPS];                 /* each one's index in the rig file */
        double sphere[3];      /* the sphere's centre, object frame (turntable frame at 0) */
        double sphere_rms_mm;  /* RMS distance of the silhouettes' axes used from it */
        double sphere_diam_mm; /* the diameter the silhouettes' sizes give at that distance */
        size_t n_views, n_used;
        struct cal_lamp_view *views; /* cal_lamps_solve_ds: the rows read (images not kept),
                                      * malloc'd, freed by cal_lamps_clear; else NULL */
};

/* Finds the mirror sphere of diameter sphere_mm in im seen by camera cam, within reach_mm
 * (0: CAL_LAMPS_REACH_MM) of the turntable centre: Hough candidates refined on radial edges
 * where the background is brighter than the rim (a mirror shows the background dimmed by its
 * reflectance there). Returns 0 with out filled, -ENOENT (none found), -EINVAL or -EIO
 * (OpenCV, cal_cv_last_error()). */
int cal_lamps_find_sphere(const struct cal_image *im, const struct sec_camera *cam,
                          double sphere_mm, double reach_mm, struct cal_sphere_image *out);

/* Finds the highlights inside the sphere's image s: blobs above half-way between the disc's
 * median and its brightest pixel, peaking at least 9/10 of the way up. Returns their number
 * (uv: the centroid of the brightest one's pixels weighted by their excess, NAN when none):
 * 0 when the brightest pixel is not twice the disc's median (no lamp reflected). */
int cal_lamps_find_highlight(const struct cal_image *im, const struct cal_sphere_image *s,
                             double uv[2]);

/* Solves the lamps lit in the n views v (their outputs filled). Returns 0; -ENODATA (the
 * sphere found in no view, or a lamp with too few rays or rays too parallel; the lamps solved
 * are still in out), -EINVAL (a bad argument) or -EIO (OpenCV), with a sentence saying what
 * was seen and what to change in err. */
int cal_lamps_solve(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                    struct cal_lamps *out, char *err, size_t errlen);

/* cal_lamps_solve on dataset d's rows of kind "image", bracket 0, laser off, with exactly one
 * lamp lit, of the cameras in o; angles from each row's pose. out->views keeps the views
 * (without images). Returns as cal_lamps_solve, or -ENOENT (no such rows) or the dataset's
 * -errno, with err. */
int cal_lamps_solve_ds(struct ds *d, const struct cal_lamps_opts *o, struct cal_lamps *out,
                       char *err, size_t errlen);

/* Frees l->views and zeroes l. */
void cal_lamps_clear(struct cal_lamps *l);
