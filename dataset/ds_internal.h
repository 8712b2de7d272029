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
        sqlite3_stmt *insert, *add_name; /* prepared by the writer */
        char error[256];                 /* ds_last_error() */
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

/* The captures table of the current schema; the angle of an axis the rig does not have
 * is NULL. */
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

/* Runs s (prepared from DS_ADD_NAME_SQL) for kind and each name of the comma-separated
 * list, adding n. Returns 0 or -errno. */
int ds_db_add_names(struct ds *d, sqlite3_stmt *s, const char *kind, const char *list, int64_t n);

/* Brings an index of an older schema to DS_SCHEMA_VERSION in one transaction
 * (ds_migrate.c); a current one is left alone. Returns 0, -EBADMSG (unknown version) or
 * -errno. */
int ds_db_upgrade(struct ds *d);

/* Commits c's row and its camera and lamp names (for ds_summary) in one transaction.
 * Returns 0 or -errno; on failure nothing is committed. Writer only. */
int ds_db_insert(struct ds *d, const struct ds_capture *c);

/* Prepares the writer's statements. Returns 0 or -errno. */
int ds_db_prepare_writer(struct ds *d);

/* The SELECT list of a full row, for ds_db_read_row. */
#define DS_ROW_COLUMNS                                                                             \
        "id, session, turntable_deg, light_arm_deg, camera_arm_deg, camera, lamps, lamp_bits, "    \
        "laser, exposure_us, gain, t_request_ns, t_exposure_ns, t_stored_ns, file, sha256, "       \
        "width, height, pixfmt"

/* Fills c from the current row of a statement selecting DS_ROW_COLUMNS. */
void ds_db_read_row(sqlite3_stmt *s, struct ds_capture *c);

/* The schema version this library writes (PRAGMA user_version). */
#define DS_SCHEMA_VERSION 3
