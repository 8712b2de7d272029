/* ds.h - the dataset store: a directory of lossless PNG images, an SQLite index
 * (WAL) with one row per capture, the rig file used, and dataset.json.
 *
 * Layout of a dataset directory:
 *   dataset.json          summary (name, created, rig, counts), rewritten on close
 *   index.sqlite          captures table (+ WAL files while open)
 *   rig.yaml              the rig file the captures were taken with
 *   images/NNNNNN_<camera>_<lamp>.png
 *
 * Every image is written to a temporary name, fsynced, renamed and its directory
 * fsynced before its row is committed, so a crash leaves no torn file and no row
 * without its image. A struct ds is used from one thread at a time (the storage
 * worker); ds_pool runs stores off the event loop. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/frame.h"
#include "common/pose.h"

struct ds;

#define DS_NAME_MAX 64

/* What the index records for one capture. */
struct ds_capture {
        int64_t id;                /* row id, set by ds_store */
        char session[DS_NAME_MAX]; /* may be empty */
        struct gn_pose pose;       /* angles NAN (NULL in the index) where the rig has no axis
                                    * of that role; lamp bit set by rig-file index; laser */
        char camera[DS_NAME_MAX];
        char lamps[256]; /* names of the lamps lit in pose, comma-separated, "" for none;
                          * written by the caller (gn_pose_lamp_list) */
        int exposure_us;
        double gain;
        uint64_t t_request_ns;  /* CLOCK_REALTIME when the capture was requested */
        uint64_t t_exposure_ns; /* frame timestamp */
        uint64_t t_stored_ns;   /* set by ds_store */
        char file[256];         /* relative to the dataset dir, set by ds_store */
        char sha256[65];        /* hex, set by ds_store */
        int width, height;
        char pixfmt[16]; /* "rgb8", "rgb16", "mono8", "mono16" */
};

/* Creates a new dataset directory at path (must not exist, parent must) and stores
 * rig_text as rig.yaml (NULL: no rig file). Returns 0, -EEXIST, or -errno; a failed
 * create removes what it made. */
int ds_create(const char *path, const char *name, const char *rig_text, struct ds **ret);

/* Opens an existing dataset for appending or reading. An index of schema 1 (angles
 * NOT NULL, no lamp bits) is migrated to the current schema in one transaction.
 * Returns 0, -ENOENT, -EBADMSG (not a dataset / corrupt index / unknown schema) or
 * -errno. */
int ds_open(const char *path, struct ds **ret);

/* Rewrites dataset.json (when this handle stored captures), closes the index. NULL is a
 * no-op. Returns NULL. */
struct ds *ds_close(struct ds *d);

/* Sets the zlib level (0-9) of the PNGs written by ds_store; the default is
 * DS_PNG_LEVEL_DEFAULT (1, fast). Returns 0 or -EINVAL. */
int ds_set_compression(struct ds *d, int level);

/* The zlib level set by ds_set_compression. */
int ds_get_compression(const struct ds *d);

/* Encodes frame as PNG, writes it atomically, computes its SHA-256 and commits the
 * row. Fills c->id, c->file, c->sha256, c->width, c->height, c->pixfmt, c->t_stored_ns.
 * Returns 0, -ENOSPC (nothing recorded, no file left behind), -EBUSY (another handle
 * is the dataset's writer), -EINVAL (the index refused the row: a constraint), or the
 * -errno of the failing call (-EFBIG, -EDQUOT...); ds_last_error() tells why. */
int ds_store(struct ds *d, const struct gn_frame *frame, struct ds_capture *c);

/* Like ds_store for an image already encoded with ds_png_encode (dataset/ds_png.h):
 * png holds len bytes encoding a frame of shape's width, height, channels and bits
 * (shape->data is not read). Lets ds_pool encode on several threads and write on one.
 * Same returns and effects as ds_store. */
int ds_store_png(struct ds *d, const void *png, size_t len, const struct gn_frame *shape,
                 struct ds_capture *c);

/* What the last failing call on d reported (SQLite's message, or the failing file
 * operation), "" if none yet. Valid until the next call on d; same thread as the call. */
const char *ds_last_error(const struct ds *d);

/* Number of rows. */
int64_t ds_count(struct ds *d);

/* Calls fn for each row in id order; stops early and returns fn's value if negative. */
int ds_foreach(struct ds *d, int (*fn)(const struct ds_capture *c, void *ud), void *ud);

/* Reads an image of the dataset back (PNG decode) into out. Returns 0 or -errno. */
int ds_load_image(struct ds *d, const char *file, struct gn_frame *out);

/* Re-hashes every file and checks it against its row; returns the number of
 * mismatching or missing files (0 = consistent) or -errno. */
int ds_verify(struct ds *d);

/* The dataset's absolute directory and name; valid until ds_close. */
const char *ds_path(const struct ds *d);
const char *ds_name(const struct ds *d);
