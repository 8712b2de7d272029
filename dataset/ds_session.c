/* ds_session.c - sessions in the index: start record and plan in one transaction, state
 * and stop record, the plan items still to capture, and the dark library (see
 * ds_session.h, docs/dataset.md).
 *
 * DESIGN
 * The plan lives in the index (table plan, one row per item) so that resume needs
 * nothing but the dataset: the items still to capture are those without a capture row
 * (NOT EXISTS on the unique (session, plan_seq) index of captures). Each session keeps
 * its count of captured items, updated in the transaction of each row (ds_index.c), so
 * a summary never counts rows; ds_check recounts.
 *
 * The dark library of a data directory is the dataset "darks" in it: sessions of any
 * dataset copy their dark rows there (ds_library_add_darks) and later sessions, in other
 * datasets, import them back (ds_import_frame). Its rows are outside any plan (session
 * "library", no plan_seq), so exactly once there is by the frame: a dark row is added
 * unless the library has one of the same checksum, camera, exposure, gain and exposure
 * time, looked up under the library's writer lock. */
#include <limits.h>
#include <math.h>
#include <string.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "ds_internal.h"
#include "ds_session.h"

static bool session_name_ok(const char *name)
{
        return name && *name && strlen(name) < DS_NAME_MAX;
}

static bool state_ended(const char *state)
{
        return strcmp(state, "done") == 0 || strcmp(state, "aborted") == 0 ||
               strcmp(state, "failed") == 0;
}

static bool state_ok(const char *state)
{
        return state && (state_ended(state) || strcmp(state, "running") == 0 ||
                         strcmp(state, "paused") == 0);
}

/* Inserts the start record of session name with n planned items. */
static int insert_session(struct ds *d, const char *name, const char *const text[4], size_t n)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        char now[32];
        int r, rc;

        r = ds_db_prepare(d,
                          "INSERT INTO sessions (name, state, started, started_ns, file_text,"
                          " rig_text, plan_json, metadata_json, planned)"
                          " VALUES (?, 'running', ?, ?, ?, ?, ?, ?, ?)",
                          &s);
        if (r < 0)
                return r;
        ds_iso8601_now(now, sizeof(now));
        sqlite3_bind_text(s, 1, name, -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 2, now, -1, SQLITE_STATIC);
        sqlite3_bind_int64(s, 3, (sqlite3_int64)gn_realtime_ns());
        for (int i = 0; i < 4; i++)
                sqlite3_bind_text(s, 4 + i, text[i] ? text[i] : "", -1, SQLITE_STATIC);
        sqlite3_bind_int64(s, 8, (sqlite3_int64)n);
        rc = sqlite3_step(s);
        if (rc == SQLITE_CONSTRAINT_PRIMARYKEY)
                return ds_fail(d, -EEXIST, "session '%s' exists already", name);
        return rc == SQLITE_DONE ? 0 : ds_db_fail(d, rc, "Failed to record the session");
}

/* Inserts one plan item of session with the prepared statement s. */
static int insert_item(struct ds *d, sqlite3_stmt *s, const char *session,
                       const struct ds_plan_item *it)
{
        const char *kind = it->kind[0] ? it->kind : "image";
        int rc = 0;

        if (it->seq < 1 || !it->camera[0] || !ds_kind_ok(kind))
                return ds_fail(d, -EINVAL, "plan item %lld: bad seq, camera or kind",
                               (long long)it->seq);
        rc |= sqlite3_bind_text(s, 1, session, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_int64(s, 2, it->seq);
        rc |= sqlite3_bind_int64(s, 3, it->shot);
        rc |= sqlite3_bind_text(s, 4, it->camera, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_text(s, 5, kind, -1, SQLITE_STATIC);
        rc |= sqlite3_bind_int(s, 6, it->bracket);
        rc |= ds_db_bind_angles(s, 7, &it->pose);
        rc |= sqlite3_bind_int64(s, 10, it->pose.lamps);
        rc |= sqlite3_bind_int64(s, 11, it->pose.lasers);
        rc |= sqlite3_bind_int(s, 12, it->exposure_us);
        rc |= sqlite3_bind_double(s, 13, it->gain);
        if (rc == SQLITE_OK)
                rc = sqlite3_step(s);
        sqlite3_reset(s);
        if (rc != SQLITE_DONE)
                return ds_db_fail(d, rc, "Failed to record a plan item");
        return 0;
}

/* The start record and every plan item (caller's transaction). */
static int record_session(struct ds *d, const char *name, const char *const text[4],
                          const struct ds_plan_item *items, size_t n)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r;

        r = insert_session(d, name, text, n);
        if (r == 0)
                r = ds_db_prepare(d,
                                  "INSERT INTO plan (session, seq, shot, camera, kind, bracket,"
                                  " turntable_deg, light_arm_deg, camera_arm_deg, lamp_bits,"
                                  " laser, exposure_us, gain)"
                                  " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                  &s);
        for (size_t i = 0; r == 0 && i < n; i++)
                r = insert_item(d, s, name, &items[i]);
        return r;
}

int ds_session_begin(struct ds *d, const char *name, const char *file_text, const char *rig_text,
                     const char *plan_json, const char *metadata_json,
                     const struct ds_plan_item *items, size_t n)
{
        const char *const text[4] = {file_text, rig_text, plan_json, metadata_json};
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !session_name_ok(name) || (n > 0 && !items))
                return -EINVAL;
        d->error[0] = 0;
        r = ds_db_exec(d, "BEGIN IMMEDIATE");
        if (r < 0)
                return r;
        r = record_session(d, name, text, items, n);
        if (r == 0)
                r = ds_db_exec(d, "COMMIT");
        if (r < 0 && !sqlite3_get_autocommit(d->db))
                (void)sqlite3_exec(d->db, "ROLLBACK", NULL, NULL, NULL);
        if (r == 0)
                log_info("dataset '%s': session '%s' begins, %zu captures planned", d->path, name,
                         n);
        return r;
}

/* Updates the session's row, in the caller's transaction. */
static int update_state(struct ds *d, const char *name, const char *state, const char *reason)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        char now[32] = "";
        int r, rc;

        r = ds_db_prepare(
                d, "UPDATE sessions SET state = ?, reason = ?, stopped = ? WHERE name = ?", &s);
        if (r < 0)
                return r;
        if (state_ended(state))
                ds_iso8601_now(now, sizeof(now));
        sqlite3_bind_text(s, 1, state, -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 2, reason ? reason : "", -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 3, now, -1, SQLITE_STATIC);
        sqlite3_bind_text(s, 4, name, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc != SQLITE_DONE)
                return ds_db_fail(d, rc, "Failed to record the session's state");
        if (sqlite3_changes(d->db) == 0)
                return ds_fail(d, -ENOENT, "no session '%s'", name);
        return 0;
}

int ds_session_set_state(struct ds *d, const char *name, const char *state, const char *reason)
{
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !session_name_ok(name) || !state_ok(state))
                return -EINVAL;
        d->error[0] = 0;
        /* dataset.json is written before the end is committed: a crash in between leaves the
         * session unfinished, and its resume claims the dataset (removing dataset.json.tmp) */
        r = ds_db_exec(d, "BEGIN IMMEDIATE");
        if (r == 0)
                r = update_state(d, name, state, reason);
        if (r == 0 && state_ended(state) && d->writer)
                r = ds_write_json(d);
        if (r == 0)
                r = ds_db_exec(d, "COMMIT");
        if (r < 0 && !sqlite3_get_autocommit(d->db))
                (void)sqlite3_exec(d->db, "ROLLBACK", NULL, NULL, NULL);
        if (r == 0)
                log_info("dataset '%s': session '%s' %s%s%s", d->path, name, state,
                         reason ? ": " : "", reason ? reason : "");
        return r;
}

void ds_session_info_clear(struct ds_session_info *s)
{
        if (!s)
                return;
        free(s->file_text);
        free(s->rig_text);
        free(s->plan_json);
        free(s->metadata_json);
        memset(s, 0, sizeof(*s));
}

/* Copies the texts of columns first.. into out's malloc'd strings. */
static int read_texts(sqlite3_stmt *s, int first, struct ds_session_info *out)
{
        char **texts[] = {&out->file_text, &out->rig_text, &out->plan_json, &out->metadata_json};

        for (size_t i = 0; i < ELEMENTSOF(texts); i++) {
                const unsigned char *t = sqlite3_column_text(s, first + (int)i);

                *texts[i] = strdup(t ? (const char *)t : "");
                if (!*texts[i])
                        return -ENOMEM;
        }
        return 0;
}

int ds_session_get(struct ds *d, const char *name, struct ds_session_info *out)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !name || !out)
                return -EINVAL;
        memset(out, 0, sizeof(*out));
        r = ds_db_prepare(d,
                          "SELECT name, state, started, stopped, reason, planned, captured,"
                          " file_text, rig_text, plan_json, metadata_json"
                          " FROM sessions WHERE name = ?",
                          &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, name, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc == SQLITE_DONE)
                return -ENOENT;
        if (rc != SQLITE_ROW)
                return ds_db_fail(d, rc, "Failed to read the session");
        ds_db_column_text(s, 0, out->name, sizeof(out->name));
        ds_db_column_text(s, 1, out->state, sizeof(out->state));
        ds_db_column_text(s, 2, out->started, sizeof(out->started));
        ds_db_column_text(s, 3, out->stopped, sizeof(out->stopped));
        ds_db_column_text(s, 4, out->reason, sizeof(out->reason));
        out->planned = sqlite3_column_int64(s, 5);
        out->captured = sqlite3_column_int64(s, 6);
        r = read_texts(s, 7, out);
        if (r < 0)
                ds_session_info_clear(out);
        return r;
}

int ds_session_unfinished(struct ds *d, char *name, size_t len)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !name || len == 0)
                return -EINVAL;
        r = ds_db_prepare(d,
                          "SELECT name FROM sessions WHERE state IN ('running', 'paused')"
                          " ORDER BY started_ns DESC, rowid DESC LIMIT 1",
                          &s);
        if (r < 0)
                return r;
        rc = sqlite3_step(s);
        if (rc == SQLITE_DONE)
                return -ENOENT;
        if (rc != SQLITE_ROW)
                return ds_db_fail(d, rc, "Failed to read sessions");
        ds_db_column_text(s, 0, name, len);
        return 0;
}

/* Fills it from a row of the pending query. */
static void read_item(sqlite3_stmt *s, struct ds_plan_item *it)
{
        memset(it, 0, sizeof(*it));
        it->seq = sqlite3_column_int64(s, 0);
        it->shot = sqlite3_column_int64(s, 1);
        ds_db_column_text(s, 2, it->camera, sizeof(it->camera));
        ds_db_column_text(s, 3, it->kind, sizeof(it->kind));
        it->bracket = sqlite3_column_int(s, 4);
        ds_db_column_angles(s, 5, &it->pose);
        it->pose.lamps = (uint32_t)sqlite3_column_int64(s, 8);
        it->pose.lasers = (uint32_t)sqlite3_column_int64(s, 9);
        it->exposure_us = sqlite3_column_int(s, 10);
        it->gain = sqlite3_column_double(s, 11);
}

/* -ENOENT unless session exists. */
static int session_exists(struct ds *d, const char *session)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = ds_db_prepare(d, "SELECT 1 FROM sessions WHERE name = ?", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, session, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc == SQLITE_ROW)
                return 0;
        return rc == SQLITE_DONE ? -ENOENT : ds_db_fail(d, rc, "Failed to read sessions");
}

int ds_plan_pending(struct ds *d, const char *session, ds_plan_fn fn, void *userdata)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        struct ds_plan_item it;
        int n = 0, r, rc;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !session || !fn)
                return -EINVAL;
        r = session_exists(d, session);
        if (r == 0)
                r = ds_db_prepare(
                        d,
                        "SELECT seq, shot, camera, kind, bracket, turntable_deg, light_arm_deg,"
                        " camera_arm_deg, lamp_bits, laser, exposure_us, gain FROM plan p"
                        " WHERE p.session = ?1 AND NOT EXISTS (SELECT 1 FROM captures c"
                        " WHERE c.session = ?1 AND c.plan_seq = p.seq) ORDER BY p.seq",
                        &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, session, -1, SQLITE_STATIC);
        while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
                read_item(s, &it);
                r = fn(&it, userdata);
                if (r < 0)
                        return r;
                n++;
        }
        return rc == SQLITE_DONE ? n : ds_db_fail(d, rc, "Failed to read the plan");
}

/* The newest row of kind from camera (with exposure_us and gain unless exposure_us < 0)
 * taken at or after not_before_ns: its id, 0 if none, or -errno. */
static int64_t find_frame(struct ds *d, const char *kind, const char *camera, int exposure_us,
                          double gain, uint64_t not_before_ns)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !camera)
                return -EINVAL;
        r = ds_db_prepare(d,
                          "SELECT id FROM captures WHERE kind = ?5 AND camera = ?1"
                          " AND (?2 < 0 OR (exposure_us = ?2 AND abs(gain - ?3) <= 1e-6))"
                          " AND t_exposure_ns >= ?4 ORDER BY t_exposure_ns DESC, id DESC LIMIT 1",
                          &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, camera, -1, SQLITE_STATIC);
        sqlite3_bind_int(s, 2, exposure_us);
        sqlite3_bind_double(s, 3, gain);
        sqlite3_bind_int64(s, 4, (sqlite3_int64)MIN(not_before_ns, (uint64_t)INT64_MAX));
        sqlite3_bind_text(s, 5, kind, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc == SQLITE_ROW)
                return sqlite3_column_int64(s, 0);
        return rc == SQLITE_DONE ? 0 : ds_db_fail(d, rc, "Failed to look up a reference frame");
}

int64_t ds_find_dark(struct ds *d, const char *camera, int exposure_us, double gain,
                     uint64_t not_before_ns)
{
        return exposure_us < 0 ? -EINVAL
                               : find_frame(d, "dark", camera, exposure_us, gain, not_before_ns);
}

int64_t ds_find_flat(struct ds *d, const char *camera)
{
        return find_frame(d, "flat", camera, -1, 0, 0);
}

/* ---- importing frames, the data directory's dark library ---- */

static int take_row(const struct ds_capture *c, void *userdata)
{
        *(struct ds_capture *)userdata = *c;
        return 0;
}

/* Reads row id of d into c. Returns 0, -ENOENT or -errno. */
static int read_row(struct ds *d, int64_t id, struct ds_capture *c)
{
        int r;

        c->id = 0;
        r = ds_rows(d, id - 1, 1, take_row, c);
        if (r < 0)
                return r;
        return c->id == id ? 0 : -ENOENT;
}

int64_t ds_import_frame(struct ds *dst, struct ds *src, int64_t src_id,
                        const struct ds_capture *label)
{
        struct ds_capture c;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!dst || !src || src_id < 1 || !label)
                return -EINVAL;
        dst->error[0] = 0;
        r = read_row(src, src_id, &c);
        if (r < 0)
                return ds_fail(dst, r, "Failed to read row %lld of dataset '%s': %s",
                               (long long)src_id, src->path, strerror(-r));
        snprintf(c.session, sizeof(c.session), "%s", label->session);
        c.plan_seq = label->plan_seq;
        if (label->kind[0])
                snprintf(c.kind, sizeof(c.kind), "%s", label->kind);
        c.bracket = label->bracket;
        c.dark_id = label->dark_id;
        c.flat_id = label->flat_id;
        r = ds_import_file(dst, src->dir_fd, c.file, &c);
        return r < 0 ? r : c.id;
}

int ds_library_open(const char *data_dir, bool create, struct ds **ret)
{
        char path[PATH_MAX];
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!data_dir || !ret)
                return -EINVAL;
        if (snprintf(path, sizeof(path), "%s/%s", data_dir, DS_LIBRARY) >= (int)sizeof(path))
                return -ENAMETOOLONG;
        if (access(path, F_OK) < 0 && errno == ENOENT) {
                if (!create)
                        return -ENOENT; /* no library yet: not an error to log */
                r = ds_create(path, DS_LIBRARY, NULL, ret);
                if (r != -EEXIST) /* else created meanwhile by another process */
                        return r;
        }
        return ds_open(path, ret);
}

struct add_darks {
        struct ds *lib, *src;
        sqlite3_stmt *known; /* of lib: has it this frame? */
        int added;
};

/* 1 when the library has the frame c (the same checksum, camera, exposure, gain and
 * exposure time), 0 when not. */
static int library_has(struct add_darks *a, const struct ds_capture *c)
{
        int rc;

        sqlite3_bind_text(a->known, 1, c->sha256, -1, SQLITE_STATIC);
        sqlite3_bind_text(a->known, 2, c->camera, -1, SQLITE_STATIC);
        sqlite3_bind_int(a->known, 3, c->exposure_us);
        sqlite3_bind_double(a->known, 4, c->gain);
        sqlite3_bind_int64(a->known, 5, (sqlite3_int64)c->t_exposure_ns);
        rc = sqlite3_step(a->known);
        sqlite3_reset(a->known);
        if (rc == SQLITE_ROW || rc == SQLITE_DONE)
                return rc == SQLITE_ROW;
        return ds_db_fail(a->lib, rc, "Failed to look up a dark frame");
}

/* Imports the dark row c of the source unless the library has it. */
static int add_dark(struct add_darks *a, const struct ds_capture *c)
{
        struct ds_capture label = {.session = DS_LIBRARY_SESSION, .kind = "dark"};
        int64_t id;
        int r;

        r = library_has(a, c);
        if (r != 0)
                return MIN(r, 0);
        id = ds_import_frame(a->lib, a->src, c->id, &label);
        if (id < 0)
                return (int)id;
        a->added++;
        return 0;
}

/* Calls add_dark for each dark row of session (NULL: all) of a->src, in id order. */
static int walk_darks(struct add_darks *a, const char *session)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        struct ds_capture c;
        int r, rc;

        r = ds_db_prepare(a->src,
                          "SELECT " DS_ROW_COLUMNS " FROM captures WHERE kind = 'dark'"
                          " AND (?1 IS NULL OR session = ?1) ORDER BY id",
                          &s);
        if (r < 0)
                return r;
        if (session)
                sqlite3_bind_text(s, 1, session, -1, SQLITE_STATIC);
        while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
                ds_db_read_row(s, &c);
                r = add_dark(a, &c);
                if (r < 0)
                        return r;
        }
        return rc == SQLITE_DONE ? 0 : ds_db_fail(a->src, rc, "Failed to read dark frames");
}

int ds_library_add_darks(struct ds *lib, struct ds *src, const char *session)
{
        struct add_darks a = {.lib = lib, .src = src};
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!lib || !src || lib == src)
                return -EINVAL;
        lib->error[0] = 0;
        r = ds_become_writer(lib); /* no other process adds between look-up and import */
        if (r == 0)
                r = ds_db_prepare(lib,
                                  "SELECT 1 FROM captures WHERE kind = 'dark' AND sha256 = ?"
                                  " AND camera = ? AND exposure_us = ? AND gain = ?"
                                  " AND t_exposure_ns = ?",
                                  &a.known);
        if (r == 0)
                r = walk_darks(&a, session);
        sqlite3_finalize(a.known);
        if (a.added > 0)
                log_info("dark library '%s': %d dark frame(s) added from '%s'", lib->path, a.added,
                         src->path);
        return r < 0 ? r : a.added;
}
