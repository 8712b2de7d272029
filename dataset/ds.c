/* ds.c - the dataset store: PNG images written atomically, an SQLite index (WAL)
 * with one row per capture, rig.yaml and dataset.json (see ds.h, docs/dataset.md).
 *
 * DESIGN
 * Durability protocol of ds_store: encode -> write images/NAME.tmp while hashing
 * the bytes -> fsync(file) -> rename to NAME -> fsync(images/) -> INSERT the row
 * (autocommit). The row is committed only after its file is durable, so the index
 * never names a missing or torn file. A crash between the rename and the commit
 * leaves an image whose id is above the last row: the first writer to open the
 * dataset again removes such orphans and any *.tmp before storing.
 *
 * Row ids come from the store's own sequence (max(id) + 1 when the writer starts),
 * so the file name is known before the row exists. One process writes a dataset at
 * a time (flock on the dataset directory, taken by the first ds_store); readers
 * never lock. */
#include <ctype.h>
#include <dirent.h>
#include <fcntl.h>
#include <jansson.h>
#include <libgen.h>
#include <limits.h>
#include <math.h>
#include <sqlite3.h>
#include <stdarg.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>

#include "common/clock.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/sha256.h"
#include "common/yconf.h"
#include "ds.h"
#include "ds_png.h"

#define DS_SCHEMA_VERSION     2 /* PRAGMA user_version; schema 1 had user_version 0 */
#define DS_SCHEMA_VERSION_STR "2"
#define DS_INDEX              "index.sqlite"
#define DS_JSON               "dataset.json"
#define DS_RIG                "rig.yaml"
#define DS_IMAGES             "images"
#define DS_BUSY_MS            5000
#define DS_FILE_MAX           (1u << 31)

/* Columns of captures in the order of struct ds_capture; shared by INSERT and SELECT. */
#define CAPTURE_COLUMNS                                                                            \
        "id, session, turntable_deg, light_arm_deg, camera_arm_deg, camera, lamps, lamp_bits, "    \
        "laser, exposure_us, gain, t_request_ns, t_exposure_ns, t_stored_ns, file, sha256, "       \
        "width, height, pixfmt"

/* The captures table; the angle of an axis the rig does not have is NULL. */
#define CAPTURES_TABLE(name)                                                                       \
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

#define CAPTURES_POSE_INDEX                                                                        \
        "CREATE INDEX captures_pose ON captures"                                                   \
        " (session, turntable_deg, light_arm_deg, camera_arm_deg);"

static const char schema_sql[] =
        "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);" CAPTURES_TABLE("captures")
                CAPTURES_POSE_INDEX "PRAGMA user_version = 2;";

/* Schema 1 -> 2: the angles become nullable and lamp_bits is added (0: unknown for
 * rows taken before; their lamp names stay in lamps). SQLite cannot drop NOT NULL in
 * place, so the table is copied. */
static const char migrate_v1_sql[] = CAPTURES_TABLE(
        "captures_v2") "INSERT INTO captures_v2 (id, session, turntable_deg, light_arm_deg, "
                       "camera_arm_deg,"
                       " camera, lamps, laser, exposure_us, gain, t_request_ns, t_exposure_ns, "
                       "t_stored_ns,"
                       " file, sha256, width, height, pixfmt)"
                       " SELECT id, session, turntable_deg, light_arm_deg, camera_arm_deg, camera, "
                       "lamps, laser,"
                       " exposure_us, gain, t_request_ns, t_exposure_ns, t_stored_ns, file, "
                       "sha256, width,"
                       " height, pixfmt FROM captures;"
                       "DROP TABLE captures;"
                       "ALTER TABLE captures_v2 RENAME TO captures;" CAPTURES_POSE_INDEX
                       "UPDATE meta SET value = '2' WHERE key = 'schema_version';"
                       "PRAGMA user_version = 2;";

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
        sqlite3_stmt *insert;
        char error[256]; /* ds_last_error() */
};

DEFINE_TRIVIAL_CLEANUP_FUNC(sqlite3_stmt *, sqlite3_finalize);
DEFINE_TRIVIAL_CLEANUP_FUNC(DIR *, closedir);

static struct ds *ds_free(struct ds *d);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_free);

/* ---- SQLite helpers ---- */

/* The errno of SQLite's last failed syscall. A failed commit does not record it in
 * sqlite3_system_errno(), so fall back to the WAL file's and the database file's own
 * last errno (SQLITE_FCNTL_LAST_ERRNO). 0 if unknown. */
static int sqlite_sys_errno(sqlite3 *db)
{
        sqlite3_file *wal = NULL;
        int e = sqlite3_system_errno(db);

        if (e == 0 &&
            sqlite3_file_control(db, "main", SQLITE_FCNTL_JOURNAL_POINTER, &wal) == SQLITE_OK &&
            wal && wal->pMethods)
                (void)wal->pMethods->xFileControl(wal, SQLITE_FCNTL_LAST_ERRNO, &e);
        if (e == 0)
                (void)sqlite3_file_control(db, "main", SQLITE_FCNTL_LAST_ERRNO, &e);
        return e;
}

/* Maps an SQLite result code to -errno, the one place that does. I/O failures keep
 * the errno of the failing syscall when SQLite recorded one (EFBIG, EDQUOT...). */
static int sqlite_errno(sqlite3 *db, int rc)
{
        int e = 0;

        switch (rc & 0xff) {
        case SQLITE_FULL:
        case SQLITE_IOERR:
        case SQLITE_CANTOPEN:
                e = db ? sqlite_sys_errno(db) : 0;
                return e > 0 ? -e : (rc & 0xff) == SQLITE_FULL ? -ENOSPC : -EIO;
        case SQLITE_NOMEM:
                return -ENOMEM;
        case SQLITE_BUSY:
        case SQLITE_LOCKED:
                return -EBUSY;
        case SQLITE_READONLY:
                return -EROFS;
        case SQLITE_CONSTRAINT:
        case SQLITE_MISMATCH:
        case SQLITE_RANGE:
                return -EINVAL;
        case SQLITE_CORRUPT:
        case SQLITE_NOTADB:
                return -EBADMSG;
        case SQLITE_PERM:
        case SQLITE_AUTH:
                return -EACCES;
        default:
                return -EPROTO;
        }
}

/* Records what failed for ds_last_error() and logs it; returns r. */
static int ds_fail(struct ds *d, int r, const char *fmt, ...) _printf_(3, 4);
static int ds_fail(struct ds *d, int r, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(d->error, sizeof(d->error), fmt, ap);
        va_end(ap);
        return log_error_errno(r, "dataset '%s': %s (%m)", d->path, d->error);
}

static int db_fail(struct ds *d, int rc, const char *what)
{
        return ds_fail(d, sqlite_errno(d->db, rc), "%s: %s", what, sqlite3_errmsg(d->db));
}

static int db_prepare(struct ds *d, const char *sql, sqlite3_stmt **ret)
{
        int rc = sqlite3_prepare_v2(d->db, sql, -1, ret, NULL);

        return rc == SQLITE_OK ? 0 : db_fail(d, rc, "Failed to prepare statement");
}

static int db_exec(struct ds *d, const char *sql)
{
        int rc = sqlite3_exec(d->db, sql, NULL, NULL, NULL);

        return rc == SQLITE_OK ? 0 : db_fail(d, rc, sql);
}

/* Runs a query returning one integer. */
static int db_int64(struct ds *d, const char *sql, int64_t *ret)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = db_prepare(d, sql, &s);
        if (r < 0)
                return r;
        rc = sqlite3_step(s);
        if (rc != SQLITE_ROW)
                return db_fail(d, rc, sql);
        *ret = sqlite3_column_int64(s, 0);
        return 0;
}

static int meta_set(struct ds *d, const char *key, const char *value)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = db_prepare(d, "INSERT OR REPLACE INTO meta (key, value) VALUES (?, ?)", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 2, value, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        return rc == SQLITE_DONE ? 0 : db_fail(d, rc, "Failed to write meta");
}

/* Reads meta[key] into out; -EBADMSG if absent. */
static int meta_get(struct ds *d, const char *key, char *out, size_t outlen)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = db_prepare(d, "SELECT value FROM meta WHERE key = ?", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc == SQLITE_DONE)
                return log_error_errno(SYNTHETIC_ERRNO(EBADMSG),
                                       "dataset '%s': index has no meta '%s'", d->path, key);
        if (rc != SQLITE_ROW)
                return db_fail(d, rc, "Failed to read meta");
        snprintf(out, outlen, "%s", (const char *)sqlite3_column_text(s, 0));
        return 0;
}

/* Opens index.sqlite in WAL mode with synchronous=NORMAL. */
static int db_open(struct ds *d, bool create)
{
        _cleanup_free_ char *file = NULL;
        int rc;

        if (asprintf(&file, "%s/%s", d->path, DS_INDEX) < 0)
                return -ENOMEM;
        if (!create && access(file, F_OK) < 0)
                return log_error_errno(errno == ENOENT ? SYNTHETIC_ERRNO(EBADMSG) : errno,
                                       "'%s' is not a dataset: %m", d->path);
        rc = sqlite3_open_v2(file, &d->db,
                             SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) |
                                     SQLITE_OPEN_NOMUTEX | SQLITE_OPEN_EXRESCODE,
                             NULL);
        if (rc != SQLITE_OK)
                return db_fail(d, rc, "Failed to open index");
        sqlite3_busy_timeout(d->db, DS_BUSY_MS);
        return db_exec(d, "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;");
}

/* ---- dataset.json ---- */

static int json_add_unique(json_t *arr, const char *s)
{
        size_t i;
        json_t *v;

        if (!*s)
                return 0;
        json_array_foreach(arr, i, v) if (strcmp(json_string_value(v), s) == 0) return 0;
        return json_array_append_new(arr, json_string(s)) == 0 ? 0 : -ENOMEM;
}

/* Adds each comma-separated name of list to arr once. */
static int json_add_names(json_t *arr, const char *list)
{
        _cleanup_free_ char *copy = strdup(list);
        char *save = NULL;
        int r = 0;

        if (!copy)
                return -ENOMEM;
        for (char *t = strtok_r(copy, ",", &save); t && r == 0; t = strtok_r(NULL, ",", &save))
                r = json_add_unique(arr, t);
        return r;
}

/* Fills arr with the distinct names found in the only column of sql. */
static int collect_names(struct ds *d, const char *sql, json_t *arr)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        if (!arr)
                return -ENOMEM;
        r = db_prepare(d, sql, &s);
        while (r == 0 && (rc = sqlite3_step(s)) == SQLITE_ROW)
                r = json_add_names(arr, (const char *)sqlite3_column_text(s, 0));
        if (r == 0 && rc != SQLITE_DONE)
                r = db_fail(d, rc, sql);
        return r;
}

static int write_json(struct ds *d)
{
        _cleanup_(json_decrefp) json_t *cameras = json_array(), *lamps = json_array(), *j = NULL;
        _cleanup_free_ char *text = NULL;
        int64_t n;
        int r;

        r = db_int64(d, "SELECT count(*) FROM captures", &n);
        if (r == 0)
                r = collect_names(d, "SELECT DISTINCT camera FROM captures ORDER BY camera",
                                  cameras);
        if (r == 0)
                r = collect_names(d, "SELECT DISTINCT lamps FROM captures ORDER BY lamps", lamps);
        if (r < 0)
                return r;
        j = json_pack("{s:s, s:s, s:s, s:I, s:O, s:O, s:s, s:s, s:i}", "name", d->name, "created",
                      d->created, "rig", d->rig, "captures", (json_int_t)n, "cameras", cameras,
                      "lamps", lamps, "format", "png", "index", DS_INDEX, "schema_version",
                      DS_SCHEMA_VERSION);
        text = j ? json_dumps(j, JSON_INDENT(2)) : NULL;
        if (!text)
                return -ENOMEM;
        r = gn_write_atomic(d->dir_fd, DS_JSON, text, strlen(text), NULL);
        if (r < 0)
                return log_error_errno(r, "dataset '%s': Failed to write %s: %m", d->path, DS_JSON);
        return 0;
}

/* ---- lifetime ---- */

static struct ds *ds_free(struct ds *d)
{
        if (!d)
                return NULL;
        sqlite3_finalize(d->insert);
        if (sqlite3_close(d->db) != SQLITE_OK)
                log_warning("dataset '%s': index not closed cleanly: %s", d->path,
                            sqlite3_errmsg(d->db));
        closep(&d->img_fd);
        closep(&d->dir_fd); /* releases the writer lock */
        free(d->path);
        free(d);
        return NULL;
}

/* Allocates a handle on the existing directory path. */
static int ds_alloc(const char *path, struct ds **ret)
{
        _cleanup_(ds_freep) struct ds *d = calloc(1, sizeof(*d));

        if (!d)
                return -ENOMEM;
        d->img_fd = -EBADF;
        d->png_level = DS_PNG_LEVEL_DEFAULT;
        d->dir_fd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (d->dir_fd < 0)
                return -errno;
        d->path = realpath(path, NULL);
        if (!d->path)
                return -errno;
        *ret = TAKE_PTR(d);
        return 0;
}

static void iso8601_now(char *buf, size_t len)
{
        time_t t = time(NULL);
        struct tm tm;

        strftime(buf, len, "%Y-%m-%dT%H:%M:%SZ", gmtime_r(&t, &tm));
}

/* The rig's name ("rig:" key of the rig file); "" when it cannot be read. */
static void rig_name(const char *rig_text, char *out, size_t outlen)
{
        struct yconf yc;
        char err[256];

        out[0] = 0;
        if (yconf_open_string(&yc, DS_RIG, rig_text, err, sizeof(err)) < 0 ||
            yconf_str(&yc, yconf_root(&yc), "rig", out, outlen) < 0)
                log_warning("Cannot read the rig name, ignoring: %s", err);
        yconf_close(&yc);
}

static int create_index(struct ds *d)
{
        int r;

        r = db_open(d, true);
        if (r == 0)
                r = db_exec(d, "BEGIN");
        if (r == 0)
                r = db_exec(d, schema_sql);
        if (r == 0)
                r = meta_set(d, "schema_version", DS_SCHEMA_VERSION_STR);
        if (r == 0)
                r = meta_set(d, "name", d->name);
        if (r == 0)
                r = meta_set(d, "created", d->created);
        if (r == 0)
                r = meta_set(d, "rig", d->rig);
        if (r == 0)
                r = db_exec(d, "COMMIT");
        return r;
}

/* Fills the new, empty directory path with a dataset. */
static int create_contents(const char *path, const char *name, const char *rig_text,
                           struct ds **ret)
{
        _cleanup_(ds_freep) struct ds *d = NULL;
        int r;

        r = ds_alloc(path, &d);
        if (r < 0)
                return r;
        snprintf(d->name, sizeof(d->name), "%s", name);
        iso8601_now(d->created, sizeof(d->created));
        if (rig_text)
                rig_name(rig_text, d->rig, sizeof(d->rig));
        if (mkdirat(d->dir_fd, DS_IMAGES, 0755) < 0)
                return -errno;
        d->img_fd = openat(d->dir_fd, DS_IMAGES, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (d->img_fd < 0)
                return -errno;
        if (rig_text &&
            (r = gn_write_atomic(d->dir_fd, DS_RIG, rig_text, strlen(rig_text), NULL)) < 0)
                return r;
        r = create_index(d);
        if (r == 0)
                r = write_json(d);
        if (r == 0 && fsync(d->dir_fd) < 0)
                r = -errno;
        if (r == 0)
                r = gn_fsync_parent(d->path);
        if (r == 0)
                *ret = TAKE_PTR(d);
        return r;
}

/* Removes what a failed ds_create left in path (only names the store creates). */
static void remove_partial(const char *path)
{
        static const char *const files[] = {
                DS_JSON,  DS_JSON ".tmp",  DS_RIG,          DS_RIG ".tmp",
                DS_INDEX, DS_INDEX "-wal", DS_INDEX "-shm", DS_INDEX "-journal",
        };
        _cleanup_close_ int fd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);

        if (fd < 0)
                return;
        for (size_t i = 0; i < ELEMENTSOF(files); i++)
                (void)unlinkat(fd, files[i], 0);
        (void)unlinkat(fd, DS_IMAGES, AT_REMOVEDIR);
        if (rmdir(path) < 0)
                log_warning("Cannot remove partial dataset '%s', ignoring: %m", path);
}

int ds_create(const char *path, const char *name, const char *rig_text, struct ds **ret)
{
        int r;

        if (!path || !name || !*name || strlen(name) >= DS_NAME_MAX || !ret)
                return -EINVAL;
        if (mkdir(path, 0755) < 0)
                return log_error_errno(errno, "Cannot create dataset '%s': %m", path);
        r = create_contents(path, name, rig_text, ret);
        if (r < 0) {
                remove_partial(path);
                return log_error_errno(r, "Cannot create dataset '%s': %m", path);
        }
        log_info("Created dataset '%s' (%s)", (*ret)->path, name);
        return 0;
}

/* Brings an index of an older schema to DS_SCHEMA_VERSION, in one transaction that
 * holds SQLite's write lock, so two openers cannot both migrate. */
static int migrate(struct ds *d)
{
        char version[16];
        int64_t v = 0;
        int r;

        r = db_exec(d, "BEGIN IMMEDIATE");
        if (r == 0)
                r = db_int64(d, "PRAGMA user_version", &v);
        if (r == 0 && v == 0)
                r = meta_get(d, "schema_version", version, sizeof(version));
        if (r == 0 && v == 0 && strcmp(version, "1") != 0)
                r = ds_fail(d, -EBADMSG, "unknown schema version %s", version);
        if (r == 0 && v == 0) {
                log_notice("dataset '%s': migrating its index from schema 1 to %d", d->path,
                           DS_SCHEMA_VERSION);
                r = db_exec(d, migrate_v1_sql);
        }
        if (r == 0)
                return db_exec(d, "COMMIT");
        (void)sqlite3_exec(d->db, "ROLLBACK", NULL, NULL, NULL);
        return r;
}

static int read_meta(struct ds *d)
{
        int64_t v = 0;
        int r;

        r = db_int64(d, "PRAGMA user_version", &v);
        if (r == 0 && v < DS_SCHEMA_VERSION) {
                r = migrate(d);
                v = DS_SCHEMA_VERSION;
        }
        if (r == 0 && v != DS_SCHEMA_VERSION)
                r = ds_fail(d, -EBADMSG, "unknown schema version %lld (newer software?)",
                            (long long)v);
        if (r == 0)
                r = meta_get(d, "name", d->name, sizeof(d->name));
        if (r == 0)
                r = meta_get(d, "created", d->created, sizeof(d->created));
        if (r == 0)
                r = meta_get(d, "rig", d->rig, sizeof(d->rig));
        return r;
}

int ds_open(const char *path, struct ds **ret)
{
        _cleanup_(ds_freep) struct ds *d = NULL;
        int r;

        if (!path || !ret)
                return -EINVAL;
        r = ds_alloc(path, &d);
        if (r < 0)
                return log_error_errno(r, "Cannot open dataset '%s': %m", path);
        d->img_fd = openat(d->dir_fd, DS_IMAGES, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (d->img_fd < 0)
                return log_error_errno(errno == ENOENT ? SYNTHETIC_ERRNO(EBADMSG) : errno,
                                       "'%s' is not a dataset (no %s/): %m", path, DS_IMAGES);
        r = db_open(d, false);
        if (r == 0)
                r = read_meta(d);
        if (r < 0)
                return r;
        *ret = TAKE_PTR(d);
        return 0;
}

struct ds *ds_close(struct ds *d)
{
        if (d && d->writer)
                (void)write_json(d);
        return ds_free(d);
}

int ds_set_compression(struct ds *d, int level)
{
        if (!d || level < 0 || level > 9)
                return -EINVAL;
        d->png_level = level;
        return 0;
}

int ds_get_compression(const struct ds *d)
{
        return d->png_level;
}

const char *ds_path(const struct ds *d)
{
        return d->path;
}

const char *ds_name(const struct ds *d)
{
        return d->name;
}

const char *ds_last_error(const struct ds *d)
{
        return d->error;
}

int64_t ds_count(struct ds *d)
{
        int64_t n = 0;
        int r;

        if (!d)
                return -EINVAL;
        r = db_int64(d, "SELECT count(*) FROM captures", &n);
        return r < 0 ? r : n;
}

/* ---- storing ---- */

/* An image name's id prefix ("000042_..."), or -1 if it has none. */
static int64_t image_id(const char *name)
{
        char *end = NULL;
        long long id;

        if (!isdigit((unsigned char)name[0]))
                return -1;
        id = strtoll(name, &end, 10);
        return *end == '_' ? id : -1;
}

/* Removes *.tmp and images without a row (id >= next_id) left by a crash. */
static int remove_orphans(struct ds *d)
{
        _cleanup_(closedirp) DIR *dir = NULL;
        struct dirent *de;
        int fd, removed = 0;

        fd = openat(d->img_fd, ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0)
                return -errno;
        dir = fdopendir(fd);
        if (!dir) {
                close(fd);
                return -errno;
        }
        while ((de = readdir(dir))) {
                size_t n = strlen(de->d_name);
                bool tmp = n > 4 && strcmp(de->d_name + n - 4, ".tmp") == 0;

                if (!tmp && image_id(de->d_name) < d->next_id)
                        continue;
                log_notice("dataset '%s': removing %s/%s left by an interrupted store", d->path,
                           DS_IMAGES, de->d_name);
                if (unlinkat(d->img_fd, de->d_name, 0) < 0)
                        return -errno;
                removed++;
        }
        return removed > 0 && fsync(d->img_fd) < 0 ? -errno : 0;
}

/* Makes this handle the dataset's only writer (first ds_store). */
static int become_writer(struct ds *d)
{
        int r;

        if (d->writer)
                return 0;
        if (flock(d->dir_fd, LOCK_EX | LOCK_NB) < 0)
                return ds_fail(d, errno == EWOULDBLOCK ? -EBUSY : -errno,
                               "being written by another process");
        r = db_int64(d, "SELECT coalesce(max(id), 0) + 1 FROM captures", &d->next_id);
        if (r == 0)
                r = remove_orphans(d);
        if (r == 0 && !d->insert)
                r = db_prepare(d,
                               "INSERT INTO captures (" CAPTURE_COLUMNS ") VALUES "
                               "(?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                               &d->insert);
        if (r < 0) {
                (void)flock(d->dir_fd, LOCK_UN);
                return r;
        }
        d->writer = true;
        return 0;
}

/* Copies a name into a file-name part: ',' -> '+', other unsafe bytes -> '-'. */
static void name_part(char *out, size_t outlen, const char *in, const char *empty)
{
        size_t n = 0;

        if (!*in)
                in = empty;
        for (; *in && n + 1 < outlen; in++) {
                unsigned char ch = (unsigned char)*in;

                out[n++] = isalnum(ch) || strchr("-_.", ch) ? (char)ch : ch == ',' ? '+' : '-';
        }
        out[n] = 0;
}

/* Sets c->file to "images/NNNNNN_<camera>_<lamps or dark>.png"; returns the base name. */
static const char *image_name(struct ds_capture *c)
{
        char cam[DS_NAME_MAX], lamps[128];

        name_part(cam, sizeof(cam), c->camera, "camera");
        name_part(lamps, sizeof(lamps), c->lamps, "dark");
        snprintf(c->file, sizeof(c->file), "%s/%06lld_%s_%s.png", DS_IMAGES, (long long)c->id, cam,
                 lamps);
        return c->file + strlen(DS_IMAGES "/");
}

static int bind_capture(sqlite3_stmt *s, const struct ds_capture *c)
{
        int i = 1, rc = 0;

        rc |= sqlite3_bind_int64(s, i++, c->id);
        rc |= sqlite3_bind_text(s, i++, c->session, -1, SQLITE_STATIC);
        for (int k = 0; k < GN_ROLE_COUNT; k++, i++)
                rc |= gn_pose_has(&c->pose, k) ? sqlite3_bind_double(s, i, c->pose.deg[k])
                                               : sqlite3_bind_null(s, i);
        rc |= sqlite3_bind_text(s, i++, c->camera, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_text(s, i++, c->lamps, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_int64(s, i++, c->pose.lamps);
        rc |= sqlite3_bind_int(s, i++, c->pose.laser);
        rc |= sqlite3_bind_int(s, i++, c->exposure_us);
        rc |= sqlite3_bind_double(s, i++, c->gain);
        rc |= sqlite3_bind_int64(s, i++, (sqlite3_int64)c->t_request_ns);
        rc |= sqlite3_bind_int64(s, i++, (sqlite3_int64)c->t_exposure_ns);
        rc |= sqlite3_bind_int64(s, i++, (sqlite3_int64)c->t_stored_ns);
        rc |= sqlite3_bind_text(s, i++, c->file, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_text(s, i++, c->sha256, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_int(s, i++, c->width);
        rc |= sqlite3_bind_int(s, i++, c->height);
        rc |= sqlite3_bind_text(s, i++, c->pixfmt, -1, SQLITE_STATIC);
        return rc == SQLITE_OK ? 0 : -ENOMEM;
}

static int insert_row(struct ds *d, const struct ds_capture *c)
{
        int r, rc;

        r = bind_capture(d->insert, c);
        rc = r == 0 ? sqlite3_step(d->insert) : SQLITE_NOMEM;
        if (rc != SQLITE_DONE)
                r = db_fail(d, rc, "Failed to commit capture row");
        sqlite3_reset(d->insert);
        sqlite3_clear_bindings(d->insert);
        return r;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct gn_sha256 *, gn_sha256_free);

/* Writes an image atomically, hashing its bytes on the way into hex. */
static int write_image(int dir_fd, const char *name, const void *png, size_t len,
                       char hex[GN_SHA256_HEX])
{
        _cleanup_(gn_sha256_freep) struct gn_sha256 *sha = NULL;
        int r;

        r = gn_sha256_new(&sha);
        if (r == 0)
                r = gn_write_atomic(dir_fd, name, png, len, sha);
        return r < 0 ? r : gn_sha256_final(sha, hex);
}

/* Writes the encoded image of row (named after row->id) and commits the row. */
static int store_encoded(struct ds *d, const void *png, size_t len, struct ds_capture *row)
{
        const char *name = image_name(row);
        int r;

        r = write_image(d->img_fd, name, png, len, row->sha256);
        if (r < 0)
                return ds_fail(d, r, "Failed to write %s: %s", row->file, strerror(-r));
        row->t_stored_ns = gn_realtime_ns();
        r = insert_row(d, row);
        if (r < 0 && unlinkat(d->img_fd, name, 0) == 0)
                (void)fsync(d->img_fd);
        return r;
}

int ds_store_png(struct ds *d, const void *png, size_t len, const struct gn_frame *shape,
                 struct ds_capture *c)
{
        struct ds_capture row;
        int r;

        if (!d || !png || !shape || !c)
                return -EINVAL;
        d->error[0] = 0;
        r = become_writer(d);
        if (r < 0)
                return r;
        row = *c;
        row.id = d->next_id;
        row.width = shape->width;
        row.height = shape->height;
        snprintf(row.pixfmt, sizeof(row.pixfmt), "%s", gn_frame_format(shape));
        r = store_encoded(d, png, len, &row);
        if (r < 0)
                return r;
        d->next_id++;
        *c = row;
        return 0;
}

int ds_store(struct ds *d, const struct gn_frame *frame, struct ds_capture *c)
{
        _cleanup_free_ void *png = NULL;
        size_t len = 0;
        int r;

        if (!d || !frame || !c)
                return -EINVAL;
        r = ds_png_encode(frame, d->png_level, &png, &len);
        if (r < 0)
                return ds_fail(d, r, "Failed to encode %dx%d %s frame: %s", frame->width,
                               frame->height, gn_frame_format(frame), strerror(-r));
        return ds_store_png(d, png, len, frame, c);
}

/* ---- reading ---- */

static void column_text(sqlite3_stmt *s, int col, char *out, size_t outlen)
{
        const unsigned char *t = sqlite3_column_text(s, col);

        snprintf(out, outlen, "%s", t ? (const char *)t : "");
}

static void row_to_capture(sqlite3_stmt *s, struct ds_capture *c)
{
        int i = 0;

        memset(c, 0, sizeof(*c));
        c->id = sqlite3_column_int64(s, i++);
        column_text(s, i++, c->session, sizeof(c->session));
        for (int k = 0; k < GN_ROLE_COUNT; k++, i++)
                c->pose.deg[k] = sqlite3_column_type(s, i) == SQLITE_NULL
                                         ? NAN
                                         : sqlite3_column_double(s, i);
        column_text(s, i++, c->camera, sizeof(c->camera));
        column_text(s, i++, c->lamps, sizeof(c->lamps));
        c->pose.lamps = (uint32_t)sqlite3_column_int64(s, i++);
        c->pose.laser = sqlite3_column_int(s, i++) != 0;
        c->exposure_us = sqlite3_column_int(s, i++);
        c->gain = sqlite3_column_double(s, i++);
        c->t_request_ns = (uint64_t)sqlite3_column_int64(s, i++);
        c->t_exposure_ns = (uint64_t)sqlite3_column_int64(s, i++);
        c->t_stored_ns = (uint64_t)sqlite3_column_int64(s, i++);
        column_text(s, i++, c->file, sizeof(c->file));
        column_text(s, i++, c->sha256, sizeof(c->sha256));
        c->width = sqlite3_column_int(s, i++);
        c->height = sqlite3_column_int(s, i++);
        column_text(s, i++, c->pixfmt, sizeof(c->pixfmt));
}

int ds_foreach(struct ds *d, int (*fn)(const struct ds_capture *c, void *ud), void *ud)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        struct ds_capture c;
        int r, rc;

        if (!d || !fn)
                return -EINVAL;
        r = db_prepare(d, "SELECT " CAPTURE_COLUMNS " FROM captures ORDER BY id", &s);
        if (r < 0)
                return r;
        while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
                row_to_capture(s, &c);
                r = fn(&c, ud);
                if (r < 0)
                        return r;
        }
        return rc == SQLITE_DONE ? 0 : db_fail(d, rc, "Failed to read captures");
}

/* A file name of the dataset must be relative and stay inside it. */
static bool file_name_ok(const char *file)
{
        return file && *file && file[0] != '/' && !strstr(file, "..");
}

int ds_load_image(struct ds *d, const char *file, struct gn_frame *out)
{
        _cleanup_free_ void *buf = NULL;
        size_t len = 0;
        int r;

        if (!d || !file_name_ok(file) || !out)
                return -EINVAL;
        r = gn_read_file_at(d->dir_fd, file, DS_FILE_MAX, &buf, &len);
        if (r == 0)
                r = ds_png_decode(buf, len, out);
        if (r < 0)
                return log_error_errno(r, "dataset '%s': Failed to load %s: %m", d->path, file);
        return 0;
}

struct verify_ctx {
        struct ds *d;
        int bad;
};

static int verify_one(const struct ds_capture *c, void *ud)
{
        struct verify_ctx *v = ud;
        char hex[65];
        int r;

        r = file_name_ok(c->file) ? gn_sha256_file_at(v->d->dir_fd, c->file, hex) : -ENOENT;
        if (r < 0 && r != -ENOENT)
                return log_error_errno(r, "dataset '%s': Failed to hash %s: %m", v->d->path,
                                       c->file);
        if (r == 0 && strcmp(hex, c->sha256) == 0)
                return 0;
        log_warning("dataset '%s': capture %lld: %s %s", v->d->path, (long long)c->id, c->file,
                    r < 0 ? "is missing" : "does not match its checksum");
        v->bad++;
        return 0;
}

int ds_verify(struct ds *d)
{
        struct verify_ctx v = {.d = d};
        int r;

        if (!d)
                return -EINVAL;
        r = ds_foreach(d, verify_one, &v);
        return r < 0 ? r : v.bad;
}
