/* model.h - the appearance model of seed 001 (section 4): per view i_v and pixel (s, t),
 * the light-dependent radiance T(i_v, l, s, t, c) projected onto real spherical harmonics
 * of order P (M = P^2 coefficients per colour), the 3M-vectors compressed by PCA:
 *
 *     T(i_v, l, s, t, c) ~= sum_m Y_m(l) (mean[m, c] + sum_k W_k(i_v, s, t) b_k[m, c])
 *
 * This header is the contract between the fit (fit.h), the file layout (model_io.c,
 * docs/appearance.md) and the renderers (render.h). Directions are unit vectors in the
 * object frame (the world frame at turntable angle 0, z up the turntable axis, mm).
 *
 * On disk, inside a dataset: models/<name>/
 *   model.json           order, K, colour space, the views (camera model and pose, size,
 *                        weight scales), the fallbacks taken, the fit's residual figures
 *   basis.f32            (K + 1) x 3M little-endian float32: row 0 the mean, rows 1..K the
 *                        components; index m * 3 + c inside a row
 *   views/NNN_wG.png     weights of view NNN, components 4G..4G+3 as RGBA 16-bit, each
 *                        sample = round((W - offset[k]) / scale[k]), 0..65535
 *   views/NNN_mask.png   mono 8-bit, 255 where the object is and the fit holds
 *
 * Units: T is the linear pixel value (1 = the camera's full scale at the dataset's base
 * exposure, dark frame subtracted) under a light from direction l of the irradiance that a
 * lamp of intensity light_intensity at light_distance_mm gives (a directional light). A point
 * light of intensity I at distance r from the surface point scales it by
 * (I / light_intensity) (light_distance_mm / r)^2. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define AP_ORDER_MAX 10 /* P: bands 0..P-1, M = P^2 */
#define AP_K_MAX     32
#define AP_NAME_MAX  64

/* A pinhole camera with OpenCV distortion (k1 k2 p1 p2 k3), x_cam = R x_obj + t. */
struct ap_camera {
        int width, height;
        double fx, fy, cx, cy;
        double dist[5];
        double R[9], t[3]; /* object frame to camera frame (OpenCV: x right, y down, z ahead) */
};

/* Projects object point x (mm) with camera g into pixel uv (the centre of the top-left pixel
 * at 0, 0); *z (may be NULL) gets its depth. Returns false for a point behind the camera. */
bool ap_camera_project(const struct ap_camera *g, const double x[3], double uv[2], double *z);

/* One sampled view direction: its camera and its weight images. */
struct ap_view {
        char camera[AP_NAME_MAX];             /* the rig's camera name */
        double turntable_deg, camera_arm_deg; /* NAN where the rig has no such axis */
        struct ap_camera cam;
        double dir[3];  /* unit, object centre towards the camera */
        float *weights; /* K per pixel, pixel-major: [(y * width + x) * K + k] */
        uint8_t *mask;  /* width * height, 1 where the model holds */
        float scale[AP_K_MAX], offset[AP_K_MAX]; /* quantisation of the weight PNGs */
};

struct ap_model {
        char name[AP_NAME_MAX];
        int order;    /* P */
        int n_coef;   /* M = P^2 */
        int k;        /* K principal components */
        float *mean;  /* 3M */
        float *basis; /* K x 3M, row-major */
        size_t n_views;
        struct ap_view *views;
        char notes[1024]; /* fallbacks taken by the fit, stated for the user ("" none) */
        double light_distance_mm, light_intensity; /* the light T is relative to (Units) */
        char reg[16];       /* the fit's regularisation: "tikhonov" or "tsvd" */
        double reg_param;   /* its lambda (relative to the largest singular value) or the
                             * relative cut-off of the singular values */
        double rms_sh;      /* RMS of the SH fit's residual over the masked samples */
        double rms_pca;     /* RMS of the PCA's residual on the coefficient vectors */
        double fit_seconds; /* wall time of the fit */
};

/* Number of coefficients of order P (P^2). */
static inline int ap_n_coef(int order)
{
        return order * order;
}

/* A zeroed model of order P, K components and n_views views (views' arrays not allocated:
 * ap_view_alloc), mean and basis allocated. Returns 0, -EINVAL or -ENOMEM. */
int ap_model_new(int order, int k, size_t n_views, struct ap_model **ret);

/* Allocates v's weights (K per pixel, zero) and mask (zero) for v->cam's size. Returns 0,
 * -EINVAL (no size) or -ENOMEM; ap_model_free frees them. */
int ap_view_alloc(struct ap_view *v, int k);

/* The range [lo, hi] of component k of v's weights (K a pixel) over its masked pixels; 0, 0
 * when none is masked in. */
void ap_view_range(const struct ap_view *v, int K, int k, float *lo, float *hi);

/* Frees m's arrays and m itself. NULL is a no-op. Returns NULL. */
struct ap_model *ap_model_free(struct ap_model *m);

/* Writes m as models/<m->name>/ of the dataset directory ds_dir, atomically (a temporary
 * directory renamed into place). Returns 0 or -errno. */
int ap_model_write(const struct ap_model *m, const char *ds_dir);

/* The dataset directory of model directory dir (DATASET/models/NAME: two levels up, made
 * absolute where it exists) into out. */
void ap_model_dataset(const char *dir, char *out, size_t len);

/* Removes directory path and everything in it (errors ignored: a temporary folder). */
void ap_remove_tree(const char *path);

/* Reads the model in directory dir (models/<name>/ of a dataset). On a malformed file
 * returns -EBADMSG with a sentence naming the file and the problem in err. Returns 0,
 * -ENOENT or -errno. */
int ap_model_read(const char *dir, struct ap_model **ret, char *err, size_t errlen);
