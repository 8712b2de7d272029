/* lampscene.h - the mirror-sphere scene of the lamps' tests (test-lamps, test-calfile's
 * gonioctl calibrate lamps): a 100 mm mirror sphere 70 mm off the axis of a white turntable,
 * three lamps 420-500 mm away, two cameras, rendered in-process (noise on), the solve's
 * options built from the rig file's true calibration, views stored in a dataset. */
#pragma once

#include "calib/lamps.h"
#include "tests/render/rtest.h"

#define LS_TOL_MM         1.0 /* lamp position against the truth */
#define LS_SPHERE_TOL_MM  0.3 /* sphere centre against the truth */
#define LS_SPHERE_MM      100.0
#define LS_LAMP_RADIUS_MM 30.0 /* scene.lamps.radius */
#define LS_ANGLES         16

/* The scene with the sphere, and one without (a cylinder in its place). */
extern const char ls_scene_sphere[], ls_scene_empty[];

/* The sphere's true centre in the object frame. */
extern const double LS_SPHERE_TRUE[3];

/* A rendering rig and the solve's options built from its true calibration. */
struct ls_fixture {
        struct rtest t;
        struct cal_lamps_camera cams[2];
        struct cal_lamps_opts o;
        uint64_t seq;
};

/* Opens the rig with scene, lamp l0 at l0_elevation degrees (30: where it is rendered). */
void ls_open(struct ls_fixture *fx, const char *scene, double l0_elevation);

void ls_close(struct ls_fixture *fx);

/* Renders camera cam at turntable angle tt, light arm arm, lamps `lit` (noise on). */
void ls_render(struct ls_fixture *fx, int cam, double tt, double arm, uint32_t lit,
               struct gn_frame *f);

/* A dataset at path, its rig.yaml the fixture's rig file, of both cameras at `angles`
 * turntable angles with each of the first n_lamps lamps lit in turn; lamp `off` (-1: none)
 * recorded as lit but left off. */
struct ds *ls_make_dataset(struct ls_fixture *fx, const char *path, int angles, int n_lamps,
                           int off);

/* Distance of pos from the true position of lamp `lamp` (rig index, light arm at 0). */
double ls_lamp_error(const struct ls_fixture *fx, int lamp, const double pos[3]);
