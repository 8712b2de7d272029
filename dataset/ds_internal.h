/* ds_internal.h - what the files of the dataset library share and nobody else sees:
 * the handle, the file names of a dataset directory, and the SQLite index layer
 * (ds_index.c). */
#pragma once

#include <assert.h>
#include <sqlite3.h>

#include "common/cleanup.h"
#include "ds.h"

#define DS_INDEX    "index.sqlite"
#define DS_JSON     "dataset.json"
#define DS_RIG      "rig.yaml"
#define DS_IMAGES   "images"
#define DS_FILE_MAX (1u << 31) /* largest image ds_load_image reads */

struct ds {
        char *path; /* absolute */
        char name[DS_NAME_MAX];
        char created[32];
        char rig[64];
        int dir_fd, img_fd;
        bool writer; /* holds the flock, orphans removed, next_id valid */
        int64_t next_id;
        int png_level;
        sqlite3 *db;
        sqlite3_stmt *insert, *add_name, *count_captured; /* prepared by the writer */
        char error[256];                                  /* ds_last_error() */
};

DEFINE_TRIVIAL_CLEANUP_FUNC(sqlite3_stmt *, sqlite3_finalize);

/* Set by ds_forbid_thread() on a thread that must not wait for dataset I/O. */
extern _Thread_local bool ds_thread_forbidden;

/* At the top of every ds_ function that does I/O (see ds_forbid_thread). */
#define DS_ASSERT_THREAD_ALLOWED()                                                                 \
        assert(!ds_thread_forbidden && "dataset I/O on a thread that must not block")

/* Records what failed for ds_last_error() and logs it with the dataset's path; returns r. */
int ds_fail(struct ds *d, int r, const char *fmt, ...) _printf_(3, 4);

/* ds_fail for an SQLite result code rc: maps it to -errno (the one place that does)
 * and records sqlite3_errmsg() after what. Returns the -errno. */
int ds_db_fail(struct ds *d, int rc, const char *what);

/* Prepares sql on d's index. Returns 0 or ds_db_fail's -errno. */
int ds_db_prepare(struct ds *d, const char *sql, sqlite3_stmt **ret);

/* Runs sql (one or more statements without results). Returns 0 or -errno. */
int ds_db_exec(struct ds *d, const char *sql);

/* Runs a query whose first row's first column is an integer. Returns 0 or -errno. */
int ds_db_int64(struct ds *d, const char *sql, int64_t *ret);

/* Reads meta[key] into out; -EBADMSG if absent. */
int ds_meta_get(struct ds *d, const char *key, char *out, size_t outlen);

/* Opens (create: creates with the current schema and meta name/created/rig from d)
 * index.sqlite in WAL mode, synchronous=NORMAL. An existing index of an older schema is
 * migrated. Returns 0, -EBADMSG (not a dataset, unknown schema) or -errno. */
int ds_db_open(struct ds *d, bool create);

/* The captures table of schema 3 (DS_V4_SQL adds the columns of schema 4); the angle of
 * an axis the rig does not have is NULL. */
#define DS_CAPTURES_TABLE(name)                                                                    \
        "CREATE TABLE " name " ("                                                                  \
        " id INTEGER PRIMARY KEY,"                                                                 \
        " session TEXT NOT NULL DEFAULT '',"                                                       \
        " turntable_deg REAL, light_arm_deg REAL, camera_arm_deg REAL,"                            \
        " camera TEXT NOT NULL, lamps TEXT NOT NULL, lamp_bits INTEGER NOT NULL DEFAULT 0,"        \
        " laser INTEGER NOT NULL,"                                                                 \
        " exposure_us INTEGER NOT NULL, gain REAL NOT NULL,"                                       \
        " t_request_ns INTEGER NOT NULL, t_exposure_ns INTEGER NOT NULL,"                          \
        " t_stored_ns INTEGER NOT NULL,"                                                           \
        " file TEXT NOT NULL UNIQUE, sha256 TEXT NOT NULL,"                                        \
        " width INTEGER NOT NULL, height INTEGER NOT NULL, pixfmt TEXT NOT NULL);"

#define DS_CAPTURES_POSE_INDEX                                                                     \
        "CREATE INDEX captures_pose ON captures"                                                   \
        " (session, turntable_deg, light_arm_deg, camera_arm_deg);"

/* Each camera ('camera') and lamp ('lamp') name with the number of rows naming it. */
#define DS_NAMES_TABLE                                                                             \
        "CREATE TABLE names (kind TEXT NOT NULL, name TEXT NOT NULL,"                              \
        " captures INTEGER NOT NULL, PRIMARY KEY (kind, name)) WITHOUT ROWID;"

/* Adds ?3 captures to the name ?2 of kind ?1. */
#define DS_ADD_NAME_SQL                                                                            \
        "INSERT INTO names (kind, name, captures) VALUES (?1, ?2, ?3)"                             \
        " ON CONFLICT (kind, name) DO UPDATE SET captures = captures + ?3"

/* Schema 3 -> 4: the session columns of captures (plan_seq NULL outside sessions; at
 * most one row per plan item), the file's size (NULL in older rows), the sessions (start and stop
 * records, captured counted in the transaction of each row) and their plans. */
#define DS_V4_SQL                                                                                  \
        "ALTER TABLE captures ADD COLUMN plan_seq INTEGER;"                                        \
        "ALTER TABLE captures ADD COLUMN kind TEXT NOT NULL DEFAULT 'image'"                       \
        " CHECK (kind IN ('image', 'dark', 'flat', 'laser'));"                                     \
        "ALTER TABLE captures ADD COLUMN bracket INTEGER NOT NULL DEFAULT 0;"                      \
        "ALTER TABLE captures ADD COLUMN dark_id INTEGER;"                                         \
        "ALTER TABLE captures ADD COLUMN flat_id INTEGER;"                                         \
        "ALTER TABLE captures ADD COLUMN size INTEGER;"                                            \
        "CREATE UNIQUE INDEX captures_plan ON captures (session, plan_seq)"                        \
        " WHERE plan_seq IS NOT NULL;"                                                             \
        "CREATE TABLE sessions (name TEXT PRIMARY KEY,"                                            \
        " state TEXT NOT NULL"                                                                     \
        " CHECK (state IN ('running', 'paused', 'done', 'aborted', 'failed')),"                    \
        " started TEXT NOT NULL, started_ns INTEGER NOT NULL, stopped TEXT NOT NULL DEFAULT '',"   \
        " reason TEXT NOT NULL DEFAULT '', file_text TEXT NOT NULL, rig_text TEXT NOT NULL,"       \
        " plan_json TEXT NOT NULL, metadata_json TEXT NOT NULL,"                                   \
        " planned INTEGER NOT NULL, captured INTEGER NOT NULL DEFAULT 0);"                         \
        "CREATE TABLE plan (session TEXT NOT NULL, seq INTEGER NOT NULL CHECK (seq >= 1),"         \
        " shot INTEGER NOT NULL, camera TEXT NOT NULL, kind TEXT NOT NULL,"                        \
        " bracket INTEGER NOT NULL,"                                                               \
        " turntable_deg REAL, light_arm_deg REAL, camera_arm_deg REAL,"                            \
        " lamp_bits INTEGER NOT NULL, laser INTEGER NOT NULL,"                                     \
        " exposure_us INTEGER NOT NULL, gain REAL NOT NULL,"                                       \
        " PRIMARY KEY (session, seq)) WITHOUT ROWID;"

/* Runs s (prepared from DS_ADD_NAME_SQL) for kind and each name of the comma-separated
 * list, adding n. Returns 0 or -errno. */
int ds_db_add_names(struct ds *d, sqlite3_stmt *s, const char *kind, const char *list, int64_t n);

/* Brings an index of an older schema to DS_SCHEMA_VERSION in one transaction
 * (ds_migrate.c); a current one is left alone. Returns 0, -EBADMSG (unknown version) or
 * -errno. */
int ds_db_upgrade(struct ds *d);

/* Commits c's row, its camera and lamp names (for ds_summary) and, for a plan item, its
 * session's captured count in one transaction. Returns 0 or -errno; on failure nothing
 * is committed. Writer only. */
int ds_db_insert(struct ds *d, const struct ds_capture *c);

/* Prepares the writer's statements. Returns 0 or -errno. */
int ds_db_prepare_writer(struct ds *d);

/* The SELECT list of a full row, for ds_db_read_row. */
#define DS_ROW_COLUMNS                                                                             \
        "id, session, turntable_deg, light_arm_deg, camera_arm_deg, camera, lamps, lamp_bits, "    \
        "laser, exposure_us, gain, t_request_ns, t_exposure_ns, t_stored_ns, file, sha256, "       \
        "width, height, pixfmt, plan_seq, kind, bracket, dark_id, flat_id, size"

/* Binds the angles of p to parameters first.. (turntable, light arm, camera arm), NULL
 * where p has no axis. Returns SQLITE_OK or an SQLite error code. */
int ds_db_bind_angles(sqlite3_stmt *s, int first, const struct gn_pose *p);

/* Reads the angles of columns first.. (turntable, light arm, camera arm) into p, NAN for
 * NULL. */
void ds_db_column_angles(sqlite3_stmt *s, int first, struct gn_pose *p);

/* Copies text column col into out ("" for NULL), truncated to outlen. */
void ds_db_column_text(sqlite3_stmt *s, int col, char *out, size_t outlen);

/* Fills c from the current row of a statement selecting DS_ROW_COLUMNS. */
void ds_db_read_row(sqlite3_stmt *s, struct ds_capture *c);

/* The schema version this library writes (PRAGMA user_version). */
#define DS_SCHEMA_VERSION 4

/* Whether a row of (session, plan_seq) may be stored: 0, -EEXIST (the plan item has its
 * row: exactly once), -EINVAL (plan_seq > 0 without a session, or the session has no
 * such plan item) or -errno. Checked before the image is written. */
int ds_db_check_plan_item(struct ds *d, const struct ds_capture *c);

/* Stores the row c (c->sha256: the source's checksum; c->file, id, size, t_stored_ns set
 * here) with the image src_file below src_dir_fd as its file, hard-linked into images/ or,
 * where link(2) cannot (another file system), copied by ds_store's durable write; the
 * bytes must match c->sha256. Same exactly-once rules and writer as ds_store_png. Returns
 * 0, -EBADMSG (checksum mismatch), -EEXIST, -EINVAL or -errno; on failure nothing is
 * recorded and no file is left behind. */
int ds_import_file(struct ds *d, int src_dir_fd, const char *src_file, struct ds_capture *c);

/* Makes d the dataset's only writer (flock; orphans removed, next_id valid), as the first
 * store does. Returns 0, -EBUSY (another handle writes) or -errno. */
int ds_become_writer(struct ds *d);

/* True for the capture kinds of the index ("image", "dark", "flat", "laser"). */
bool ds_kind_ok(const char *kind);

/* Copies a name into a file-name part: ',' -> '+', other unsafe bytes -> '-'; an empty
 * name becomes empty (itself copied the same way). */
void ds_name_part(char *out, size_t outlen, const char *in, const char *empty);

/* True when file (a row's file name) is relative and stays inside the dataset. */
bool ds_file_name_ok(const char *file);

/* The current time as ISO 8601 UTC ("2026-11-29T22:00:00Z"). */
void ds_iso8601_now(char *buf, size_t len);

/* Rewrites dataset.json from the index. Returns 0 or -errno. */
int ds_write_json(struct ds *d);

/* An image name's id prefix ("000042_..."), or -1 if it has none. */
int64_t ds_image_id(const char *name);

/* True for a temporary file name (gn_write_atomic's "*.tmp"). */
bool ds_tmp_name(const char *name);

/* Calls fn for each entry of the directory rel below dir_fd ("." for dir_fd itself) but
 * . and ..; a negative return stops the walk and is returned. Returns 0, -ENOENT (no
 * such directory) or -errno. */
int ds_walk_dir(int dir_fd, const char *rel, int (*fn)(const char *name, void *userdata),
                void *userdata);
