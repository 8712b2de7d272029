/* export_internal.h - what the exporters (export_*.c) share: the dataset's geometry, its
 * images linked into the export, the scan's point cloud read back. Private to appearance/. */
#pragma once

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "appearance/export.h"
#include "appearance/fit.h"
#include "common/cleanup.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_geometry *, ap_geometry_free);

/* Opens dir/name for writing, or NULL (errno set) with a sentence in err. */
FILE *exp_open(const char *dir, const char *name, char *err, size_t errlen);

/* Closes f (dir's file name), flushed and synced. Returns 0 or -EIO with a sentence in err. */
int exp_close(FILE *f, const char *name, char *err, size_t errlen);

/* The scan's points (calib/ply.h's vertex layout). */
struct exp_cloud {
        float *x, *n; /* 3 per point: position (mm, object frame), unit normal */
        uint8_t *rgb; /* 3 per point */
        size_t n_points;
};

/* The geometry of d's lamp-lit images with o's calibration (ap_geometry_read). Returns 0 or
 * -errno with a sentence in err. */
int exp_geometry(struct ds *d, const struct ap_export_opts *o, struct ap_geometry **ret, char *err,
                 size_t errlen);

/* Links (hard, else symbolic) every shot's image of g from ds_dir into dir/images/ under
 * its file's base name. Returns 0 or -errno with a sentence in err. */
int exp_link_images(const struct ap_geometry *g, const char *ds_dir, const char *dir, char *err,
                    size_t errlen);

/* The base name of a row's file ("images/000001_cam_lamp.png" -> "000001_cam_lamp.png"). */
const char *exp_image_name(const struct ds_capture *row);

/* Reads the vertices of the PLY file at path (calib/ply.h's binary layout) into c. Returns
 * 0, -ENOENT, -EBADMSG (another layout) or -ENOMEM, with a sentence in err. */
int exp_cloud_read(const char *path, struct exp_cloud *c, char *err, size_t errlen);

/* Frees c's arrays. */
void exp_cloud_free(struct exp_cloud *c);
