/* ds.c - the dataset store: PNG images written atomically, an SQLite index (WAL)
 * with one row per capture, rig.yaml and dataset.json (see ds.h, docs/dataset.md).
 *
 * DESIGN
 * Durability protocol of ds_store: encode -> write images/NAME.tmp while hashing
 * the bytes -> fsync(file) -> rename to NAME -> fsync(images/) -> INSERT the row
 * and count its names in one transaction (ds_index.c). The row is committed only after its file is
 * durable, so the index never names a missing or torn file. A crash between the rename and the
 * commit leaves an image whose id is above the last row: the first writer to open the dataset again
 * removes such orphans and any *.tmp (images/, the top directory, lp/SESSION/) before storing.
 *
 * A row of a session's plan item is stored exactly once: (session, plan_seq) is looked
 * up before the image is written (-EEXIST, nothing written), and the unique index
 * captures_plan refuses a second row from anyone.
 *
 * ds_import_file puts an image of another dataset in place as a hard link (link(2) is
 * atomic: the name appears complete; then fsync(images/)) or, across file systems, as a
 * copy by the same durable write, and commits its row the same way; the image is read
 * back once (link) or hashed as written (copy) and must match the source row's checksum.
 *
 * Row ids come from the store's own sequence (max(id) + 1 when the writer starts),
 * so the file name is known before the row exists. One process writes a dataset at
 * a time (flock on the dataset directory, taken by the first ds_store); readers
 * never lock. */
#include <ctype.h>
#include <dirent.h>
#include <fcntl.h>
#include <jansson.h>
#include <limits.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>

#include "common/clock.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/sha256.h"
#include "common/yconf.h"
#include "ds_internal.h"
#include "ds_png.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(DIR *, closedir);

static struct ds *ds_free(struct ds *d);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_free);

_Thread_local bool ds_thread_forbidden;

void ds_forbid_thread(bool forbid)
{
        ds_thread_forbidden = forbid;
}

/* ---- dataset.json ---- */

/* The names of a summary as a JSON array. */
static json_t *names_json(const struct ds_name_count *names, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                if (json_array_append_new(a, json_string(names[i].name)) < 0)
                        return json_decref(a), NULL;
        return a;
}

/* The sessions of a summary as a JSON array of {name, state, planned, captured}. */
static json_t *sessions_json(const struct ds_session_count *s, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                if (json_array_append_new(a, json_pack("{s:s, s:s, s:I, s:I}", "name", s[i].name,
                                                       "state", s[i].state, "planned",
                                                       (json_int_t)s[i].planned, "captured",
                                                       (json_int_t)s[i].captured)) < 0)
                        return json_decref(a), NULL;
        return a;
}

int ds_write_json(struct ds *d)
{
        _cleanup_(json_decrefp) json_t *j = NULL;
        _cleanup_free_ char *text = NULL;
        struct ds_summary sum;
        int r;

        r = ds_summary(d, &sum);
        if (r < 0)
                return r;
        j = json_pack("{s:s, s:s, s:s, s:I, s:o?, s:o?, s:o?, s:s, s:s, s:i}", "name", sum.name,
                      "created", sum.created, "rig", sum.rig, "captures", (json_int_t)sum.captures,
                      "cameras", names_json(sum.cameras, sum.n_cameras), "lamps",
                      names_json(sum.lamps, sum.n_lamps), "sessions",
                      sessions_json(sum.sessions, sum.n_sessions), "format", "png", "index",
                      DS_INDEX, "schema_version", sum.schema_version);
        text = j ? json_dumps(j, JSON_INDENT(2)) : NULL;
        if (!text)
                return -ENOMEM;
        r = gn_write_atomic(d->dir_fd, DS_JSON, text, strlen(text), NULL);
        if (r < 0)
                return ds_fail(d, r, "Failed to write %s: %s", DS_JSON, strerror(-r));
        return 0;
}

/* ---- lifetime ---- */

static struct ds *ds_free(struct ds *d)
{
        if (!d)
                return NULL;
        sqlite3_finalize(d->insert);
        sqlite3_finalize(d->add_name);
        sqlite3_finalize(d->count_captured);
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

void ds_iso8601_now(char *buf, size_t len)
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
        ds_iso8601_now(d->created, sizeof(d->created));
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
        r = ds_db_open(d, true);
        if (r == 0)
                r = ds_write_json(d);
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

        DS_ASSERT_THREAD_ALLOWED();

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

static int read_meta(struct ds *d)
{
        int r;

        r = ds_meta_get(d, "name", d->name, sizeof(d->name));
        if (r == 0)
                r = ds_meta_get(d, "created", d->created, sizeof(d->created));
        if (r == 0)
                r = ds_meta_get(d, "rig", d->rig, sizeof(d->rig));
        return r;
}

int ds_open(const char *path, struct ds **ret)
{
        _cleanup_(ds_freep) struct ds *d = NULL;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!path || !ret)
                return -EINVAL;
        r = ds_alloc(path, &d);
        if (r < 0)
                return log_error_errno(r, "Cannot open dataset '%s': %m", path);
        d->img_fd = openat(d->dir_fd, DS_IMAGES, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (d->img_fd < 0)
                return log_error_errno(errno == ENOENT ? SYNTHETIC_ERRNO(EBADMSG) : errno,
                                       "'%s' is not a dataset (no %s/): %m", path, DS_IMAGES);
        r = ds_db_open(d, false);
        if (r == 0)
                r = read_meta(d);
        if (r < 0)
                return r;
        *ret = TAKE_PTR(d);
        return 0;
}

struct ds *ds_close(struct ds *d)
{
        if (d)
                DS_ASSERT_THREAD_ALLOWED();
        if (d && d->writer)
                (void)ds_write_json(d);
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

/* ---- storing ---- */

int64_t ds_image_id(const char *name)
{
        char *end = NULL;
        long long id;

        if (!isdigit((unsigned char)name[0]))
                return -1;
        id = strtoll(name, &end, 10);
        return *end == '_' ? id : -1;
}

int ds_walk_dir(int dir_fd, const char *rel, int (*fn)(const char *name, void *userdata),
                void *userdata)
{
        _cleanup_(closedirp) DIR *dir = NULL;
        struct dirent *de;
        int fd, r;

        fd = openat(dir_fd, rel, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0)
                return -errno;
        dir = fdopendir(fd);
        if (!dir) {
                close(fd);
                return -errno;
        }
        while ((errno = 0, de = readdir(dir)))
                if (strcmp(de->d_name, ".") != 0 && strcmp(de->d_name, "..") != 0 &&
                    (r = fn(de->d_name, userdata)) < 0)
                        return r;
        return errno > 0 ? -errno : 0;
}

bool ds_tmp_name(const char *name)
{
        size_t n = strlen(name);

        return n > 4 && strcmp(name + n - 4, ".tmp") == 0;
}

struct orphans {
        struct ds *d;
        int removed;
};

/* Removes the image name if it is a *.tmp or has no row (id >= next_id). */
static int remove_orphan(const char *name, void *userdata)
{
        struct orphans *o = userdata;

        if (!ds_tmp_name(name) && ds_image_id(name) < o->d->next_id)
                return 0;
        log_notice("dataset '%s': removing %s/%s left by an interrupted store", o->d->path,
                   DS_IMAGES, name);
        if (unlinkat(o->d->img_fd, name, 0) < 0)
                return -errno;
        o->removed++;
        return 0;
}

/* A directory of the dataset (rel) holding files written with gn_write_atomic. */
struct tmp_dir {
        struct ds *d;
        const char *rel;
};

/* Removes rel/name if it is a *.tmp: a write cut short (dataset.json, rig.yaml, .lp). */
static int remove_tmp(const char *name, void *userdata)
{
        struct tmp_dir *t = userdata;
        char path[512];

        if (!ds_tmp_name(name))
                return 0;
        snprintf(path, sizeof(path), "%s/%s", t->rel, name);
        log_notice("dataset '%s': removing %s left by an interrupted write", t->d->path, path);
        return unlinkat(t->d->dir_fd, path, 0) < 0 ? -errno : 0;
}

/* A session directory of lp/: its *.tmp. */
static int remove_lp_tmp(const char *name, void *userdata)
{
        struct tmp_dir *top = userdata;
        char rel[256];
        struct tmp_dir t = {top->d, rel};
        int r;

        snprintf(rel, sizeof(rel), "lp/%s", name);
        r = ds_walk_dir(top->d->dir_fd, rel, remove_tmp, &t);
        return r == -ENOTDIR ? 0 : r;
}

/* Removes images without a row (id >= next_id) and every *.tmp that ds_check reports
 * (images/, the top directory, lp/SESSION/) left by a crash. */
static int remove_orphans(struct ds *d)
{
        struct orphans o = {.d = d};
        struct tmp_dir top = {d, "."};
        int r;

        r = ds_walk_dir(d->img_fd, ".", remove_orphan, &o);
        if (r == 0 && o.removed > 0 && fsync(d->img_fd) < 0)
                r = -errno;
        if (r == 0)
                r = ds_walk_dir(d->dir_fd, ".", remove_tmp, &top);
        if (r == 0 && (r = ds_walk_dir(d->dir_fd, "lp", remove_lp_tmp, &top)) == -ENOENT)
                r = 0;
        return r;
}

/* Makes this handle the dataset's only writer (first ds_store). */
int ds_become_writer(struct ds *d)
{
        int r;

        if (d->writer)
                return 0;
        if (flock(d->dir_fd, LOCK_EX | LOCK_NB) < 0)
                return ds_fail(d, errno == EWOULDBLOCK ? -EBUSY : -errno,
                               "being written by another process");
        r = ds_db_int64(d, "SELECT coalesce(max(id), 0) + 1 FROM captures", &d->next_id);
        if (r == 0 && (r = remove_orphans(d)) < 0)
                ds_fail(d, r, "Failed to remove what an interrupted store left: %s", strerror(-r));
        if (r == 0)
                r = ds_db_prepare_writer(d);
        if (r < 0) {
                (void)flock(d->dir_fd, LOCK_UN);
                return r;
        }
        d->writer = true;
        return 0;
}

int ds_claim(struct ds *d)
{
        DS_ASSERT_THREAD_ALLOWED();
        return ds_become_writer(d);
}

void ds_name_part(char *out, size_t outlen, const char *in, const char *empty)
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

/* Sets c->file to "images/NNNNNN_<camera>_<lamps>[_laser<k...>].png", the lamps part "dark"
 * without lamps and left out for a frame lit by lasers alone, the laser part "_laser" for
 * laser 0 alone (as before several lasers), else "_laser" and the digits of the lit lasers'
 * indices ("_laser1", "_laser01"); returns the base name. */
static const char *image_name(struct ds_capture *c)
{
        char cam[DS_NAME_MAX], lamps[128], laser[16] = "";
        uint32_t lit = c->pose.lasers;

        if (lit)
                snprintf(laser, sizeof(laser), "_laser");
        for (int i = 0; lit != 1 && i < 8; i++)
                if (lit & (UINT32_C(1) << i))
                        snprintf(laser + strlen(laser), sizeof(laser) - strlen(laser), "%d", i);
        ds_name_part(cam, sizeof(cam), c->camera, "camera");
        ds_name_part(lamps, sizeof(lamps), c->lamps, lit ? "" : "dark");
        snprintf(c->file, sizeof(c->file), "%s/%06lld_%s%s%s%s.png", DS_IMAGES, (long long)c->id,
                 cam, lamps[0] ? "_" : "", lamps, laser);
        return c->file + strlen(DS_IMAGES "/");
}

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

/* Removes the image name of a row that was not committed (durably when it was there). */
static void remove_image(struct ds *d, const char *name)
{
        if (unlinkat(d->img_fd, name, 0) == 0)
                (void)fsync(d->img_fd);
}

/* Commits row, whose image name is in place and durable; removes the image when the commit
 * fails. */
static int commit_row(struct ds *d, struct ds_capture *row, const char *name)
{
        int r;

        row->t_stored_ns = gn_realtime_ns();
        r = ds_db_insert(d, row);
        if (r < 0) {
                remove_image(d, name);
                return r;
        }
        d->next_id++;
        return 0;
}

/* Copies c into row, the next row to store: its kind defaulted and checked, the handle
 * made the writer, its plan item free (exactly once), its id reserved. */
static int begin_row(struct ds *d, const struct ds_capture *c, struct ds_capture *row)
{
        int r;

        if (!c->camera[0])
                return ds_fail(d, -EINVAL, "a capture needs a camera name");
        *row = *c;
        if (!row->kind[0])
                snprintf(row->kind, sizeof(row->kind), "image");
        if (!ds_kind_ok(row->kind))
                return ds_fail(d, -EINVAL, "unknown capture kind '%.*s'", (int)sizeof(row->kind),
                               row->kind);
        r = ds_become_writer(d);
        if (r == 0)
                r = ds_db_check_plan_item(d, row);
        if (r == 0)
                row->id = d->next_id;
        return r;
}

/* Writes the encoded image of row (named after row->id) and commits the row. */
static int store_encoded(struct ds *d, const void *png, size_t len, struct ds_capture *row)
{
        const char *name = image_name(row);
        int r;

        r = write_image(d->img_fd, name, png, len, row->sha256);
        if (r < 0)
                return ds_fail(d, r, "Failed to write %s: %s", row->file, strerror(-r));
        return commit_row(d, row, name);
}

int ds_store_png(struct ds *d, const void *png, size_t len, const struct gn_frame *shape,
                 struct ds_capture *c)
{
        struct ds_capture row;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !png || !shape || !c)
                return -EINVAL;
        d->error[0] = 0;
        r = begin_row(d, c, &row);
        if (r < 0)
                return r;
        row.size = (int64_t)len;
        row.width = shape->width;
        row.height = shape->height;
        snprintf(row.pixfmt, sizeof(row.pixfmt), "%s", gn_frame_format(shape));
        r = store_encoded(d, png, len, &row);
        if (r == 0)
                *c = row;
        return r;
}

/* ---- importing ---- */

/* Hard-links src_file (below src_dir_fd) as images/name, reads it back once into hex and
 * *size, and makes the new name durable; nothing is left on failure. */
static int link_image(struct ds *d, int src_dir_fd, const char *src_file, const char *name,
                      char hex[GN_SHA256_HEX], int64_t *size)
{
        struct stat st = {0};
        int r = 0;

        if (linkat(src_dir_fd, src_file, d->img_fd, name, 0) < 0)
                return -errno;
        if (fstatat(d->img_fd, name, &st, 0) < 0)
                r = -errno;
        if (r == 0)
                r = gn_sha256_file_at(d->img_fd, name, hex);
        if (r == 0 && fsync(d->img_fd) < 0)
                r = -errno;
        if (r < 0)
                remove_image(d, name);
        *size = st.st_size;
        return r;
}

/* Copies src_file (below src_dir_fd) to images/name with the durable write of ds_store,
 * hashing the bytes into hex as they are written; nothing is left on failure. */
static int copy_image(struct ds *d, int src_dir_fd, const char *src_file, const char *name,
                      char hex[GN_SHA256_HEX], int64_t *size)
{
        _cleanup_free_ void *buf = NULL;
        size_t len = 0;
        int r;

        r = gn_read_file_at(src_dir_fd, src_file, DS_FILE_MAX, &buf, &len);
        if (r == 0)
                r = write_image(d->img_fd, name, buf, len, hex);
        *size = (int64_t)len;
        return r;
}

/* Puts src_file (below src_dir_fd) in place as images/name: a hard link, or a copy where
 * the file systems differ or do not link. hex and *size: what was put there. */
static int place_image(struct ds *d, int src_dir_fd, const char *src_file, const char *name,
                       char hex[GN_SHA256_HEX], int64_t *size)
{
        int r = link_image(d, src_dir_fd, src_file, name, hex, size);

        if (r == -EXDEV || r == -EPERM || r == -EMLINK || r == -EOPNOTSUPP)
                r = copy_image(d, src_dir_fd, src_file, name, hex, size);
        return r;
}

int ds_import_file(struct ds *d, int src_dir_fd, const char *src_file, struct ds_capture *c)
{
        char hex[GN_SHA256_HEX];
        struct ds_capture row;
        const char *name;
        int64_t size = 0;
        int r;

        if (!ds_file_name_ok(src_file))
                return ds_fail(d, -EINVAL, "bad source file name '%s'", src_file);
        r = begin_row(d, c, &row);
        if (r < 0)
                return r;
        name = image_name(&row);
        r = place_image(d, src_dir_fd, src_file, name, hex, &size);
        if (r < 0)
                return ds_fail(d, r, "Failed to import %s as %s: %s", src_file, row.file,
                               strerror(-r));
        if (strcmp(hex, row.sha256) != 0) {
                remove_image(d, name);
                return ds_fail(d, -EBADMSG, "%s does not match the checksum of its source row",
                               src_file);
        }
        row.size = size;
        r = commit_row(d, &row, name);
        if (r == 0)
                *c = row;
        return r;
}

int ds_store(struct ds *d, const struct gn_frame *frame, struct ds_capture *c)
{
        _cleanup_free_ void *png = NULL;
        size_t len = 0;
        int r;

        DS_ASSERT_THREAD_ALLOWED();

        if (!d || !frame || !c)
                return -EINVAL;
        r = ds_png_encode(frame, d->png_level, &png, &len);
        if (r < 0)
                return ds_fail(d, r, "Failed to encode %dx%d %s frame: %s", frame->width,
                               frame->height, gn_frame_format(frame), strerror(-r));
        return ds_store_png(d, png, len, frame, c);
}
