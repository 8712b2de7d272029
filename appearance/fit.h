/* fit.h - the appearance model of a dataset (seed 001, section 4; model.h): per view
 * (camera, turntable angle, camera-arm angle) and pixel, the light-dependent values fitted
 * with real SH of order P by one regularised least-squares solve per tile of pixels (the
 * light directions and distances from the tile's surface point: the dataset's scan mesh,
 * else the nominal object point) and one matrix product per tile; brackets merged and dark
 * frames subtracted first; the coefficient vectors compressed by PCA with K components fitted
 * on a sample. Views in parallel. Reads the dataset through the dataset library only.
 * docs/appearance.md, "The fit". */
#pragma once

#include <stddef.h>

#include "appearance/model.h"
#include "common/rigconf.h"
#include "dataset/ds.h"

#define AP_ORDER_DEFAULT  6
#define AP_K_DEFAULT      12
#define AP_SAMPLE_DEFAULT 0.01
#define AP_TILE_DEFAULT   16

/* The regularisation of the per-tile solve (docs/appearance.md, "Regularisation"). */
enum ap_reg {
        AP_REG_TIKHONOV, /* lambda = param x the largest singular value */
        AP_REG_TSVD,     /* singular values below param x the largest dropped */
};

struct ap_fit_opts {
        const char *name; /* the model's name (models/<name>), default "default" */
        int order;        /* P, 1..AP_ORDER_MAX */
        int k;            /* K, 1..AP_K_MAX (at most 3 P^2) */
        double sample;    /* fraction of the coefficient vectors the PCA is fitted on */
        enum ap_reg reg;
        double reg_param;        /* < 0: the default of reg */
        int tile;                /* pixels per tile side, 1..64 */
        int threads;             /* views fitted at once, 1..16 */
        double background;       /* a pixel below this (full scale 1) in every light is masked */
        double saturation;       /* a raw sample at or above this (full scale 1) is saturated */
        const char *calibration; /* a calibration file; NULL: the dataset's calibration.yaml
                                  * when there is one; "nominal": the rig file's geometry */
        const char *mesh;        /* a PLY mesh (calib/ply.h's format) in the object frame;
                                  * NULL: the dataset's mesh.ply when there is one */
        const struct rig_backend *const *backends; /* to read the dataset's rig.yaml */
};

/* Fills o with the defaults above: name "default", Tikhonov with its default, 2 threads,
 * background 0.01, saturation 0.995, backends NULL (the caller sets them). Never fails. */
void ap_fit_opts_default(struct ap_fit_opts *o);

/* Fits the model of dataset d with o into *ret (free with ap_model_free; not written: see
 * ap_model_write). Fallbacks taken (a lower order, nominal geometry, views skipped,
 * ill-conditioned lights regularised, pixels masked) are stated in (*ret)->notes. Returns 0
 * or -EINVAL (bad options), -ENOENT (no rig file), -ENODATA (no lamp-lit image rows, no
 * lamps, no view with enough lights), -EBADMSG (a malformed calibration or mesh file),
 * -ENOMEM or the -errno of reading the dataset, with a sentence in err. Call from one thread;
 * uses o->threads more. */
int ap_fit(struct ds *d, const struct ap_fit_opts *o, struct ap_model **ret, char *err,
           size_t errlen);

/* The regularised pseudo-inverse of the L x M matrix A (row-major, rows = lights) into pinv
 * (M x L, row-major, float), from the eigen-decomposition of A^T A (the singular values
 * squared): Tikhonov or truncated SVD with param relative to the largest singular value.
 * *cond (may be NULL) gets the largest over the smallest singular value (1e8 at most: the
 * smaller ones are lost in the squares' rounding). Returns 0, -EINVAL
 * or -EDOM (LAPACK failed). Any thread. */
int ap_fit_pinv(const double *A, int L, int M, enum ap_reg reg, double param, float *pinv,
                double *cond);

/* The default parameter of reg (docs/appearance.md, "Regularisation"). */
double ap_fit_reg_default(enum ap_reg reg);

/* One lamp-lit image of a dataset placed in the object frame (ap_geometry_read). */
struct ap_shot {
        const struct ds_capture *row; /* its index row (in the geometry's rows) */
        size_t view;                  /* its view: cameras[view] */
        int cam;                      /* the rig's camera index */
        double lamp[3];               /* the lit lamp in the object frame, mm */
        double intensity;             /* the lamp's intensity (rig units; 1 when unset) */
};

/* The geometry of a dataset's lamp-lit images, as the fit places them (docs/exports.md). */
struct ap_geometry {
        struct rig_config *rc;
        struct ds_capture *rows; /* every index row */
        size_t n_rows;
        struct ap_camera *cameras; /* one per view (camera, turntable and camera-arm angle) */
        size_t n_views;
        struct ap_shot *shots; /* one per lamp-lit image row, grouped by view */
        size_t n_shots;
        char notes[1024]; /* the fallbacks taken (nominal geometry...), "" none */
};

/* The cameras (intrinsics, distortion, pose in the object frame) and lamp positions of every
 * lamp-lit image of d, from calibration (a calibration file, "nominal", or NULL: the
 * dataset's calibration.yaml when there is one) exactly as ap_fit places them; backends read
 * the dataset's rig.yaml. Returns 0 or -ENOENT (no rig file), -ENODATA (no lamp-lit image),
 * -EBADMSG (a malformed calibration file) or -errno, with a sentence in err. */
int ap_geometry_read(struct ds *d, const char *calibration,
                     const struct rig_backend *const *backends, struct ap_geometry **ret, char *err,
                     size_t errlen);

/* Frees g. NULL is a no-op. Returns NULL. */
struct ap_geometry *ap_geometry_free(struct ap_geometry *g);
