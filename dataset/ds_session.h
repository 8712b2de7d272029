/* ds_session.h - capture sessions in a dataset: the start record and the whole plan of
 * a session, its state and stop record, the plan items still to capture (resume), dark
 * frames (ds_find_dark) and the data directory's dark library shared by its datasets
 * (ds_library_open), frames imported from another dataset, and the RTI light files
 * (.lp) of its views. The rows themselves are stored with ds_store (ds.h) with c->session and
 * c->plan_seq set: exactly once per plan item. Every function does blocking I/O (see
 * ds_forbid_thread); the records are SQLite transactions, so any handle of the dataset may write
 * them, the store's writer or a second handle. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/pose.h"
#include "ds.h"

/* One planned capture: what ds_plan_pending hands back for each item not yet captured. */
/* How far a row's angle may be from its plan item's (ds_check; the session runner refuses to
 * store a frame further away). Degrees; a string for SQL, a number for C. */
#define DS_PLAN_POSE_TOL_DEG_SQL "0.05"
#define DS_PLAN_POSE_TOL_DEG     0.05

struct ds_plan_item {
        int64_t seq;  /* >= 1, unique in the session */
        int64_t shot; /* items of one shot are exposed together */
        char camera[DS_NAME_MAX];
        char kind[8]; /* "image", "dark", "flat", "laser" ("" = "image") */
        int bracket;
        struct gn_pose pose; /* planned: NAN angles where no axis */
        int exposure_us;
        double gain;
};

/* A session's start and stop records, read back by ds_session_get. */
struct ds_session_info {
        char name[DS_NAME_MAX];
        char state[16];                /* "running", "paused", "done", "aborted", "failed" */
        char started[32], stopped[32]; /* ISO 8601 UTC; stopped "" while not ended */
        char reason[256];
        int64_t planned, captured; /* plan items; plan items with a capture row */
        char *file_text, *rig_text, *plan_json, *metadata_json; /* malloc'd */
};

/* Records a new session (state "running") and its whole plan in one transaction; any
 * text may be NULL (stored as ""). Returns 0, -EEXIST if the name exists, -EINVAL (a bad
 * name, an item with seq < 1, a duplicate seq, no camera or an unknown kind; nothing is
 * recorded) or -errno. */
int ds_session_begin(struct ds *d, const char *name, const char *file_text, const char *rig_text,
                     const char *plan_json, const char *metadata_json,
                     const struct ds_plan_item *items, size_t n);

/* Sets the state and reason (NULL: "") of session name; "done", "aborted" and "failed"
 * (the stop record) also set stopped, "running" and "paused" clear it. On the store's
 * writer, an ended session rewrites dataset.json before the state is committed (in its
 * transaction: a failed write leaves the state as it was). Returns 0, -ENOENT (no such session),
 * -EINVAL (unknown state) or -errno. */
int ds_session_set_state(struct ds *d, const char *name, const char *state, const char *reason);

/* Reads session name into out (its texts malloc'd; free with ds_session_info_clear).
 * Returns 0, -ENOENT or -errno. */
int ds_session_get(struct ds *d, const char *name, struct ds_session_info *out);

/* Frees the texts of s and zeroes it. NULL is a no-op. */
void ds_session_info_clear(struct ds_session_info *s);

/* The newest session whose state is running or paused (the one to resume): 0 with its
 * name in name (len bytes), -ENOENT if none, or -errno. */
int ds_session_unfinished(struct ds *d, char *name, size_t len);

/* Called for each pending plan item; it is valid during the call only. A negative return
 * stops the walk, which returns it. */
typedef int (*ds_plan_fn)(const struct ds_plan_item *it, void *userdata);

/* Calls fn for each plan item of session that has no capture row, in seq order. Returns
 * the count, fn's negative value, -ENOENT (no such session) or -errno. */
int ds_plan_pending(struct ds *d, const char *session, ds_plan_fn fn, void *userdata);

/* Dark frames: the newest row of kind "dark" of camera with exposure_us and gain
 * (within 1e-6) whose frame was exposed at or after not_before_ns (CLOCK_REALTIME).
 * Returns its row id, 0 if there is none, or -errno. */
int64_t ds_find_dark(struct ds *d, const char *camera, int exposure_us, double gain,
                     uint64_t not_before_ns);

/* The newest row of kind "flat" of camera: its row id, 0 if there is none, or -errno. */
int64_t ds_find_flat(struct ds *d, const char *camera);

/* Copies row src_id of src into dst as a new row: its file (hard-linked into dst's
 * images/ under dst's naming, or copied by the durable write of ds_store where the two
 * are on different file systems) and its pose, lamps, camera, exposure, gain, request and
 * exposure times, sha256, size, width, height and pixfmt; session, plan_seq, bracket,
 * dark_id and flat_id come from label, and so does the kind unless label->kind is "" (the
 * source's); the other fields of label are ignored. The file is read back (link) or
 * hashed as it is written (copy) once and must match the source row's sha256. A plan
 * item is stored exactly once as by ds_store (the recorded angles are the source's: those
 * of a plan item ds_check compares). src may be read by another process meanwhile; dst
 * becomes its writer. Returns the new row's id, -ENOENT (src has no row src_id), -EEXIST
 * (the plan item has its row), -EBADMSG (the file does not match its checksum), -EBUSY,
 * -EINVAL or -errno; on failure nothing is recorded and no file is left in dst
 * (ds_last_error(dst) tells why). */
int64_t ds_import_frame(struct ds *dst, struct ds *src, int64_t src_id,
                        const struct ds_capture *label);

/* The dark library of a data directory: the dataset DS_LIBRARY in it, shared by the
 * sessions of every dataset there. Its rows have session DS_LIBRARY_SESSION and no plan
 * item. */
#define DS_LIBRARY         "darks"
#define DS_LIBRARY_SESSION "library"

/* Opens <data_dir>/darks, creating it (no rig file) when it does not exist and create is
 * set. Find its frames with ds_find_dark, take them into a dataset with ds_import_frame.
 * Returns 0, -ENOENT (none and !create), -EBADMSG (not a dataset) or -errno. */
int ds_library_open(const char *data_dir, bool create, struct ds **ret);

/* Imports into the library lib every row of kind "dark" of session (NULL: of every
 * session) of src that lib lacks: a frame is in lib when lib has a dark row of the same
 * sha256, camera, exposure, gain and exposure time (so frames imported from the library
 * do not come back, and identical bytes taken at other settings or times are kept). lib
 * becomes the library's writer (held until ds_close: open, add, close). Returns the
 * number of rows added, -EINVAL (lib is src), or ds_import_frame's -errno (the rows
 * imported before stay: calling it again adds the rest). */
int ds_library_add_darks(struct ds *lib, struct ds *src, const char *session);

/* Computes the unit direction towards the lit lamp of capture c, in the object's frame
 * (rig geometry: the caller's), into dir. Returns 0, > 0 to leave c out of the file, or
 * a negative -errno that stops ds_write_lp. */
typedef int (*ds_light_dir_fn)(const struct ds_capture *c, double dir[3], void *userdata);

/* Writes the RTI light files of session: its rows of kind "image", bracket 0, with
 * exactly one lamp lit and the laser off, grouped by view (camera, turntable angle,
 * camera arm angle, from the plan item of the row, else the row, to 0.01 degree), one
 * file per view, lp/<session>/<camera>[_tt<deg>][_ca<deg>].lp, each written atomically:
 * the number of images, then one line "path dx dy dz" per image in id order, path
 * relative to the .lp file's directory. Returns the number of files written, or fn's
 * negative value, or -errno. */
int ds_write_lp(struct ds *d, const char *session, ds_light_dir_fn dir, void *userdata);
