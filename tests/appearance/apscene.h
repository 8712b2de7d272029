/* apscene.h - small synthetic 4-DOF datasets for the appearance model's tests (the fit and
 * the renderers): a 60 mm sphere (or another built-in shape) on a turntable without a disc,
 * lamps at several elevations on a light arm, one to three fixed cameras, rendered
 * in-process by gonio-sim's renderer with noise off (16-bit, ideal sensor) and stored with
 * the dataset library; the material selectable from diffuse to sharply glossy. Also renders
 * the simulator's image for any light position and view, for held-out comparisons. */
#pragma once

#include <stdbool.h>

#include "dataset/ds.h"
#include "tests/render/rtest.h"

#define APS_MAX_LAMPS   8
#define APS_MAX_CAMERAS 3
#define APS_SIZE_MM     60.0 /* the object's size (sphere: diameter, centre at z = 30) */

/* What to build (aps_opts_default fills it). */
struct aps_opts {
        int width, height;    /* the cameras' images */
        int n_cameras;        /* at elevations 15, 35, 55 degrees, 400 mm from (0, 0, 30) */
        int turntable_angles; /* views per camera, 360 / n apart from 0 */
        int arm_angles;       /* light-arm positions, 360 / n apart from arm_offset_deg */
        double arm_offset_deg;
        int n_lamps; /* lamps used, of lamp_elevation_deg */
        double lamp_elevation_deg[APS_MAX_LAMPS];
        double lamp_radius_mm; /* distance of the lamps from the turntable centre */
        double intensity;      /* the lamps' radiant intensity (rig units) */
        const char *shape;     /* scene.object.shape: "sphere", "gem"... */
        double albedo[3];
        double ks, alpha; /* Beckmann lobe: weight and roughness; ks 0: diffuse */
        double alpha_y;   /* > 0: the roughness across the object's z axis (alpha along it) */
        bool mesh;        /* store the true surface as the dataset's mesh.ply */
        double dist[5];   /* the cameras' lens distortion (OpenCV k1 k2 p1 p2 k3; 0: none) */
        int mesh_rings;   /* of that sphere mesh (its segments twice as many) */
        bool noise;       /* the sensor's shot and read noise on */
};

/* The materials of the tests and of docs/appearance.md's PSNR table. */
enum aps_material {
        APS_DIFFUSE,
        APS_ROUGH,  /* Beckmann alpha 0.5 */
        APS_GLOSSY, /* alpha 0.3: "moderately glossy" */
        APS_SHINY,  /* alpha 0.2 */
        APS_SHARP,  /* alpha 0.12 */
};

/* A rendering rig of the options, its lamps plus one probe lamp (the last) that
 * aps_render_light moves anywhere. */
struct apscene {
        struct rtest t;
        struct aps_opts o;
        int probe;
        uint64_t seq;
};

/* Defaults: 96x72, one camera, 2 turntable angles, 18 arm angles, 6 lamps (-40 to 85
 * degrees) 500 mm away, a sphere with material m (isotropic), its mesh of 48 rings stored,
 * noise off. */
void aps_opts_default(struct aps_opts *o, enum aps_material m);

/* Builds the rig file and the scene; exits the test on failure. */
void aps_open(struct apscene *s, const struct aps_opts *o);

void aps_close(struct apscene *s);

/* Renders camera cam at turntable angle tt (degrees) lit by lamp `lamp` with the light arm at
 * arm degrees: what the dataset stores. flags and truth as sim_render. */
void aps_render_lamp(struct apscene *s, int cam, double tt, double arm, int lamp,
                     struct gn_frame *f, unsigned flags, struct sim_truth *truth);

/* Renders camera cam at turntable angle tt lit by a point lamp of the rig's intensity at
 * world position p (mm; the light arm at 0). */
void aps_render_light(struct apscene *s, int cam, double tt, const double p[3], struct gn_frame *f,
                      unsigned flags, struct sim_truth *truth);

/* Like aps_render_light with camera cam moved to elevation_deg (same distance, azimuth and
 * target): a view between the dataset's. sim_camera_geom of the scene gives its geometry only
 * during the call; the camera is put back after. */
void aps_render_view(struct apscene *s, int cam, double elevation_deg, double tt, const double p[3],
                     struct gn_frame *f, unsigned flags, struct sim_truth *truth);

/* World position (mm) of lamp `lamp` with the light arm at arm degrees. */
void aps_lamp_position(const struct apscene *s, int lamp, double arm, double p[3]);

/* Writes the true surface of a sphere (a UV mesh, exact normals) as dir/mesh.ply (calib/ply.h);
 * nothing for other shapes. */
void aps_write_mesh(const struct apscene *s, const char *dir);

/* A dataset at path (must not exist) with the rig file and every view (camera, turntable
 * angle) under every light (lamp, arm angle), 16-bit, noise off; with o.mesh the true surface
 * as mesh.ply. Returns the open dataset (ds_close it). */
struct ds *aps_make_dataset(struct apscene *s, const char *path);

struct ap_model;

/* aps_make_dataset at path, then the model fitted (P 6, K 12, tiles of tile pixels) and written
 * into it as models/default; the model in *m. Exits the test on failure. */
void aps_fit_dataset(struct apscene *s, const char *path, int tile, struct ap_model **m);
