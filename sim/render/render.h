/* render.h - the renderer of synthetic captures of gonio-sim.
 *
 * Builds a scene (object, turntable, calibration targets, materials, lights,
 * laser) from a rig file and renders what a camera of the rig sees for a given
 * state of the emulated axes, lamps and laser, plus per-pixel ground truth.
 * Deterministic: the same scene seed, state, request and frame sequence number
 * give the same bytes. Thread-safe for concurrent sim_render() calls on one scene. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/frame.h"
#include "common/pose.h"
#include "common/rigconf.h"

struct sim_scene;

/* The rig's state when a frame is exposed is a struct gn_pose (common/pose.h): angles by
 * axis role, lamps and lasers as bit sets by rig-file index. An angle that is NAN (the rig
 * has no axis of that role) renders as 0. */

/* Exposure of one frame. 0 fields take the camera's defaults from the rig file. */
struct sim_expose {
        int exposure_us;
        double gain;
        int bits;      /* 8 or 16 */
        bool no_noise; /* ideal sensor: no shot/read noise (for closed-form tests) */
};

enum sim_truth_flags {
        SIM_TRUTH_DEPTH = 1 << 0,  /* float z in camera frame (mm), NAN on background */
        SIM_TRUTH_NORMAL = 1 << 1, /* float[3] world-space unit normal */
        SIM_TRUTH_POINT = 1 << 2,  /* float[3] object-space point (mm) */
        SIM_TRUTH_LAMP = 1 << 3,   /* uint32 bit mask of lamps that reach the point */
};

/* Per-pixel ground truth, row-major width*height; arrays present for requested flags.
 * Owned by the caller: free with sim_truth_free(). */
struct sim_truth {
        int width, height;
        float *depth;
        float *normal;
        float *point;
        uint32_t *lamp_mask;
};

/* Pinhole + Brown-Conrady camera, OpenCV conventions: x_cam = R * x_world + t. */
struct sim_cam_geom {
        int width, height;
        double fx, fy, cx, cy;
        double dist[5];
        double R[9];
        double t[3];
};

/* Builds the scene from rc (scene section, lamps, laser, cameras). On error returns
 * -errno and writes "FILE:LINE: key 'x': reason" into err. rc must outlive the scene. */
int sim_scene_new(struct rig_config *rc, struct sim_scene **ret, char *err, size_t errlen);

/* Frees the scene; NULL is a no-op. Returns NULL. */
struct sim_scene *sim_scene_free(struct sim_scene *s);

/* Renders camera cam (index into rc->cameras) in state st. out is allocated here
 * (caller frees with gn_frame_free_data). truth may be NULL; truth_flags selects arrays.
 * seq numbers the frame for noise. Returns 0 or -errno (-EINVAL for a bad camera). */
int sim_render(struct sim_scene *s, const struct gn_pose *st, int cam, const struct sim_expose *exp,
               uint64_t seq, struct gn_frame *out, unsigned truth_flags, struct sim_truth *truth);

/* Exact geometry of camera cam in state st. Returns 0 or -EINVAL. */
int sim_camera_geom(const struct sim_scene *s, const struct gn_pose *st, int cam,
                    struct sim_cam_geom *out);

/* World position (mm) of lamp i in state st. Returns 0 or -EINVAL. */
int sim_lamp_position(const struct sim_scene *s, const struct gn_pose *st, int lamp, double out[3]);

/* The plane of laser `laser` (rig-file index) in world coordinates as n.x + d = 0 with
 * |n| = 1. Returns 0 or -ENOENT (no such laser). */
int sim_laser_plane(const struct sim_scene *s, int laser, double n[3], double *d);

/* Frees the arrays of a truth struct. */
void sim_truth_free(struct sim_truth *t);

/* Projects world point p (mm) with camera geometry g (OpenCV model, same as projectPoints)
 * into pixel coordinates uv. Returns 0, or -EDOM when p is not in front of the camera. */
int sim_cam_project(const struct sim_cam_geom *g, const double p[3], double uv[2]);

/* Pose of calibration target i (order of scene.targets) in state st: world point =
 * R * board point + t, board frame as documented in docs/sim-render.md. Returns 0 or
 * -EINVAL. */
int sim_target_pose(const struct sim_scene *s, const struct gn_pose *st, int target, double R[9],
                    double t[3]);

/* A triangle mesh handed out by the renderer (object frame, mm): malloc'ed arrays that the
 * caller frees with free(). */
struct sim_mesh {
        size_t nv, nt;
        float *pos;    /* 3 * nv */
        uint32_t *idx; /* 3 * nt */
};

/* Reads the PLY or OBJ mesh at path (the reader of the scene's "mesh" shape) into *out.
 * Returns 0 or -errno with "path:line: reason" in err. */
int sim_mesh_read(const char *path, struct sim_mesh *out, char *err, size_t errlen);

/* A copy of the triangles of the scene's object (placed: object frame at turntable angle 0)
 * into *out; an analytic sphere (resolution 0) is tessellated with res rows. Returns 0,
 * -ENOENT (the scene has no object) or -ENOMEM. */
int sim_object_mesh(const struct sim_scene *s, int res, struct sim_mesh *out);
