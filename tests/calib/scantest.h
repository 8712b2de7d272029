/* scantest.h - 100 mm objects (sphere, gem, relief plate) scanned by light sectioning with the
 * renderer in-process (laser on minus off, noise on, a strong lens), and every scanned point
 * scored against the renderer's true surface: for the sphere analytically, for the gem and the
 * relief against the triangles the renderer traced (meshdist.h).
 * Shared by test-section.c (the true calibration) and test-shape.c (the estimated one). */
#pragma once

#include "calib/section.h"
#include "tests/calib/meshdist.h"
#include "tests/render/rtest.h"

#define SCAN_W          800
#define SCAN_H          600
#define SCAN_WORST_MM   0.5 /* no point farther from the true surface */
#define SCAN_FAR_MM     0.1 /* and at most SCAN_FAR_SHARE of the points farther than this */
#define SCAN_FAR_SHARE  0.02
#define SCAN_MAX_LASERS 3

struct scan;

/* The true surface near p (object frame) as a plane n.x + d = 0 (pl: n, d; n unit, outwards)
 * through its point nearest p; false where p is not scored. */
typedef bool (*truth_fn)(const struct scan *s, const struct sec_point *p, double pl[4]);

/* One rendering rig per laser (the renderer has one laser), the camera of the first. The
 * points are scored after the rigid motion T (R row-major, then t: x_truth = R x + t) from
 * the frame they were triangulated in to the renderer's object frame (identity: the same);
 * truth[i] is the true surface's plane near point i (NAN: not scored), kept for
 * scan_rescore. */
struct scan {
        struct rtest t[SCAN_MAX_LASERS];
        int lasers, angles;
        struct sec_ctx c;
        double T[12];
        double (*truth)[4];
        struct meshdist md; /* the object's true triangles (none for the sphere) */
};

/* What a scan with one laser scored. */
struct score {
        double rms, worst, bias; /* mm: RMS, largest and mean signed distance */
        int scored, far;         /* points scored; those beyond SCAN_FAR_MM */
};

/* The camera of the scans: 380 mm from (0, 0, target_z), at azimuth 30 and the given
 * elevation, 800x600, a strong lens. Writes its rig-file section into buf. */
void scan_camera_yaml(char *buf, size_t len, double elevation, double target_z);

/* The laser at azimuth az: from the side at 500 mm, or from above for a flat object
 * (target_z < 10). Writes its rig-file section into buf. */
void scan_laser_yaml(char *buf, size_t len, double az, double target_z);

/* Opens the rigs of shape with the lasers at the n azimuths az, to scan at `angles`
 * turntable angles; no context yet (scan_start). */
void scan_rigs(struct scan *s, const char *shape, double elevation, double target_z,
               const double *az, int n, int angles);

/* Starts the context with camera cam and the lasers' planes (the world frame of cam, one per
 * rig), T the identity. */
void scan_start(struct scan *s, const struct sec_camera *cam, const double (*p)[3],
                const double (*n)[3]);

/* scan_rigs then scan_start with the true calibration of the rig file: intrinsics,
 * riggeom_camera_pose, the lasers' planes. */
void scan_open(struct scan *s, const char *shape, double elevation, double target_z,
               const double *az, int n, int angles);

void scan_close(struct scan *s);

/* The sphere's true surface: its tangent plane at the point nearest p (the distance to it is
 * the distance to the sphere). */
bool scan_sphere_dist(const struct scan *s, const struct sec_point *p, double pl[4]);

/* The true triangles' surface: the plane through their point nearest p, normal to the way
 * from it to p (the distance to it is the distance to the surface). Scores every point. */
bool scan_mesh_dist(const struct scan *s, const struct sec_point *p, double pl[4]);

/* Scans laser l over s->angles angles and scores its points with fn; prints the numbers and
 * checks at least min_points scored, RMS <= rms_max, none beyond SCAN_WORST_MM and at most
 * SCAN_FAR_SHARE beyond SCAN_FAR_MM. */
struct score scan_expect(struct scan *s, int l, const char *shape, truth_fn fn, int min_points,
                         double rms_max);

/* Scores laser l's points of s again as they are now (moved by cal_lasers_refine, say)
 * against the true planes kept when they were scanned; prints the numbers under label. */
struct score scan_rescore(const struct scan *s, int l, const char *label);
