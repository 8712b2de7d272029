/* ds_index.c - the SQLite index of a dataset: connection, current schema, the row
 * codec, the commit of a row with its names, and the one mapping of SQLite result
 * codes to -errno (see ds_internal.h, docs/dataset.md; older schemas: ds_migrate.c). */
#include <math.h>
#include <stdarg.h>
#include <string.h>
#include <unistd.h>

#include "common/log.h"
#include "ds_internal.h"

#define DS_BUSY_MS 5000

static const char schema_sql[] =
        "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);" DS_CAPTURES_TABLE(
                "captures") DS_CAPTURES_POSE_INDEX DS_NAMES_TABLE DS_V4_SQL
        "PRAGMA user_version = 4;"
        "INSERT INTO meta (key, value) VALUES ('schema_version', '4');";

/* ---- errors ---- */

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

/* Maps an SQLite result code to -errno. I/O failures keep the errno of the failing
 * syscall when SQLite recorded one (EFBIG, EDQUOT...). */
static int sqlite_errno(sqlite3 *db, int rc)
{
        int e;

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

int ds_fail(struct ds *d, int r, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(d->error, sizeof(d->error), fmt, ap);
        va_end(ap);
        return log_error_errno(r, "dataset '%s': %s (%m)", d->path, d->error);
}

int ds_db_fail(struct ds *d, int rc, const char *what)
{
        return ds_fail(d, sqlite_errno(d->db, rc), "%s: %s", what, sqlite3_errmsg(d->db));
}

/* ---- statements ---- */

int ds_db_prepare(struct ds *d, const char *sql, sqlite3_stmt **ret)
{
        int rc = sqlite3_prepare_v2(d->db, sql, -1, ret, NULL);

        return rc == SQLITE_OK ? 0 : ds_db_fail(d, rc, "Failed to prepare statement");
}

int ds_db_exec(struct ds *d, const char *sql)
{
        int rc = sqlite3_exec(d->db, sql, NULL, NULL, NULL);

        return rc == SQLITE_OK ? 0 : ds_db_fail(d, rc, sql);
}

int ds_db_int64(struct ds *d, const char *sql, int64_t *ret)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = ds_db_prepare(d, sql, &s);
        if (r < 0)
                return r;
        rc = sqlite3_step(s);
        if (rc != SQLITE_ROW)
                return ds_db_fail(d, rc, sql);
        *ret = sqlite3_column_int64(s, 0);
        return 0;
}

static int meta_set(struct ds *d, const char *key, const char *value)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = ds_db_prepare(d, "INSERT OR REPLACE INTO meta (key, value) VALUES (?, ?)", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 2, value, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        return rc == SQLITE_DONE ? 0 : ds_db_fail(d, rc, "Failed to write meta");
}

int ds_meta_get(struct ds *d, const char *key, char *out, size_t outlen)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = ds_db_prepare(d, "SELECT value FROM meta WHERE key = ?", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc == SQLITE_DONE)
                return ds_fail(d, -EBADMSG, "index has no meta '%s'", key);
        if (rc != SQLITE_ROW)
                return ds_db_fail(d, rc, "Failed to read meta");
        snprintf(out, outlen, "%s", (const char *)sqlite3_column_text(s, 0));
        return 0;
}

/* ---- names (schema 3) ---- */

int ds_db_add_names(struct ds *d, sqlite3_stmt *s, const char *kind, const char *list, int64_t n)
{
        char copy[sizeof(((struct ds_capture *)0)->lamps)], *save = NULL;
        int r = 0, rc;

        snprintf(copy, sizeof(copy), "%s", list);
        for (char *t = strtok_r(copy, ",", &save); t && r == 0; t = strtok_r(NULL, ",", &save)) {
                sqlite3_bind_text(s, 1, kind, -1, SQLITE_STATIC);
                sqlite3_bind_text(s, 2, t, -1, SQLITE_TRANSIENT);
                sqlite3_bind_int64(s, 3, n);
                rc = sqlite3_step(s);
                if (rc != SQLITE_DONE)
                        r = ds_db_fail(d, rc, "Failed to count a name");
                sqlite3_reset(s);
        }
        return r;
}

/* ---- connection ---- */

/* Distance of two angles on the circle, in [0, 180]; NULL when either is NULL. */
static void angle_dist(sqlite3_context *ctx, int argc, sqlite3_value **argv)
{
        double d;

        if (sqlite3_value_type(argv[0]) == SQLITE_NULL ||
            sqlite3_value_type(argv[1]) == SQLITE_NULL) {
                sqlite3_result_null(ctx);
                return;
        }
        d = fmod(fabs(sqlite3_value_double(argv[0]) - sqlite3_value_double(argv[1])), 360.0);
        sqlite3_result_double(ctx, d > 180 ? 360 - d : d);
}

static int create_schema(struct ds *d)
{
        int r;

        r = ds_db_exec(d, "BEGIN");
        if (r == 0)
                r = ds_db_exec(d, schema_sql);
        if (r == 0)
                r = meta_set(d, "name", d->name);
        if (r == 0)
                r = meta_set(d, "created", d->created);
        if (r == 0)
                r = meta_set(d, "rig", d->rig);
        if (r == 0)
                r = ds_db_exec(d, "COMMIT");
        return r;
}

int ds_db_open(struct ds *d, bool create)
{
        _cleanup_free_ char *file = NULL;
        int r, rc;

        if (asprintf(&file, "%s/%s", d->path, DS_INDEX) < 0)
                return -ENOMEM;
        if (!create && access(file, F_OK) < 0)
                return ds_fail(d, errno == ENOENT ? -EBADMSG : -errno, "not a dataset (%s: %s)",
                               DS_INDEX, strerror(errno));
        rc = sqlite3_open_v2(file, &d->db,
                             SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) |
                                     SQLITE_OPEN_NOMUTEX | SQLITE_OPEN_EXRESCODE,
                             NULL);
        if (rc != SQLITE_OK)
                return ds_db_fail(d, rc, "Failed to open index");
        sqlite3_busy_timeout(d->db, DS_BUSY_MS);
        rc = sqlite3_create_function(d->db, "gn_angle_dist", 2,
                                     SQLITE_UTF8 | SQLITE_DETERMINISTIC | SQLITE_INNOCUOUS, NULL,
                                     angle_dist, NULL, NULL);
        if (rc != SQLITE_OK)
                return ds_db_fail(d, rc, "Failed to register gn_angle_dist");
        r = ds_db_exec(d, "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;");
        if (r == 0)
                r = create ? create_schema(d) : ds_db_upgrade(d);
        return r;
}

/* ---- rows ---- */

int ds_db_prepare_writer(struct ds *d)
{
        int r = 0;

        if (!d->insert)
                r = ds_db_prepare(d,
                                  "INSERT INTO captures (" DS_ROW_COLUMNS ") VALUES "
                                  "(?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                                  &d->insert);
        if (r == 0 && !d->add_name)
                r = ds_db_prepare(d, DS_ADD_NAME_SQL, &d->add_name);
        if (r == 0 && !d->count_captured)
                r = ds_db_prepare(d, "UPDATE sessions SET captured = captured + 1 WHERE name = ?",
                                  &d->count_captured);
        return r;
}

bool ds_kind_ok(const char *kind)
{
        static const char *const kinds[] = {"image", "dark", "flat", "laser"};

        for (size_t i = 0; i < ELEMENTSOF(kinds); i++)
                if (strcmp(kind, kinds[i]) == 0)
                        return true;
        return false;
}

int ds_db_check_plan_item(struct ds *d, const struct ds_capture *c)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        if (c->plan_seq == 0)
                return 0;
        if (c->plan_seq < 0 || !c->session[0])
                return ds_fail(d, -EINVAL, "plan item %lld needs a session",
                               (long long)c->plan_seq);
        r = ds_db_prepare(d,
                          "SELECT (SELECT id FROM captures WHERE session = ?1 AND plan_seq = ?2),"
                          " EXISTS (SELECT 1 FROM plan WHERE session = ?1 AND seq = ?2)",
                          &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, c->session, -1, SQLITE_STATIC);
        sqlite3_bind_int64(s, 2, c->plan_seq);
        rc = sqlite3_step(s);
        if (rc != SQLITE_ROW)
                return ds_db_fail(d, rc, "Failed to look up a plan item");
        if (sqlite3_column_type(s, 0) != SQLITE_NULL)
                return ds_fail(d, -EEXIST, "plan item %lld of session '%s' is row %lld already",
                               (long long)c->plan_seq, c->session,
                               (long long)sqlite3_column_int64(s, 0));
        if (!sqlite3_column_int(s, 1))
                return ds_fail(d, -EINVAL, "session '%s' has no plan item %lld", c->session,
                               (long long)c->plan_seq);
        return 0;
}

/* Binds v, or NULL for 0 (no plan item, no dark or flat frame, size unknown). */
static int bind_id(sqlite3_stmt *s, int i, int64_t v)
{
        return v ? sqlite3_bind_int64(s, i, v) : sqlite3_bind_null(s, i);
}

int ds_db_bind_angles(sqlite3_stmt *s, int first, const struct gn_pose *p)
{
        int rc = 0;

        for (int k = 0; k < GN_ROLE_COUNT; k++)
                rc |= gn_pose_has(p, k) ? sqlite3_bind_double(s, first + k, p->deg[k])
                                        : sqlite3_bind_null(s, first + k);
        return rc;
}

static int bind_capture(sqlite3_stmt *s, const struct ds_capture *c)
{
        int i = 1, rc = 0;

        rc |= sqlite3_bind_int64(s, i++, c->id);
        rc |= sqlite3_bind_text(s, i++, c->session, -1, SQLITE_STATIC);
        rc |= ds_db_bind_angles(s, i, &c->pose);
        i += GN_ROLE_COUNT;
        rc |= sqlite3_bind_text(s, i++, c->camera, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_text(s, i++, c->lamps, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_int64(s, i++, c->pose.lamps);
        rc |= sqlite3_bind_int64(s, i++, c->pose.lasers);
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
        rc |= bind_id(s, i++, c->plan_seq);
        rc |= sqlite3_bind_text(s, i++, c->kind[0] ? c->kind : "image", -1, SQLITE_STATIC);
        rc |= sqlite3_bind_int(s, i++, c->bracket);
        rc |= bind_id(s, i++, c->dark_id);
        rc |= bind_id(s, i++, c->flat_id);
        rc |= bind_id(s, i++, c->size);
        return rc == SQLITE_OK ? 0 : -ENOMEM;
}

static int insert_row(struct ds *d, const struct ds_capture *c)
{
        int r, rc;

        r = bind_capture(d->insert, c);
        rc = r == 0 ? sqlite3_step(d->insert) : SQLITE_NOMEM;
        if (rc != SQLITE_DONE)
                r = ds_db_fail(d, rc, "Failed to insert capture row");
        sqlite3_reset(d->insert);
        sqlite3_clear_bindings(d->insert);
        return r;
}

/* Adds the row of a plan item to its session's captured count. */
static int count_captured(struct ds *d, const char *session)
{
        int rc;

        sqlite3_bind_text(d->count_captured, 1, session, -1, SQLITE_STATIC);
        rc = sqlite3_step(d->count_captured);
        sqlite3_reset(d->count_captured);
        return rc == SQLITE_DONE ? 0 : ds_db_fail(d, rc, "Failed to count a session's capture");
}

int ds_db_insert(struct ds *d, const struct ds_capture *c)
{
        int r;

        r = ds_db_exec(d, "BEGIN");
        if (r == 0)
                r = insert_row(d, c);
        if (r == 0)
                r = ds_db_add_names(d, d->add_name, "camera", c->camera, 1);
        if (r == 0)
                r = ds_db_add_names(d, d->add_name, "lamp", c->lamps, 1);
        if (r == 0 && c->plan_seq > 0)
                r = count_captured(d, c->session);
        if (r == 0)
                r = ds_db_exec(d, "COMMIT");
        if (r < 0 && !sqlite3_get_autocommit(d->db))
                (void)sqlite3_exec(d->db, "ROLLBACK", NULL, NULL, NULL);
        return r;
}

void ds_db_column_text(sqlite3_stmt *s, int col, char *out, size_t outlen)
{
        const unsigned char *t = sqlite3_column_text(s, col);

        snprintf(out, outlen, "%s", t ? (const char *)t : "");
}

void ds_db_column_angles(sqlite3_stmt *s, int first, struct gn_pose *p)
{
        for (int k = 0; k < GN_ROLE_COUNT; k++)
                p->deg[k] = sqlite3_column_type(s, first + k) == SQLITE_NULL
                                    ? NAN
                                    : sqlite3_column_double(s, first + k);
}

void ds_db_read_row(sqlite3_stmt *s, struct ds_capture *c)
{
        int i = 0;

        memset(c, 0, sizeof(*c));
        c->id = sqlite3_column_int64(s, i++);
        ds_db_column_text(s, i++, c->session, sizeof(c->session));
        ds_db_column_angles(s, i, &c->pose);
        i += GN_ROLE_COUNT;
        ds_db_column_text(s, i++, c->camera, sizeof(c->camera));
        ds_db_column_text(s, i++, c->lamps, sizeof(c->lamps));
        c->pose.lamps = (uint32_t)sqlite3_column_int64(s, i++);
        c->pose.lasers = (uint32_t)sqlite3_column_int64(s, i++);
        c->exposure_us = sqlite3_column_int(s, i++);
        c->gain = sqlite3_column_double(s, i++);
        c->t_request_ns = (uint64_t)sqlite3_column_int64(s, i++);
        c->t_exposure_ns = (uint64_t)sqlite3_column_int64(s, i++);
        c->t_stored_ns = (uint64_t)sqlite3_column_int64(s, i++);
        ds_db_column_text(s, i++, c->file, sizeof(c->file));
        ds_db_column_text(s, i++, c->sha256, sizeof(c->sha256));
        c->width = sqlite3_column_int(s, i++);
        c->height = sqlite3_column_int(s, i++);
        ds_db_column_text(s, i++, c->pixfmt, sizeof(c->pixfmt));
        c->plan_seq = sqlite3_column_int64(s, i++);
        ds_db_column_text(s, i++, c->kind, sizeof(c->kind));
        c->bracket = sqlite3_column_int(s, i++);
        c->dark_id = sqlite3_column_int64(s, i++);
        c->flat_id = sqlite3_column_int64(s, i++);
        c->size = sqlite3_column_int64(s, i++);
}
