/* ds_read.c - the read API of the dataset library: summary, rows by range and by pose,
 * images (see ds.h; verification: ds_check.c). Every query is bounded by its result:
 * the summary reads the names and sessions tables and the primary key, rows use LIMIT
 * on the key. */
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"
#include "common/log.h"
#include "ds_internal.h"
#include "ds_png.h"

int64_t ds_count(struct ds *d)
{
        int64_t n = 0;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d)
                return -EINVAL;
        r = ds_db_int64(d, "SELECT coalesce(sum(captures), 0) FROM names WHERE kind = 'camera'",
                        &n);
        return r < 0 ? r : n;
}

/* Fills names with up to DS_SUMMARY_MAX_NAMES names of kind, by name. */
static int read_names(struct ds *d, const char *kind, struct ds_name_count *names, size_t *n)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc = SQLITE_DONE;

        *n = 0;
        r = ds_db_prepare(
                d, "SELECT name, captures FROM names WHERE kind = ? ORDER BY name LIMIT ?", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, kind, -1, SQLITE_STATIC);
        sqlite3_bind_int(s, 2, DS_SUMMARY_MAX_NAMES);
        while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
                snprintf(names[*n].name, sizeof(names[*n].name), "%s",
                         (const char *)sqlite3_column_text(s, 0));
                names[(*n)++].captures = sqlite3_column_int64(s, 1);
        }
        return rc == SQLITE_DONE ? 0 : ds_db_fail(d, rc, "Failed to read names");
}

/* Fills out->sessions with the DS_SUMMARY_MAX_NAMES newest sessions, oldest first. */
static int read_sessions(struct ds *d, struct ds_summary *out)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc = SQLITE_DONE;

        r = ds_db_prepare(d,
                          "SELECT name, state, planned, captured FROM (SELECT rowid AS r, *"
                          " FROM sessions ORDER BY started_ns DESC, rowid DESC LIMIT ?)"
                          " ORDER BY started_ns, r",
                          &s);
        if (r < 0)
                return r;
        sqlite3_bind_int(s, 1, DS_SUMMARY_MAX_NAMES);
        while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
                struct ds_session_count *c = &out->sessions[out->n_sessions++];

                snprintf(c->name, sizeof(c->name), "%s", (const char *)sqlite3_column_text(s, 0));
                snprintf(c->state, sizeof(c->state), "%s", (const char *)sqlite3_column_text(s, 1));
                c->planned = sqlite3_column_int64(s, 2);
                c->captured = sqlite3_column_int64(s, 3);
        }
        return rc == SQLITE_DONE ? 0 : ds_db_fail(d, rc, "Failed to read sessions");
}

int ds_summary(struct ds *d, struct ds_summary *out)
{
        int64_t n;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !out)
                return -EINVAL;
        memset(out, 0, sizeof(*out));
        snprintf(out->name, sizeof(out->name), "%s", d->name);
        snprintf(out->created, sizeof(out->created), "%s", d->created);
        snprintf(out->rig, sizeof(out->rig), "%s", d->rig);
        out->schema_version = DS_SCHEMA_VERSION;
        n = ds_count(d);
        if (n < 0)
                return (int)n;
        out->captures = n;
        r = ds_db_int64(d, "SELECT coalesce(max(id), 0) FROM captures", &out->last_id);
        if (r == 0)
                r = read_names(d, "camera", out->cameras, &out->n_cameras);
        if (r == 0)
                r = read_names(d, "lamp", out->lamps, &out->n_lamps);
        if (r == 0)
                r = read_sessions(d, out);
        return r;
}

/* Steps a prepared row query, calling fn for each row. */
static int run_rows(struct ds *d, sqlite3_stmt *s, ds_row_fn fn, void *userdata)
{
        struct ds_capture c;
        int n = 0, r, rc;

        while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
                ds_db_read_row(s, &c);
                r = fn(&c, userdata);
                if (r < 0)
                        return r;
                n++;
        }
        return rc == SQLITE_DONE ? n : ds_db_fail(d, rc, "Failed to read captures");
}

int ds_rows(struct ds *d, int64_t after_id, int limit, ds_row_fn fn, void *userdata)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !fn)
                return -EINVAL;
        r = ds_db_prepare(d,
                          "SELECT " DS_ROW_COLUMNS " FROM captures WHERE id > ? ORDER BY id"
                          " LIMIT ?",
                          &s);
        if (r < 0)
                return r;
        sqlite3_bind_int64(s, 1, after_id);
        sqlite3_bind_int(s, 2, limit < 0 ? -1 : limit);
        return run_rows(d, s, fn, userdata);
}

/* The growing result of ds_rows_collect. */
struct collect {
        ds_keep_fn keep;
        void *userdata;
        struct ds_capture *rows;
        size_t n, cap;
};

static int collect_row(const struct ds_capture *c, void *userdata)
{
        struct collect *k = userdata;

        if (k->keep && !k->keep(c, k->userdata))
                return 0;
        if (k->n == k->cap) {
                size_t cap = k->cap ? 2 * k->cap : 64;
                struct ds_capture *p = reallocarray(k->rows, cap, sizeof(*p));

                if (!p)
                        return -ENOMEM;
                k->rows = p;
                k->cap = cap;
        }
        k->rows[k->n++] = *c;
        return 0;
}

int ds_rows_collect(struct ds *d, ds_keep_fn keep, void *userdata, struct ds_capture **rows,
                    size_t *n)
{
        struct collect k = {.keep = keep, .userdata = userdata};
        int r = ds_rows(d, 0, -1, collect_row, &k);

        if (r < 0) {
                free(k.rows);
                k = (struct collect){0};
        }
        *rows = k.rows;
        *n = k.n;
        return r < 0 ? r : 0;
}

int ds_rows_by_pose(struct ds *d, const struct gn_pose *p, double tol_deg, ds_row_fn fn,
                    void *userdata)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !p || !fn || !(tol_deg >= 0))
                return -EINVAL;
        r = ds_db_prepare(d,
                          "SELECT " DS_ROW_COLUMNS " FROM captures WHERE"
                          " (?1 IS NULL OR gn_angle_dist(turntable_deg, ?1) <= ?4) AND"
                          " (?2 IS NULL OR gn_angle_dist(light_arm_deg, ?2) <= ?4) AND"
                          " (?3 IS NULL OR gn_angle_dist(camera_arm_deg, ?3) <= ?4) ORDER BY id",
                          &s);
        if (r < 0)
                return r;
        for (int k = 0; k < GN_ROLE_COUNT; k++)
                if (gn_pose_has(p, k))
                        sqlite3_bind_double(s, k + 1, p->deg[k]);
        sqlite3_bind_double(s, 4, tol_deg);
        return run_rows(d, s, fn, userdata);
}

bool ds_file_name_ok(const char *file)
{
        return file && *file && file[0] != '/' && !strstr(file, "..");
}

int ds_load_image(struct ds *d, const char *file, struct gn_frame *out)
{
        _cleanup_free_ void *buf = NULL;
        size_t len = 0;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !ds_file_name_ok(file) || !out)
                return -EINVAL;
        r = gn_read_file_at(d->dir_fd, file, DS_FILE_MAX, &buf, &len);
        if (r == 0)
                r = ds_png_decode(buf, len, out);
        if (r < 0)
                return ds_fail(d, r, "Failed to load %s: %s", file, strerror(-r));
        return 0;
}
