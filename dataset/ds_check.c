/* ds_check.c - verification of a whole dataset: files against rows (ds_verify), files
 * without rows, temporary files, plan items against their rows, session counts, and
 * SQLite's own integrity check (see ds.h, docs/dataset.md).
 *
 * DESIGN
 * Everything here reads: ds_check runs on a second handle while goniod writes. A store
 * in flight there renames its image before it commits its row, so while another process
 * holds the writer's flock, an image whose id is above the last committed row and a
 * *.tmp file are stores in flight, not problems. Rows are never in flight: a row is
 * committed only once its file is durable. Each problem is one sentence naming the
 * file, row or plan item. */
#include <fcntl.h>
#include <stdarg.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>

#include "common/log.h"
#include "common/sha256.h"
#include "ds_internal.h"
#include "ds_session.h"

/* The largest distance in degrees between a row's angle and its plan item's. */

struct check {
        struct ds *d;
        ds_problem_fn fn;
        void *userdata;
        int problems;
        bool live; /* another process is the writer: stores may be in flight */
};

static void problem(struct check *ck, const char *fmt, ...) _printf_(2, 3);

static void problem(struct check *ck, const char *fmt, ...)
{
        char msg[1024];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        ck->problems++;
        if (ck->fn)
                ck->fn(msg, ck->userdata);
}

/* True when another open file description holds the dataset's writer lock. */
static bool other_writer(struct ds *d)
{
        _cleanup_close_ int fd = -EBADF;

        if (d->writer)
                return false;
        fd = openat(d->dir_fd, ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        return fd >= 0 && flock(fd, LOCK_SH | LOCK_NB) < 0 && errno == EWOULDBLOCK;
}

/* ---- rows against files ---- */

static int check_row_file(const struct ds_capture *c, void *userdata)
{
        struct check *ck = userdata;
        char hex[GN_SHA256_HEX];
        struct stat st;
        int r = 0;

        if (!ds_file_name_ok(c->file) || fstatat(ck->d->dir_fd, c->file, &st, 0) < 0)
                r = ds_file_name_ok(c->file) ? -errno : -ENOENT;
        if (r == 0 && c->size > 0 && st.st_size != c->size) {
                problem(ck, "Row %lld: %s is %lld bytes, its row says %lld.", (long long)c->id,
                        c->file, (long long)st.st_size, (long long)c->size);
                return 0;
        }
        if (r == 0)
                r = gn_sha256_file_at(ck->d->dir_fd, c->file, hex);
        if (r < 0 && r != -ENOENT)
                return ds_fail(ck->d, r, "Failed to read %s: %s", c->file, strerror(-r));
        if (r == -ENOENT)
                problem(ck, "Row %lld: %s is missing.", (long long)c->id, c->file);
        else if (strcmp(hex, c->sha256) != 0)
                problem(ck, "Row %lld: %s does not match its checksum.", (long long)c->id, c->file);
        return 0;
}

/* Re-hashes the file of every row. */
static int check_row_files(struct check *ck)
{
        int r = ds_rows(ck->d, 0, -1, check_row_file, ck);

        return r < 0 ? r : 0;
}

static void log_problem(const char *msg, void *userdata)
{
        struct ds *d = userdata;

        log_warning("dataset '%s': %s", d->path, msg);
}

int ds_verify(struct ds *d)
{
        struct check ck = {.d = d, .fn = log_problem, .userdata = d};
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d)
                return -EINVAL;
        r = check_row_files(&ck);
        return r < 0 ? r : ck.problems;
}

/* ---- files against rows ---- */

/* Reports a temporary file rel/name, unless a store may be writing it. */
static void check_tmp(struct check *ck, const char *rel, const char *name)
{
        if (!ck->live)
                problem(ck, "%s%s%s is a temporary file left by an interrupted write.",
                        strcmp(rel, ".") == 0 ? "" : rel, strcmp(rel, ".") == 0 ? "" : "/", name);
}

/* 1 when the index has a row of file, 0 when not. */
static int has_row(struct ds *d, const char *file)
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = ds_db_prepare(d, "SELECT 1 FROM captures WHERE file = ?", &s);
        if (r < 0)
                return r;
        sqlite3_bind_text(s, 1, file, -1, SQLITE_STATIC);
        rc = sqlite3_step(s);
        if (rc == SQLITE_ROW || rc == SQLITE_DONE)
                return rc == SQLITE_ROW;
        return ds_db_fail(d, rc, "Failed to look up a file");
}

/* An entry of images/: a temporary file, or an image that must have a row. */
static int check_image(const char *name, void *userdata)
{
        struct check *ck = userdata;
        char file[512];
        int64_t last = 0;
        int r;

        if (ds_tmp_name(name)) {
                check_tmp(ck, DS_IMAGES, name);
                return 0;
        }
        snprintf(file, sizeof(file), "%s/%s", DS_IMAGES, name);
        r = has_row(ck->d, file);
        if (r != 0)
                return r < 0 ? r : 0;
        if (ck->live) {
                r = ds_db_int64(ck->d, "SELECT coalesce(max(id), 0) FROM captures", &last);
                if (r < 0 || ds_image_id(name) > last)
                        return r;         /* renamed, its row not committed yet */
                r = has_row(ck->d, file); /* committed since the first look? */
                if (r != 0)
                        return r < 0 ? r : 0;
        }
        problem(ck, "%s has no row (left by an interrupted store, or not the store's).", file);
        return 0;
}

struct tmp_walk {
        struct check *ck;
        const char *rel;
};

/* An entry of a directory where only temporary files are problems. */
static int check_tmp_entry(const char *name, void *userdata)
{
        struct tmp_walk *w = userdata;

        if (ds_tmp_name(name))
                check_tmp(w->ck, w->rel, name);
        return 0;
}

/* A session directory of lp/: temporary .lp files. */
static int check_lp_dir(const char *name, void *userdata)
{
        struct check *ck = userdata;
        char rel[256];
        struct tmp_walk w = {ck, rel};
        int r;

        snprintf(rel, sizeof(rel), "lp/%s", name);
        r = ds_walk_dir(ck->d->dir_fd, rel, check_tmp_entry, &w);
        return r == -ENOTDIR ? 0 : r;
}

/* images/ against the rows; temporary files in the dataset's top directory and lp/. */
static int check_files(struct check *ck)
{
        struct tmp_walk top = {ck, "."};
        int r;

        r = ds_walk_dir(ck->d->img_fd, ".", check_image, ck);
        if (r == 0)
                r = ds_walk_dir(ck->d->dir_fd, ".", check_tmp_entry, &top);
        if (r == 0)
                r = ds_walk_dir(ck->d->dir_fd, "lp", check_lp_dir, ck);
        return r == -ENOENT ? 0 : r;
}

/* ---- the index ---- */

static const char *col(sqlite3_stmt *s, int i)
{
        const unsigned char *t = sqlite3_column_text(s, i);

        return t ? (const char *)t : "";
}

static void integrity_msg(struct check *ck, sqlite3_stmt *s)
{
        if (strcmp(col(s, 0), "ok") != 0)
                problem(ck, "SQLite's integrity check of %s: %s.", DS_INDEX, col(s, 0));
}

static void plan_index_msg(struct check *ck, sqlite3_stmt *s)
{
        if (sqlite3_column_int64(s, 0) == 0)
                problem(ck, "The index lacks captures_plan, the unique index that keeps plan "
                            "items from being stored twice.");
}

static void duplicate_msg(struct check *ck, sqlite3_stmt *s)
{
        problem(ck, "Plan item %lld of session '%s' has %lld rows (ids %s).",
                (long long)sqlite3_column_int64(s, 1), col(s, 0),
                (long long)sqlite3_column_int64(s, 2), col(s, 3));
}

static void no_item_msg(struct check *ck, sqlite3_stmt *s)
{
        problem(ck, "Row %lld (%s) names plan item %lld of session '%s', which does not exist.",
                (long long)sqlite3_column_int64(s, 0), col(s, 1),
                (long long)sqlite3_column_int64(s, 3), col(s, 2));
}

static void mismatch_msg(struct check *ck, sqlite3_stmt *s)
{
        problem(ck, "Row %lld (%s) disagrees with plan item %lld of session '%s' in:%s.",
                (long long)sqlite3_column_int64(s, 0), col(s, 1),
                (long long)sqlite3_column_int64(s, 3), col(s, 2), col(s, 4));
}

static void reference_msg(struct check *ck, sqlite3_stmt *s)
{
        problem(ck, "Row %lld (%s) refers to %s frame %lld, which is not a %s row.",
                (long long)sqlite3_column_int64(s, 0), col(s, 1), col(s, 2),
                (long long)sqlite3_column_int64(s, 3), col(s, 2));
}

static void session_msg(struct check *ck, sqlite3_stmt *s)
{
        const char *name = col(s, 0), *state = col(s, 1);
        int64_t planned = sqlite3_column_int64(s, 2), captured = sqlite3_column_int64(s, 3);
        int64_t items = sqlite3_column_int64(s, 4), done = sqlite3_column_int64(s, 5);

        if (planned != items)
                problem(ck, "Session '%s' records %lld planned captures, its plan has %lld items.",
                        name, (long long)planned, (long long)items);
        if (captured != done)
                problem(ck,
                        "Session '%s' records %lld captures, %lld of its plan items have a row.",
                        name, (long long)captured, (long long)done);
        if (strcmp(state, "done") == 0 && done < items)
                problem(ck, "Session '%s' is done, yet %lld of its %lld plan items have no row.",
                        name, (long long)(items - done), (long long)items);
}

/* The row differs from its plan item in: a list of " field" words, "" if it agrees. */
/* clang-format off */
#define ANGLE_DIFF(col, word)                                                                      \
        "(CASE WHEN p." col " IS NOT NULL AND coalesce(gn_angle_dist(c." col ", p." col ") > "     \
        DS_PLAN_POSE_TOL_DEG_SQL ", 1) THEN ' " word "' ELSE '' END)"
#define FIELD_DIFF(col, word) "(CASE WHEN c." col " <> p." col " THEN ' " word "' ELSE '' END)"

/* Rows disagreeing with their plan item, with the list of what differs. */
#define MISMATCH_SQL                                                                               \
        "SELECT * FROM (SELECT c.id, c.file, c.session, c.plan_seq, "                              \
        FIELD_DIFF("camera", "camera") " || " FIELD_DIFF("kind", "kind") " || "                    \
        FIELD_DIFF("bracket", "bracket") " || " FIELD_DIFF("lamp_bits", "lamps") " || "            \
        FIELD_DIFF("laser", "laser") " || " ANGLE_DIFF("turntable_deg", "turntable") " || "        \
        ANGLE_DIFF("light_arm_deg", "light_arm") " || " ANGLE_DIFF("camera_arm_deg", "camera_arm") \
        " AS diff FROM captures c JOIN plan p ON p.session = c.session AND p.seq = c.plan_seq)"    \
        " WHERE diff <> '' ORDER BY id"
/* clang-format on */

/* Each query of the index and what makes a problem of its rows. */
static const struct {
        const char *sql;
        void (*msg)(struct check *ck, sqlite3_stmt *s);
} queries[] = {
        {"PRAGMA integrity_check", integrity_msg},
        {"SELECT count(*) FROM sqlite_master WHERE type = 'index' AND name = 'captures_plan'",
         plan_index_msg},
        {"SELECT session, plan_seq, count(*), group_concat(id, ', ') FROM captures"
         " WHERE plan_seq IS NOT NULL GROUP BY session, plan_seq HAVING count(*) > 1",
         duplicate_msg},
        {"SELECT c.id, c.file, c.session, c.plan_seq FROM captures c WHERE c.plan_seq IS NOT NULL"
         " AND NOT EXISTS (SELECT 1 FROM plan p WHERE p.session = c.session"
         " AND p.seq = c.plan_seq) ORDER BY c.id",
         no_item_msg},
        {MISMATCH_SQL, mismatch_msg},
        {"SELECT c.id, c.file, 'dark', c.dark_id FROM captures c WHERE c.dark_id IS NOT NULL AND"
         " NOT EXISTS (SELECT 1 FROM captures x WHERE x.id = c.dark_id AND x.kind = 'dark')"
         " UNION ALL SELECT c.id, c.file, 'flat', c.flat_id FROM captures c WHERE c.flat_id IS"
         " NOT NULL AND NOT EXISTS (SELECT 1 FROM captures x WHERE x.id = c.flat_id AND"
         " x.kind = 'flat')",
         reference_msg},
        {"SELECT s.name, s.state, s.planned, s.captured,"
         " (SELECT count(*) FROM plan p WHERE p.session = s.name),"
         " (SELECT count(*) FROM plan p WHERE p.session = s.name AND EXISTS (SELECT 1 FROM"
         " captures c WHERE c.session = s.name AND c.plan_seq = p.seq)) FROM sessions s"
         " ORDER BY s.name",
         session_msg},
};

/* Runs sql and hands each of its rows to msg. */
static int check_query(struct check *ck, const char *sql,
                       void (*msg)(struct check *ck, sqlite3_stmt *s))
{
        _cleanup_(sqlite3_finalizep) sqlite3_stmt *s = NULL;
        int r, rc;

        r = ds_db_prepare(ck->d, sql, &s);
        if (r < 0)
                return r;
        while ((rc = sqlite3_step(s)) == SQLITE_ROW)
                msg(ck, s);
        return rc == SQLITE_DONE ? 0 : ds_db_fail(ck->d, rc, "Failed to check the index");
}

int ds_check(struct ds *d, ds_problem_fn fn, void *userdata)
{
        struct check ck = {.d = d, .fn = fn, .userdata = userdata};
        int r = 0;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d)
                return -EINVAL;
        d->error[0] = 0;
        ck.live = other_writer(d);
        for (size_t i = 0; r == 0 && i < ELEMENTSOF(queries); i++)
                r = check_query(&ck, queries[i].sql, queries[i].msg);
        if (r == 0)
                r = check_row_files(&ck);
        if (r == 0)
                r = check_files(&ck);
        return r < 0 ? r : ck.problems;
}
