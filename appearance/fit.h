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
