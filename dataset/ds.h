/* ds.h - the dataset library (gn_dataset): a directory of lossless PNG images, an
 * SQLite index (WAL) with one row per capture, the rig file used, and dataset.json;
 * used by goniod and, offline, by calibration, the appearance fit and the exporters.
 * It never touches devices.
 *
 * Layout of a dataset directory:
 *   dataset.json          summary (name, created, rig, counts, sessions), rewritten on close
 *   index.sqlite          captures, names, sessions and plan tables (+ WAL files while open)
 *   rig.yaml              the rig file the captures were taken with
 *   images/NNNNNN_<camera>_<lamp>.png
 *   lp/<session>/<view>.lp  light directions per view (ds_session.h)
 *
 * Every image is written to a temporary name, fsynced, renamed and its directory
 * fsynced before its row is committed, so a crash leaves no torn file and no row
 * without its image. Readers use the read API (ds_summary, ds_rows, ds_rows_by_pose)
 * and never parse dataset.json or walk the whole index themselves. Every function but the accessors
 * does blocking I/O: call it from a worker (see ds_forbid_thread). A struct ds is used from one
 * thread at a time; ds_pool (ds_pool.h) stores frames off the event loop. */
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
                                    * of that role; lamp and laser bit sets by rig-file
                                    * index (index column laser: 0/1 rows of datasets from
                                    * one-laser rigs read as laser 0) */
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
        char pixfmt[16];          /* "rgb8", "rgb16", "mono8", "mono16" */
        int64_t plan_seq;         /* the session's plan item this row captures; 0: none (a capture
                                   * outside sessions). At most one row per (session, plan_seq). */
        char kind[8];             /* "image", "dark", "flat", "laser"; "" is stored as "image" */
        int bracket;              /* HDR bracket index, 0 for the base exposure */
        int64_t dark_id, flat_id; /* row ids of the dark and flat frames to apply; 0: none */
        int64_t size;             /* bytes of the file, set by ds_store; 0: not recorded
                                   * (rows older than schema 4) */
};

/* Creates a new dataset directory at path (must not exist, parent must) and stores
 * rig_text as rig.yaml (NULL: no rig file). Returns 0, -EEXIST, or -errno; a failed
 * create removes what it made. */
int ds_create(const char *path, const char *name, const char *rig_text, struct ds **ret);

/* Opens an existing dataset for appending or reading. An index of an older schema (1:
 * angles NOT NULL, no lamp bits; 2: no names table; 3: no sessions) is migrated to the current one
 * in one transaction (docs/dataset.md). Returns 0, -ENOENT, -EBADMSG (not a dataset / corrupt index
 * / unknown schema) or -errno. */
int ds_open(const char *path, struct ds **ret);

/* Makes d the dataset's writer now rather than at its first store: takes the directory's
 * lock and removes what an interrupted store or write left (images without a row, *.tmp in
 * images/, the top directory and lp/SESSION/), so that a dataset reopened after a crash is
 * clean before anything else runs. Returns 0, -EBUSY (another process writes it) or -errno. */
int ds_claim(struct ds *d);

/* Rewrites dataset.json (when this handle stored captures), closes the index. NULL is a
 * no-op. Returns NULL. */
struct ds *ds_close(struct ds *d);

/* Sets the zlib level (0-9) of the PNGs written by ds_store; the default is
 * DS_PNG_LEVEL_DEFAULT (1, fast). Returns 0 or -EINVAL. */
int ds_set_compression(struct ds *d, int level);

/* The zlib level set by ds_set_compression. */
int ds_get_compression(const struct ds *d);

/* Encodes frame as PNG, writes it atomically, computes its SHA-256 and commits the
 * row. Fills c->id, c->file, c->sha256, c->size, c->width, c->height, c->pixfmt, c->t_stored_ns
 * (and c->kind "image" when empty). A row of a plan item (c->plan_seq > 0) is stored
 * exactly once: -EEXIST when (c->session, c->plan_seq) has its row already, checked
 * before any file is written. Returns 0, -EEXIST, -ENOSPC (nothing recorded, no file left
 * behind), -EBUSY (another handle is the dataset's writer), -EINVAL (an unknown kind, a
 * plan item the session does not have, or the index refused the row: a constraint), or
 * the -errno of the failing call (-EFBIG, -EDQUOT...); ds_last_error() tells why. Nothing
 * is recorded and no file is left behind on any failure. */
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

/* Marks (true) or unmarks the calling thread as one that must never wait for dataset
 * I/O: goniod's event loop while it serves. In builds with assertions, every ds_
 * function that touches files or the index (create, open, close, store, count,
 * summary, rows, load, verify) aborts when called on a marked thread; without them,
 * nothing is checked. The mark is per thread. */
void ds_forbid_thread(bool forbid);

/* Number of rows (from the per-camera counts: no scan). Returns >= 0 or -errno. */
int64_t ds_count(struct ds *d);

/* The most names a summary lists per kind. */
#define DS_SUMMARY_MAX_NAMES 32

/* A camera or lamp name and the number of captures that name it. */
struct ds_name_count {
        char name[DS_NAME_MAX];
        int64_t captures;
};

/* A session of the dataset and how far it got (ds_session.h). */
struct ds_session_count {
        char name[DS_NAME_MAX];
        char state[16];
        int64_t planned, captured; /* plan items; plan items with a capture row */
};

/* What a dataset holds, read from its index (never from dataset.json). */
struct ds_summary {
        char name[DS_NAME_MAX];
        char created[32]; /* ISO 8601, UTC */
        char rig[64];     /* the rig's name, "" if unknown */
        int schema_version;
        int64_t captures; /* rows */
        int64_t last_id;  /* highest row id, 0 when empty */
        size_t n_cameras, n_lamps;
        struct ds_name_count cameras[DS_SUMMARY_MAX_NAMES]; /* by name; the first 32 */
        struct ds_name_count lamps[DS_SUMMARY_MAX_NAMES];
        size_t n_sessions;
        struct ds_session_count sessions[DS_SUMMARY_MAX_NAMES]; /* the 32 newest, oldest first */
};

/* Fills out from the index with a few indexed queries (cost independent of the number
 * of rows). Returns 0 or -errno. */
int ds_summary(struct ds *d, struct ds_summary *out);

/* Called for each row a query passes; c is valid during the call only. A negative
 * return stops the query, which returns it. */
typedef int (*ds_row_fn)(const struct ds_capture *c, void *userdata);

/* Calls fn for at most limit rows (limit < 0: all) whose id is above after_id, in id
 * order; SQLite reads only those (LIMIT on the primary key). Returns the number of rows
 * passed to fn, fn's negative value, or -errno. */
int ds_rows(struct ds *d, int64_t after_id, int limit, ds_row_fn fn, void *userdata);

/* Decides whether ds_rows_collect() keeps row c. */
typedef bool (*ds_keep_fn)(const struct ds_capture *c, void *userdata);

/* Collects the rows keep accepts (keep NULL: every row), in id order, into *rows (malloc'd,
 * the caller frees it; NULL when none) and their number into *n. Returns 0, -ENOMEM or the
 * -errno of the query (ds_last_error), with *rows NULL and *n 0. */
int ds_rows_collect(struct ds *d, ds_keep_fn keep, void *userdata, struct ds_capture **rows,
                    size_t *n);

/* Calls fn, in id order, for each row taken at the pose p: for each role p has (angle
 * not NAN), the row has an axis of that role within tol_deg of p's angle (modulo 360);
 * roles p lacks match any row. p's lamps and laser are not compared: the result is one
 * view under every lighting (filter on c->pose.lamps for one lamp). SQLite tests every
 * row (angles modulo 360 fit no index); only matching rows are decoded. Returns the
 * number of rows passed to fn, fn's negative value, -EINVAL (tol_deg < 0) or -errno. */
int ds_rows_by_pose(struct ds *d, const struct gn_pose *p, double tol_deg, ds_row_fn fn,
                    void *userdata);

/* Reads an image of the dataset back (PNG decode) into out. Returns 0 or -errno. */
int ds_load_image(struct ds *d, const char *file, struct gn_frame *out);

/* Checks every row's file: its size (when recorded) and its re-hashed checksum; returns
 * the number of mismatching or missing files (0 = consistent) or -errno. */
int ds_verify(struct ds *d);

/* Called by ds_check with one sentence describing one problem (naming its file, row or
 * plan item); valid during the call only. */
typedef void (*ds_problem_fn)(const char *problem, void *userdata);

/* Checks the whole dataset and calls fn (may be NULL) for each problem found: a row's
 * file missing, of another size or not matching its checksum (ds_verify), an image without a row, a
 * temporary file left, a plan item with several rows, a row disagreeing with its plan
 * item (camera, kind, bracket, lamps, laser, or an angle the plan has off by more than
 * 0.05 degrees) or naming none, a dark or flat reference to no such frame, a session's
 * counts not matching its rows, SQLite's integrity_check. Reads only: works on a
 * second handle while another process writes (a store in flight there is not a problem).
 * Returns the number of problems (0 = consistent) or -errno. */
int ds_check(struct ds *d, ds_problem_fn fn, void *userdata);

/* The dataset's absolute directory and name; valid until ds_close. */
const char *ds_path(const struct ds *d);
const char *ds_name(const struct ds *d);
