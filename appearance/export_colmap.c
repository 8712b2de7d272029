/* export_colmap.c - the dataset as a COLMAP text model (export.h, docs/exports.md):
 * cameras.txt (one camera per rig camera: OPENCV, or FULL_OPENCV when k3 is not 0),
 * images.txt (each lamp-lit image's world-to-camera rotation as a quaternion and its
 * translation, the object frame as COLMAP's world, mm), points3D.txt (the scan's cloud,
 * without tracks; empty without a scan), images/ (the dataset's images linked). COLMAP's
 * pixel centres are at +0.5: its cx, cy are gonio's + 0.5. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/export_internal.h"
#include "calib/scan.h"
#include "common/cleanup.h"

/* The unit quaternion (w x y z, w >= 0) of rotation matrix R (row-major). */
static void quaternion(const double R[9], double q[4])
{
        double tr = R[0] + R[4] + R[8], s;

        if (tr > 0) {
                s = 2 * sqrt(tr + 1);
                q[0] = s / 4, q[1] = (R[7] - R[5]) / s, q[2] = (R[2] - R[6]) / s,
                q[3] = (R[3] - R[1]) / s;
        } else if (R[0] > R[4] && R[0] > R[8]) {
                s = 2 * sqrt(1 + R[0] - R[4] - R[8]);
                q[0] = (R[7] - R[5]) / s, q[1] = s / 4, q[2] = (R[1] + R[3]) / s,
                q[3] = (R[2] + R[6]) / s;
        } else if (R[4] > R[8]) {
                s = 2 * sqrt(1 + R[4] - R[0] - R[8]);
                q[0] = (R[2] - R[6]) / s, q[1] = (R[1] + R[3]) / s, q[2] = s / 4,
                q[3] = (R[5] + R[7]) / s;
        } else {
                s = 2 * sqrt(1 + R[8] - R[0] - R[4]);
                q[0] = (R[3] - R[1]) / s, q[1] = (R[2] + R[6]) / s, q[2] = (R[5] + R[7]) / s,
                q[3] = s / 4;
        }
        if (q[0] < 0)
                for (int k = 0; k < 4; k++)
                        q[k] = -q[k];
}

/* The camera of the first image of rig camera c, or NULL when c has no image. */
static const struct ap_camera *first_camera(const struct ap_geometry *g, size_t c)
{
        for (size_t v = 0; v < g->n_shots; v++)
                if (g->shots[v].cam == (int)c)
                        return &g->cameras[g->shots[v].view];
        return NULL;
}

/* cameras.txt: one line per rig camera with images (the header counts those lines). */
static int write_cameras(const struct ap_geometry *g, const char *dir, char *err, size_t errlen)
{
        FILE *f = exp_open(dir, "cameras.txt", err, errlen);
        size_t n = 0;

        if (!f)
                return -errno;
        for (size_t c = 0; c < g->rc->n_cameras; c++)
                n += first_camera(g, c) != NULL;
        fprintf(f,
                "# Camera list with one line of data per camera:\n"
                "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
                "# Number of cameras: %zu\n",
                n);
        for (size_t c = 0; c < g->rc->n_cameras; c++) {
                const struct ap_camera *k = first_camera(g, c);
                if (!k)
                        continue;
                fprintf(f, "%zu %s %d %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g", c + 1,
                        k->dist[4] != 0 ? "FULL_OPENCV" : "OPENCV", k->width, k->height, k->fx,
                        k->fy, k->cx + 0.5, k->cy + 0.5, k->dist[0], k->dist[1], k->dist[2],
                        k->dist[3]);
                if (k->dist[4] != 0)
                        fprintf(f, " %.17g 0 0 0", k->dist[4]);
                fputc('\n', f);
        }
        return exp_close(f, "cameras.txt", err, errlen);
}

static int write_images(const struct ap_geometry *g, const char *dir, char *err, size_t errlen)
{
        FILE *f = exp_open(dir, "images.txt", err, errlen);

        if (!f)
                return -errno;
        fprintf(f,
                "# Image list with two lines of data per image:\n"
                "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
                "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
                "# Number of images: %zu, mean observations per image: 0\n",
                g->n_shots);
        for (size_t i = 0; i < g->n_shots; i++) {
                const struct ap_camera *k = &g->cameras[g->shots[i].view];
                double q[4];
                quaternion(k->R, q);
                fprintf(f, "%zu %.17g %.17g %.17g %.17g %.17g %.17g %.17g %d %s\n\n", i + 1, q[0],
                        q[1], q[2], q[3], k->t[0], k->t[1], k->t[2], g->shots[i].cam + 1,
                        exp_image_name(g->shots[i].row));
        }
        return exp_close(f, "images.txt", err, errlen);
}

/* points3D.txt from the scan's cloud (no tracks); empty when the dataset has no scan. */
static int write_points(const char *ds_dir, const char *dir, char *err, size_t errlen)
{
        struct exp_cloud c;
        char path[4200];
        FILE *f;
        int r;

        snprintf(path, sizeof(path), "%s/%s", ds_dir, SCAN_FILE_POINTS);
        r = exp_cloud_read(path, &c, err, errlen);
        if (r < 0 && r != -ENOENT)
                return r;
        f = exp_open(dir, "points3D.txt", err, errlen);
        if (!f) {
                exp_cloud_free(&c);
                return -errno;
        }
        fprintf(f,
                "# 3D point list with one line of data per point:\n"
                "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, "
                "POINT2D_IDX)\n"
                "# Number of points: %zu, mean track length: 0\n",
                c.n_points);
        for (size_t i = 0; i < c.n_points; i++)
                fprintf(f, "%zu %.9g %.9g %.9g %d %d %d 0\n", i + 1, c.x[3 * i], c.x[3 * i + 1],
                        c.x[3 * i + 2], c.rgb[3 * i], c.rgb[3 * i + 1], c.rgb[3 * i + 2]);
        exp_cloud_free(&c);
        return exp_close(f, "points3D.txt", err, errlen);
}

int ap_export_colmap(struct ds *d, const char *ds_dir, const char *dir,
                     const struct ap_export_opts *o, char *err, size_t errlen)
{
        _cleanup_(ap_geometry_freep) struct ap_geometry *g = NULL;
        int r = exp_geometry(d, o, &g, err, errlen);

        if (r == 0)
                r = write_cameras(g, dir, err, errlen);
        if (r == 0)
                r = write_images(g, dir, err, errlen);
        if (r == 0)
                r = write_points(ds_dir, dir, err, errlen);
        if (r == 0)
                r = exp_link_images(g, ds_dir, dir, err, errlen);
        return r;
}
