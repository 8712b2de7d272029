/* fit_internal.h - what the parts of the fit share (fit.c: rows to views and lights, the
 * model; fit_geom.c: cameras, lamps and the surface point of each tile; fit_view.c: one
 * view's images to SH coefficients; fit_pca.c: the PCA). Private to appearance/. */
#pragma once

#include <pthread.h>
#include <stdbool.h>

#include "appearance/fit.h"

/* One light of a view: a lamp at a light-arm angle, its rows (brackets) in the view. */
struct fit_light {
        int lamp;        /* rig index */
        double arm_deg;  /* NAN: no light arm */
        double pos[3];   /* the lamp in the object frame of the view's turntable angle, mm */
        double scale;    /* intensity / the model's reference intensity */
        size_t first, n; /* rows view->rows[first .. first + n) */
};

/* One view: camera, turntable and camera-arm angles, its camera model, rows and lights. */
struct fit_view {
        int cam; /* rig index */
        double tt_deg, arm_deg;
        struct ap_camera geom;
        double dir[3];                  /* unit, object centre towards the camera */
        const struct ds_capture **rows; /* image rows sorted by light, then bracket */
        size_t n_rows;
        struct fit_light *lights;
        size_t n_lights;
        float *points; /* 3 per tile: the tile's surface point (object frame); NAN: none */
        bool pilot;    /* its coefficient vectors feed the PCA's sample */
        float *kept;   /* its vectors (3M each) kept: a pilot's, or solved before the basis */
        uint32_t *kept_pix;
        size_t n_kept;
        size_t n_sat; /* pixels masked for a saturated sample */
};

/* A triangle mesh in the object frame (read from a PLY file). */
struct fit_mesh {
        float *v; /* 3 per vertex */
        uint32_t *tri;
        size_t n_v, n_tri;
};

/* A worker's buffers, kept from one view to the next (fit_view). */
struct fit_scratch;

struct fit_ctx {
        const struct ap_fit_opts *o;
        const char *dir; /* the dataset's */
        struct rig_config *rc;
        struct ds_capture *all; /* every row, id order */
        size_t n_all;
        struct fit_view *views;
        size_t n_views;
        struct fit_mesh mesh; /* n_tri 0: none */
        int order, M;
        double exposure_ref, gain_ref, d_ref, i_ref;
        struct ap_model *model;
        pthread_mutex_t lock;
        size_t n_sample; /* the PCA's sample: vectors (fit_pca) */
        size_t stride;   /* one masked pixel in `stride` of a pilot view is sampled */
        double sse_sh;   /* the SH fit's squared residuals over the sampled pixels */
        size_t n_sse;
        size_t masked_saturated;         /* pixels masked for a saturated sample */
        double cond_max;                 /* the worst condition number of a tile's solve */
        struct fit_scratch *scratch[16]; /* each worker's buffers (fit.c's run_views) */
        char notes[1024];                /* fit_note's sentences, for the model's notes */
        char err[512];                   /* the first worker's error */
        int error;
};

/* Appends a sentence to the model's notes ("; "-separated). */
void fit_note(struct fit_ctx *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Records the first worker error r with its sentence (thread-safe). Returns r. */
int fit_fail(struct fit_ctx *c, int r, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Cameras and lamps of every view from the calibration (o->calibration or the dataset's
 * calibration.yaml) or the rig file's nominal geometry, stated in the notes; the reference
 * distance and intensity. Returns 0 or -EBADMSG/-errno with c->err. */
int fit_geometry(struct fit_ctx *c);

/* The point of camera g's optical axis nearest the turntable axis (the object's centre), in
 * the object frame. */
void fit_camera_centre(const struct ap_camera *g, double c0[3]);

/* The point of pixel uv's ray of camera g (distortion undone) nearest c0 (object frame):
 * where the fit places a surface it has no mesh for. */
void fit_nominal_point(const struct ap_camera *g, const double c0[3], const double uv[2],
                       double X[3]);

/* Reads the mesh (o->mesh, else the dataset's mesh.ply when there is one) into c->mesh.
 * Returns 0, or -EBADMSG/-errno with c->err. */
int fit_mesh_read(struct fit_ctx *c);

/* Fills v->points: each tile's surface point, from the mesh when there is one and it is seen
 * at the tile's centre, else the point of the tile's centre ray nearest the object's centre.
 * Returns 0 or -ENOMEM. */
int fit_tile_points(const struct fit_ctx *c, struct fit_view *v);

/* Decodes the image of row r (its file in dataset directory dir) into f. Returns 0 or -errno
 * with "PATH: reason" in err. Any thread. */
int fit_read_image(const char *dir, const struct ds_capture *r, struct gn_frame *f, char *err,
                   size_t errlen);

/* Frees s. NULL is a no-op. */
void fit_scratch_free(struct fit_scratch *s);

/* Fits view i: its images (merged, dark subtracted, normalised) to coefficient vectors of
 * its masked pixels, held in *s (the calling worker's buffers; NULL: allocated here, free
 * with fit_scratch_free) until fit_view_keep or fit_view_project; a pilot view's residuals
 * added to c. Returns 0 or -errno (with c->err when it has a sentence). Any thread, one *s
 * per thread. */
int fit_view_solve(struct fit_ctx *c, size_t i, struct fit_scratch **s);

/* Moves the vectors of view i held in s into the view (v->kept), for fit_pca's sample or
 * for projecting once the basis is known. Any thread. */
void fit_view_keep(struct fit_ctx *c, size_t i, struct fit_scratch *s);

/* Projects the vectors of view i (kept in the view, else held in s) on the model's basis
 * into the model's view i; frees the kept ones. Returns 0 or -ENOMEM. Any thread. */
int fit_view_project(struct fit_ctx *c, size_t i, struct fit_scratch *s);

/* Mean and K principal components into the model of the sample: every c->stride-th vector
 * kept by each pilot view, in view order (c->n_sample); c->model->rms_pca. Returns 0,
 * -ENODATA (fewer vectors than 2) or -ENOMEM. */
int fit_pca(struct fit_ctx *c);

/* Projects n coefficient vectors coef (n x 3M) on the model's basis into w (n x K): one
 * product. */
void fit_pca_project(const struct ap_model *m, const float *coef, size_t n, float *w);

/* Frees the mesh's arrays. */
void fit_mesh_free(struct fit_mesh *m);
