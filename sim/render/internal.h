/* internal.h - data structures shared by the renderer's modules (scene description,
 * geometry, materials, textures, boards, cameras, lights, sensor). Not a public API.
 *
 * DESIGN: the whole scene (object, targets, turntable disc) is built once, in the
 * "object frame" (the world frame at turntable angle 0), into one Embree BVH. A frame at
 * turntable angle a is rendered by rotating the camera, lamps and laser by -a about z
 * into that frame instead of moving geometry, so nothing is rebuilt per frame. */
#pragma once

#include <embree3/rtcore.h>
#include <stdbool.h>
#include <stdint.h>

#include "common/cleanup.h"
#include "common/riggeom.h"
#include "render.h"
#include "vec.h"

#define SIM_MAX_GEOMS        24
#define SIM_MAX_TARGETS      8
#define SIM_MAX_LAMP_SAMPLES 64
#define SIM_MAX_DOME         16384

/* A texture in linear float, 1 or 3 channels, repeated outside [0,1). */
struct rtex {
        int w, h, channels;
        float *px;
};

enum spec_model { SPEC_NONE, SPEC_WARD, SPEC_BECKMANN, SPEC_MIRROR };

struct rmat {
        enum spec_model model;
        float albedo[3];
        float ks, ax, ay, f0;                         /* f0 = 1: no Fresnel falloff */
        struct rtex *albedo_map, *ks_map, *alpha_map; /* owned */
};

/* Material parameters at one surface point. */
struct surf {
        enum spec_model model;
        float albedo[3];
        float ks, ax, ay, f0;
};

enum board_kind { BOARD_CHESS, BOARD_CHARUCO };

/* A calibration board pattern in its own frame, OpenCV's object frame of the board: x to
 * the right and y down as the printed side is seen, origin at the top-left corner of the
 * squares, z into the board (the printed side faces -z); squares [0,nx*sq] x [0,ny*sq],
 * square (0,0) black, markers in the white squares numbered row by row from the top. */
struct board {
        enum board_kind kind;
        int nx, ny;
        float square, marker, margin;
        float white, black; /* albedo */
        int first_id;
};

enum uv_map { UV_NONE, UV_MESH, UV_SPHERE, UV_CYLINDER, UV_PLANAR };

struct mesh {
        size_t nv, nt;
        float *pos;    /* 3 * nv */
        float *nrm;    /* 3 * nv, or NULL: flat shading */
        float *uv;     /* 2 * nv, or NULL */
        uint32_t *idx; /* 3 * nt */
};

enum geom_kind { GEOM_MESH, GEOM_SPHERE };

/* One Embree geometry; its index in sim_scene.geoms is its geomID. */
struct rgeom {
        enum geom_kind kind;
        int mat;
        struct mesh mesh;        /* object frame (GEOM_MESH) */
        float centre[3], radius; /* object frame (GEOM_SPHERE) */
        float to_local[12];      /* object frame -> shape frame, row-major 3x4 */
        float axis[3];           /* shape z axis in object frame: anisotropy direction */
        enum uv_map uvmap;
        float uv_size; /* shape size for the procedural uv maps */
        const struct board *board;
};

struct camera {
        float *dirs; /* unit ray directions in the camera frame, 3 per pixel */
};

struct dome_el {
        double dir[3]; /* world frame, unit */
        double w[3];   /* radiance x solid angle, RGB */
};

/* The procedural sky (radiance, zenith_ratio, ground) or, with env, a lat-long environment
 * map (appearance/envmap.h's convention, world frame) scaled by radiance. */
struct dome {
        struct rtex *env; /* owned, or NULL */
        double radiance, zenith_ratio, ground;
        double sun_dir[3], sun_cos, sun_radiance; /* sun_cos = cos(sun radius) */
        double threshold;
        int max_elements;
};

enum sensor_format { FMT_RGB, FMT_MONO, FMT_RGGB };

struct sensor {
        double response;   /* electrons per (radiance unit x second) */
        double full_well;  /* electrons */
        double read_noise; /* electrons rms */
        double black;      /* fraction of full scale */
        bool shot_noise;
        enum sensor_format format;
};

struct sim_scene {
        struct rig_config *rc;
        bool has_object; /* geoms[0] is the scene's object */
        RTCDevice dev;
        RTCScene scn;
        struct rgeom geoms[SIM_MAX_GEOMS];
        int n_geoms;
        struct rmat mats[SIM_MAX_GEOMS];
        int n_mats;
        struct board boards[SIM_MAX_TARGETS];
        int n_boards;
        double target_R[SIM_MAX_TARGETS][9], target_t[SIM_MAX_TARGETS][3]; /* object frame */
        int n_targets;
        struct camera cams[RIG_MAX_CAMERAS];
        struct dome dome;
        struct dome_el *dome_els; /* world frame, n_dome */
        int n_dome;
        double lamp_radius;
        int lamp_samples;
        struct sensor sensor;
        float *noise_q; /* sensor_table() */
        uint64_t seed;
        int threads;
};

/* --- scene.c: scene section parsing --- */
int scene_parse(struct sim_scene *s, char *err, size_t errlen);

/* --- shapes.c: procedural shapes and mesh helpers --- */
int shape_sphere_mesh(float radius, int res, struct mesh *m);
int shape_cylinder(float radius, float height, int res, struct mesh *m);
int shape_gem(float size, int facets, struct mesh *m);
int shape_relief(float size, int res, struct mesh *m);
int shape_rect(float x0, float y0, float x1, float y1, struct mesh *m);
int shape_disc(float radius, int res, struct mesh *m);
int mesh_alloc(struct mesh *m, size_t nv, size_t nt, bool normals, bool uvs);
void mesh_free(struct mesh *m);
/* Smooth vertex normals by area-weighted face normals (allocates nrm). */
int mesh_smooth_normals(struct mesh *m);
/* Scales so the largest extent is size, centres x/y and puts the bottom on z = 0. */
void mesh_fit(struct mesh *m, float size);
/* Applies p' = R p + t to positions and R to normals (R row-major 3x3). */
void mesh_transform(struct mesh *m, const double R[9], const double t[3]);

/* --- meshio.c: PLY and OBJ --- */
int mesh_load(const char *path, struct mesh *m, char *err, size_t errlen);

/* --- texture.c --- */
int rtex_load_png(const char *path, bool srgb, struct rtex **ret);
/* A lat-long environment map: PFM, or PNG taken as linear. Returns 0 or -errno. */
int rtex_load_env(const char *path, struct rtex **ret);
struct rtex *rtex_free(struct rtex *t);
void rtex_sample(const struct rtex *t, float u, float v, float out[3]);

/* --- board.c --- */
/* Albedo of the board at board-frame point (x, y), box-filtered over the footprint
 * spanned by (dx0, dy0) and (dx1, dy1) (board-frame pixel footprint). */
float board_albedo(const struct board *b, float x, float y, const float fp[4]);
/* The 16 bits (row-major, 1 = white) of marker id of DICT_4X4_50; -EINVAL if out of range. */
int board_marker_bits(int id, uint16_t *bits);

/* --- camera.c --- */
/* Angle of the axis of role in p, 0 where the rig has none (NAN). */
double pose_deg(const struct gn_pose *p, enum gn_role role);
int camera_build(struct camera *c, const struct rig_camera_conf *cc);
void camera_free(struct camera *c);

/* --- light.c --- */
/* Sample point k of n of a lamp of radius r at p: a disc facing the origin. */
void lamp_sample(const double p[3], double r, int k, int n, double out[3]);
int dome_build(const struct dome *d, struct dome_el **ret, int *n);
/* Dome radiance (RGB) in world direction w (unit). */
void dome_radiance(const struct dome *d, const double w[3], double out[3]);

/* --- material.c --- */
void surf_eval(const struct rmat *m, float u, float v, struct surf *s);
/* f(l,v) * cos(theta_l) per channel; n, t unit; l, v unit towards light / viewer. */
void brdf_cos(const struct surf *s, struct v3 n, struct v3 t, struct v3 l, struct v3 v,
              float out[3]);
/* Anisotropic Beckmann NDF, seed 002 eq. 6, of a half vector with components hn (along
 * n), ht (along t), hb (along n x t). */
float beckmann_ndf(const struct surf *s, float hn, float ht, float hb);
/* The rest of the Beckmann lobe's f cos(theta_l) for ks = 1 (the NDF times this): the Smith
 * term, Schlick's Fresnel and 1 / (4 cos(theta_v)), for unit t, b, l, v, half vector h and
 * the cosines nl, nv (both positive). */
float beckmann_gf(const struct surf *s, struct v3 t, struct v3 b, struct v3 l, struct v3 v,
                  struct v3 h, float nl, float nv);
/* Weight of the perfect mirror reflection (0 for non-mirrors). */
float mirror_weight(const struct surf *s, float cos_v);
void rmat_free(struct rmat *m);

/* --- sensor.c --- */
/* Per-frame constants of the sensor model (sensor_setup). */
struct sensor_rt {
        const float *q; /* normal quantile table (sensor_table) */
        uint64_t key;   /* sensor_frame_key() */
        float k, b;     /* DN = electrons * k + b before rounding */
        float maxdn, full_well, read2;
        bool shot_noise;
        bool ideal; /* no noise */
};
void sensor_setup(struct sensor_rt *rt, const struct sensor *se, const float *q, uint64_t key,
                  double gain, int bits, bool ideal);
/* Allocates the table of normal quantiles (free()). Returns 0 or -ENOMEM. */
int sensor_table(float **ret);
uint64_t sensor_frame_key(uint64_t seed, uint64_t seq, uint32_t cam);
#define SENSOR_MAX_PIXELS 16
/* Digital numbers of n <= SENSOR_MAX_PIXELS pixels (indices pix) with nch channels each,
 * from electrons e[n * nch] into dn[n * nch]. */
void sensor_pixels(const struct sensor_rt *rt, const uint64_t *pix, const float *e, int n, int nch,
                   uint16_t *dn);
