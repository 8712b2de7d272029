/* test-ds.c - the dataset store against a real directory, SQLite index and PNG files:
 * create/open, bit-exact round trips, checksums and verify, WAL, reopen, the temp-name
 * protocol, crash leftovers, the single-writer lock and write failures (RLIMIT_FSIZE).
 *
 * Usage: test-ds CASE (one meson test per case). */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <openssl/sha.h>
#include <signal.h>
#include <sqlite3.h>
#include <stdint.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/sha256.h"
#include "dataset/ds.h"
#include "ds-util.h"
#include "tests/test.h"

static const char rig_text[] = "# test rig\nrig: test-rig\nbuses: []\n";

struct fixture {
        char *tmp;
        char path[4096];
        struct ds *d;
};

static void setup(struct fixture *fx)
{
        fx->tmp = tu_tmpdir();
        snprintf(fx->path, sizeof(fx->path), "%s/ds", fx->tmp);
        CHECK_INT(ds_create(fx->path, "test-set", rig_text, &fx->d), 0);
}

static void teardown(struct fixture *fx)
{
        fx->d = ds_close(fx->d);
        tu_rm_rf(fx->tmp);
        free(fx->tmp);
}

/* Stores a noisy frame of the given shape; returns ds_store's result. */
static int store(struct ds *d, int w, int h, int ch, int bits, const char *cam, const char *lamps,
                 int i, struct ds_capture *c)
{
        struct gn_frame f;
        int r;

        tu_frame(&f, w, h, ch, bits, (unsigned)i, false);
        tu_capture(c, cam, lamps, i);
        r = ds_store(d, &f, c);
        gn_frame_free_data(&f);
        return r;
}

static void path_of(const struct fixture *fx, const char *rel, char *out, size_t len)
{
        snprintf(out, len, "%s/%s", fx->path, rel);
}

static json_t *load_json(const struct fixture *fx)
{
        char p[4200];
        json_t *j;

        path_of(fx, "dataset.json", p, sizeof(p));
        j = json_load_file(p, 0, NULL);
        CHECK(j);
        return j;
}

static void check_json_names(json_t *arr, const char *const *names, size_t n)
{
        CHECK_INT(json_array_size(arr), n);
        for (size_t i = 0; i < n; i++)
                CHECK(strcmp(json_string_value(json_array_get(arr, i)), names[i]) == 0);
}

static void test_create(void)
{
        static const char *const cams[] = {"cam0", "cam1"}, *const lamps[] = {"l1", "l2"};
        struct fixture fx = {};
        struct ds *other = NULL;
        struct ds_capture c;
        char p[4200];
        json_t *j;

        setup(&fx);
        CHECK(strcmp(ds_name(fx.d), "test-set") == 0);
        CHECK(ds_path(fx.d)[0] == '/');
        CHECK_INT(ds_create(fx.path, "again", rig_text, &other), -EEXIST);
        path_of(&fx, "nope", p, sizeof(p));
        CHECK_INT(ds_open(p, &other), -ENOENT);
        CHECK_INT(ds_open(fx.tmp, &other), -EBADMSG); /* a directory, not a dataset */
        path_of(&fx, "rig.yaml", p, sizeof(p));
        FILE *fp = fopen(p, "r");
        char text[256] = "";
        CHECK(fp && fread(text, 1, sizeof(text) - 1, fp) == strlen(rig_text) && fclose(fp) == 0);
        CHECK(strcmp(text, rig_text) == 0);

        j = load_json(&fx);
        CHECK(strcmp(json_string_value(json_object_get(j, "name")), "test-set") == 0);
        CHECK(strcmp(json_string_value(json_object_get(j, "rig")), "test-rig") == 0);
        CHECK(strcmp(json_string_value(json_object_get(j, "format")), "png") == 0);
        CHECK_INT(json_integer_value(json_object_get(j, "captures")), 0);
        const char *created = json_string_value(json_object_get(j, "created"));
        CHECK(created && strlen(created) == 20 && created[10] == 'T' && created[19] == 'Z');
        json_decref(j);

        CHECK_INT(store(fx.d, 16, 8, 1, 8, "cam1", "l2,l1", 0, &c), 0);
        CHECK_INT(store(fx.d, 16, 8, 1, 8, "cam0", "l1", 1, &c), 0);
        CHECK_INT(store(fx.d, 16, 8, 1, 8, "cam0", "", 2, &c), 0);
        fx.d = ds_close(fx.d);
        j = load_json(&fx);
        CHECK_INT(json_integer_value(json_object_get(j, "captures")), 3);
        check_json_names(json_object_get(j, "cameras"), cams, 2);
        check_json_names(json_object_get(j, "lamps"), lamps, 2);
        json_decref(j);
        teardown(&fx);
}

static void check_roundtrip(struct ds *d, int ch, int bits, bool pad, int i)
{
        struct gn_frame f, back = {};
        struct ds_capture c, want;

        tu_frame(&f, 37, 23, ch, bits, (unsigned)i, pad);
        tu_capture(&c, "cam0", "l1,l3", i);
        want = c;
        CHECK_INT(ds_store(d, &f, &c), 0);
        CHECK_INT(c.id, i + 1);
        CHECK_INT(c.width, 37);
        CHECK_INT(c.height, 23);
        CHECK(strcmp(c.pixfmt, gn_frame_format(&f)) == 0);
        CHECK_INT(strlen(c.sha256), 64);
        CHECK(c.t_stored_ns >= want.t_exposure_ns);
        char name[64];
        snprintf(name, sizeof(name), "images/%06d_cam0_l1+l3%s.png", i + 1,
                 c.pose.lasers ? "_laser" : "");
        CHECK(strcmp(c.file, name) == 0);
        CHECK_INT(ds_load_image(d, c.file, &back), 0);
        CHECK(tu_frames_equal(&f, &back));
        gn_frame_free_data(&f);
        gn_frame_free_data(&back);
}

/* 16-bit samples must be big-endian in the file: a stored (level 0) 1x1 PNG shows them. */
static void check_big_endian(struct fixture *fx)
{
        struct gn_frame f;
        struct ds_capture c;
        char p[4400];
        FILE *fp;
        uint8_t buf[512];
        size_t n;

        CHECK_INT(gn_frame_alloc(&f, 1, 1, 1, 16), 0);
        ((uint16_t *)f.data)[0] = 0xA1B2;
        tu_capture(&c, "cam9", "", 8); /* even: laser off, a dark frame */
        CHECK_INT(ds_set_compression(fx->d, 0), 0);
        CHECK_INT(ds_set_compression(fx->d, 10), -EINVAL);
        CHECK_INT(ds_store(fx->d, &f, &c), 0);
        CHECK(strstr(c.file, "_cam9_dark.png"));
        path_of(fx, c.file, p, sizeof(p));
        fp = fopen(p, "rb");
        CHECK(fp);
        n = fread(buf, 1, sizeof(buf), fp);
        fclose(fp);
        CHECK(n > 8 && memcmp(buf, "\x89PNG\r\n\x1a\n", 8) == 0);
        CHECK(memmem(buf, n, "\xA1\xB2", 2) != NULL);
        CHECK(memmem(buf, n, "\xB2\xA1", 2) == NULL);
        gn_frame_free_data(&f);
}

static void test_roundtrip(void)
{
        struct fixture fx = {};
        int i = 0;

        setup(&fx);
        for (int ch = 1; ch <= 3; ch += 2)
                for (int bits = 8; bits <= 16; bits += 8)
                        for (int pad = 0; pad <= 1; pad++)
                                check_roundtrip(fx.d, ch, bits, pad, i++);
        check_big_endian(&fx);
        CHECK_INT(ds_count(fx.d), i + 1);
        teardown(&fx);
}

struct rows {
        struct ds_capture c[16];
        int n;
};

static int collect(const struct ds_capture *c, void *ud)
{
        struct rows *rows = ud;

        CHECK(rows->n < 16);
        rows->c[rows->n++] = *c;
        return 0;
}

static void test_verify(void)
{
        struct fixture fx = {};
        struct ds_capture c[5];
        struct gn_frame back = {};
        struct rows rows = {};
        char p[4400], hex[65];
        FILE *fp;

        setup(&fx);
        for (int i = 0; i < 5; i++)
                CHECK_INT(store(fx.d, 64, 48, 3, 8, "cam0", "l1", i, &c[i]), 0);
        CHECK_INT(ds_verify(fx.d), 0);
        CHECK(ds_rows(fx.d, 0, -1, collect, &rows) >= 0);
        CHECK_INT(rows.n, 5);
        for (int i = 0; i < 5; i++) {
                path_of(&fx, rows.c[i].file, p, sizeof(p));
                CHECK_INT(gn_sha256_file_at(AT_FDCWD, p, hex), 0);
                CHECK(strcmp(hex, rows.c[i].sha256) == 0);
        }
        path_of(&fx, "abc.txt", p, sizeof(p));
        fp = fopen(p, "w");
        CHECK(fp && fputs("abc", fp) >= 0 && fclose(fp) == 0);
        CHECK_INT(gn_sha256_file_at(AT_FDCWD, p, hex), 0);
        CHECK(strcmp(hex, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad") == 0);

        /* flip one byte in the middle of an image: detected by verify and by the decoder */
        path_of(&fx, c[1].file, p, sizeof(p));
        fp = fopen(p, "r+b");
        CHECK(fp && fseek(fp, 200, SEEK_SET) == 0);
        int ch = fgetc(fp);
        CHECK(fseek(fp, 200, SEEK_SET) == 0 && fputc(ch ^ 0x40, fp) != EOF && fclose(fp) == 0);
        CHECK_INT(ds_verify(fx.d), 1);
        CHECK(ds_load_image(fx.d, c[1].file, &back) < 0);
        path_of(&fx, c[3].file, p, sizeof(p));
        CHECK(unlink(p) == 0);
        CHECK_INT(ds_verify(fx.d), 2);
        CHECK_INT(ds_load_image(fx.d, c[3].file, &back), -ENOENT);
        CHECK_INT(ds_load_image(fx.d, "../escape.png", &back), -EINVAL);
        teardown(&fx);
}

static void test_wal(void)
{
        static const char *const keys[] = {"schema_version", "name", "created", "rig"};
        struct fixture fx = {};
        struct ds_capture c;
        sqlite3 *db;
        sqlite3_stmt *s;
        char p[4200];

        setup(&fx);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "l1", 0, &c), 0);
        path_of(&fx, "index.sqlite", p, sizeof(p));
        CHECK_INT(sqlite3_open_v2(p, &db, SQLITE_OPEN_READONLY, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_prepare_v2(db, "PRAGMA journal_mode", -1, &s, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_step(s), SQLITE_ROW);
        CHECK(strcmp((const char *)sqlite3_column_text(s, 0), "wal") == 0);
        sqlite3_finalize(s);
        CHECK_INT(sqlite3_prepare_v2(db,
                                     "SELECT id, session, turntable_deg, light_arm_deg, "
                                     "camera_arm_deg, camera, lamps, laser, exposure_us, gain, "
                                     "t_request_ns, t_exposure_ns, t_stored_ns, file, sha256, "
                                     "width, height, pixfmt FROM captures",
                                     -1, &s, NULL),
                  SQLITE_OK);
        CHECK_INT(sqlite3_step(s), SQLITE_ROW); /* the open writer's commit is visible */
        CHECK(strcmp((const char *)sqlite3_column_text(s, 13), c.file) == 0);
        sqlite3_finalize(s);
        for (size_t i = 0; i < 4; i++) {
                CHECK_INT(sqlite3_prepare_v2(db, "SELECT value FROM meta WHERE key = ?", -1, &s,
                                             NULL),
                          SQLITE_OK);
                sqlite3_bind_text(s, 1, keys[i], -1, SQLITE_STATIC);
                CHECK_INT(sqlite3_step(s), SQLITE_ROW);
                sqlite3_finalize(s);
        }
        sqlite3_close(db);
        teardown(&fx);
}

static void check_rows_equal(const struct ds_capture *a, const struct ds_capture *b)
{
        CHECK_INT(a->id, b->id);
        CHECK(strcmp(a->session, b->session) == 0 && strcmp(a->camera, b->camera) == 0);
        CHECK(strcmp(a->lamps, b->lamps) == 0 && strcmp(a->file, b->file) == 0);
        CHECK(strcmp(a->sha256, b->sha256) == 0 && strcmp(a->pixfmt, b->pixfmt) == 0);
        CHECK(gn_pose_equal(&a->pose, &b->pose, 0) && a->gain == b->gain);
        for (int k = 0; k < GN_ROLE_COUNT; k++)
                CHECK(isnan(a->pose.deg[k]) ? isnan(b->pose.deg[k])
                                            : a->pose.deg[k] == b->pose.deg[k]);
        CHECK_INT(a->exposure_us, b->exposure_us);
        CHECK(a->t_request_ns == b->t_request_ns && a->t_exposure_ns == b->t_exposure_ns);
        CHECK(a->t_stored_ns == b->t_stored_ns);
        CHECK_INT(a->width, b->width);
        CHECK_INT(a->height, b->height);
}

static void test_reopen(void)
{
        struct fixture fx = {};
        struct ds_capture c[5];
        struct rows rows = {};
        json_t *j;

        setup(&fx);
        for (int i = 0; i < 3; i++)
                CHECK_INT(store(fx.d, 20, 10, 1, 16, i ? "cam1" : "cam0", "l2", i, &c[i]), 0);
        fx.d = ds_close(fx.d);
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK(strcmp(ds_name(fx.d), "test-set") == 0);
        CHECK_INT(ds_count(fx.d), 3);
        for (int i = 3; i < 5; i++)
                CHECK_INT(store(fx.d, 20, 10, 3, 8, "cam0", "l1,l2", i, &c[i]), 0);
        CHECK_INT(c[3].id, 4);
        CHECK_INT(c[4].id, 5);
        fx.d = ds_close(fx.d);
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK(ds_rows(fx.d, 0, -1, collect, &rows) >= 0);
        CHECK_INT(rows.n, 5);
        for (int i = 0; i < 5; i++)
                check_rows_equal(&rows.c[i], &c[i]);
        CHECK_INT(ds_verify(fx.d), 0);
        j = load_json(&fx);
        CHECK_INT(json_integer_value(json_object_get(j, "captures")), 5);
        json_decref(j);
        teardown(&fx);
}

/* Replaces the file rel of the dataset with text. */
static void touch_text(const struct fixture *fx, const char *rel, const char *text)
{
        char p[4200];
        FILE *fp;

        path_of(fx, rel, p, sizeof(p));
        fp = fopen(p, "w");
        CHECK(fp && fputs(text, fp) >= 0 && fclose(fp) == 0);
}

/* Runs sql on the dataset's index with a second connection. */
static void raw_sql(const struct fixture *fx, const char *sql)
{
        char p[4200];
        sqlite3 *db;

        path_of(fx, "index.sqlite", p, sizeof(p));
        CHECK_INT(sqlite3_open_v2(p, &db, SQLITE_OPEN_READWRITE, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_exec(db, sql, NULL, NULL, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_close(db), SQLITE_OK);
}

/* Runs a query of one integer on the dataset's index with a second connection. */
static int64_t raw_int(const struct fixture *fx, const char *sql)
{
        char p[4200];
        sqlite3 *db;
        sqlite3_stmt *s;
        int64_t v;

        path_of(fx, "index.sqlite", p, sizeof(p));
        CHECK_INT(sqlite3_open_v2(p, &db, SQLITE_OPEN_READONLY, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_prepare_v2(db, sql, -1, &s, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_step(s), SQLITE_ROW);
        v = sqlite3_column_int64(s, 0);
        sqlite3_finalize(s);
        CHECK_INT(sqlite3_close(db), SQLITE_OK);
        return v;
}

/* Bug 3: a rig with a turntable only stores NULL angles and reads them back as NAN. */
static void test_nullpose(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        struct rows rows = {};

        setup(&fx);
        tu_capture(&c, "cam0", "l1", 3);
        c.pose = gn_pose_none();
        c.pose.deg[GN_ROLE_TURNTABLE] = 33.5;
        c.pose.lamps = 0x5;
        struct gn_frame f;
        tu_frame(&f, 8, 8, 1, 8, 1, false);
        CHECK_INT(ds_store(fx.d, &f, &c), 0);
        gn_frame_free_data(&f);
        fx.d = ds_close(fx.d);
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK(ds_rows(fx.d, 0, -1, collect, &rows) >= 0);
        CHECK_INT(rows.n, 1);
        check_rows_equal(&rows.c[0], &c);
        CHECK(rows.c[0].pose.deg[GN_ROLE_TURNTABLE] == 33.5);
        CHECK(isnan(rows.c[0].pose.deg[GN_ROLE_LIGHT_ARM]));
        CHECK(isnan(rows.c[0].pose.deg[GN_ROLE_CAMERA_ARM]));
        CHECK_INT(rows.c[0].pose.lamps, 0x5);
        /* NULL in the index, not NaN or 0 */
        CHECK_INT(raw_int(&fx, "SELECT count(*) FROM captures WHERE camera_arm_deg IS NULL "
                               "AND light_arm_deg IS NULL AND turntable_deg = 33.5 "
                               "AND lamp_bits = 5"),
                  1);
        teardown(&fx);
}

/* The index refusing a row is -EINVAL with SQLite's message, not a stale errno, and
 * nothing is left behind. */
static void test_refused(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        char images[4200];

        setup(&fx);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "l1", 0, &c), 0);
        raw_sql(&fx, "CREATE TRIGGER no_more BEFORE INSERT ON captures "
                     "BEGIN SELECT RAISE(ABORT, 'rows refused by test'); END");
        errno = EEXIST; /* a stale errno must not leak into the result */
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "l1", 1, &c), -EINVAL);
        CHECK_STR_CONTAINS(ds_last_error(fx.d), "rows refused by test");
        path_of(&fx, "images", images, sizeof(images));
        CHECK_INT(tu_count(images, ""), 1);
        CHECK_INT(tu_count_tmp(fx.path), 0);
        CHECK_INT(ds_count(fx.d), 1);
        teardown(&fx);
}

/* A schema-1 index (angles NOT NULL, no lamp_bits, user_version 0) opens, is migrated
 * and then takes rows without a camera arm. */
static void test_migrate(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        struct rows rows = {};

        setup(&fx);
        fx.d = ds_close(fx.d);
        touch_text(&fx, "rig.yaml", "rig: old\nlamps:\n  - { name: l0 }\n  - { name: l1 }\n");
        tu_make_schema1(fx.path,
                        "INSERT INTO captures VALUES (1, 's', 10, 20, 30, 'cam0', 'l1', 1, 1000,"
                        " 1.5, 5, 6, 7, 'images/000001_cam0_l1.png', 'ab', 4, 4, 'mono8');");
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK(ds_rows(fx.d, 0, -1, collect, &rows) >= 0);
        CHECK_INT(rows.n, 1);
        CHECK(rows.c[0].pose.deg[GN_ROLE_TURNTABLE] == 10);
        CHECK(rows.c[0].pose.deg[GN_ROLE_CAMERA_ARM] == 30);
        CHECK(rows.c[0].pose.lasers);
        CHECK_STR(rows.c[0].lamps, "l1");
        CHECK_INT(rows.c[0].pose.lamps, 0x2); /* l1 is the second lamp of rig.yaml */
        struct ds_summary sum;
        CHECK_INT(ds_summary(fx.d, &sum), 0); /* names counted from the old rows */
        CHECK_INT(sum.captures, 1);
        CHECK_INT(sum.n_cameras, 1);
        CHECK_INT(sum.n_lamps, 1);
        CHECK_STR(sum.lamps[0].name, "l1");
        fx.d = ds_close(fx.d);
        raw_sql(&fx, "DELETE FROM captures; DELETE FROM names"); /* its image does not exist */
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        tu_capture(&c, "cam0", "", 1);
        c.pose.deg[GN_ROLE_CAMERA_ARM] = NAN;
        struct gn_frame f;
        tu_frame(&f, 8, 8, 1, 8, 1, false);
        CHECK_INT(ds_store(fx.d, &f, &c), 0);
        gn_frame_free_data(&f);
        /* a schema from the future is refused */
        fx.d = ds_close(fx.d);
        raw_sql(&fx, "PRAGMA user_version = 5");
        CHECK_INT(ds_open(fx.path, &fx.d), -EBADMSG);
        teardown(&fx);
}

/* The summary comes from the index: names with their counts, rows, last id. */
static void test_summary(void)
{
        struct fixture fx = {};
        struct ds_summary sum;
        struct ds_capture c;

        setup(&fx);
        CHECK_INT(ds_summary(fx.d, &sum), 0);
        CHECK_STR(sum.name, "test-set");
        CHECK_STR(sum.rig, "test-rig");
        CHECK_INT(sum.captures, 0);
        CHECK_INT(sum.last_id, 0);
        CHECK_INT(sum.n_cameras, 0);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam1", "l2,l1", 0, &c), 0);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "l1", 1, &c), 0);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "", 2, &c), 0);
        fx.d = ds_close(fx.d);
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK_INT(ds_summary(fx.d, &sum), 0);
        CHECK_INT(sum.captures, 3);
        CHECK_INT(ds_count(fx.d), 3);
        CHECK_INT(sum.last_id, 3);
        CHECK_INT(sum.n_cameras, 2);
        CHECK_STR(sum.cameras[0].name, "cam0");
        CHECK_INT(sum.cameras[0].captures, 2);
        CHECK_STR(sum.cameras[1].name, "cam1");
        CHECK_INT(sum.n_lamps, 2);
        CHECK_STR(sum.lamps[0].name, "l1");
        CHECK_INT(sum.lamps[0].captures, 2);
        CHECK_STR(sum.lamps[1].name, "l2");
        CHECK_INT(sum.lamps[1].captures, 1);
        CHECK(strlen(sum.created) == 20);
        /* dataset.json is not read: removing it changes nothing */
        char p[4200];
        path_of(&fx, "dataset.json", p, sizeof(p));
        CHECK(unlink(p) == 0);
        CHECK_INT(ds_summary(fx.d, &sum), 0);
        CHECK_INT(sum.captures, 3);
        teardown(&fx);
}

/* Rows by range: after_id and LIMIT. */
static void test_rows(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        struct rows rows = {};

        setup(&fx);
        for (int i = 0; i < 10; i++)
                CHECK_INT(store(fx.d, 4, 4, 1, 8, "cam0", "l1", i, &c), 0);
        CHECK_INT(ds_rows(fx.d, 3, 4, collect, &rows), 4);
        CHECK_INT(rows.n, 4);
        for (int i = 0; i < 4; i++)
                CHECK_INT(rows.c[i].id, 4 + i);
        rows.n = 0;
        CHECK_INT(ds_rows(fx.d, 8, 5, collect, &rows), 2);
        CHECK_INT(rows.c[1].id, 10);
        rows.n = 0;
        CHECK_INT(ds_rows(fx.d, 10, 5, collect, &rows), 0);
        CHECK_INT(ds_rows(fx.d, 0, -1, collect, &rows), 10);
        CHECK_INT(ds_rows(fx.d, 0, 0, collect, &rows), 0);
        teardown(&fx);
}

static int stop_at_two(const struct ds_capture *c, void *ud)
{
        return c->id == 2 ? -ECANCELED : 0;
}

/* Rows by pose: roles the query has are compared modulo 360, roles it lacks match
 * anything, a row without the axis never matches an angle. */
static void test_bypose(void)
{
        static const double tt[] = {0.0, 359.9, 90.0, 90.05, 180.0, 720.0};
        struct fixture fx = {};
        struct ds_capture c;
        struct rows rows = {};
        struct gn_pose q = gn_pose_none();
        struct gn_frame f;

        setup(&fx);
        tu_frame(&f, 4, 4, 1, 8, 1, false);
        for (int i = 0; i < 6; i++) {
                tu_capture(&c, "cam0", "l1", i);
                c.pose.deg[GN_ROLE_TURNTABLE] = tt[i];
                c.pose.deg[GN_ROLE_CAMERA_ARM] = i == 5 ? NAN : 30.0;
                CHECK_INT(ds_store(fx.d, &f, &c), 0);
        }
        gn_frame_free_data(&f);
        q.deg[GN_ROLE_TURNTABLE] = 0.0;
        CHECK_INT(ds_rows_by_pose(fx.d, &q, 0.2, collect, &rows), 3); /* 0, 359.9, 720 */
        CHECK_INT(rows.c[0].id, 1);
        CHECK_INT(rows.c[1].id, 2);
        CHECK_INT(rows.c[2].id, 6);
        rows.n = 0;
        q.deg[GN_ROLE_CAMERA_ARM] = 30.0; /* row 6 has no camera arm */
        CHECK_INT(ds_rows_by_pose(fx.d, &q, 0.2, collect, &rows), 2);
        rows.n = 0;
        q.deg[GN_ROLE_TURNTABLE] = 450.0; /* = 90 */
        CHECK_INT(ds_rows_by_pose(fx.d, &q, 0.1, collect, &rows), 2);
        CHECK_INT(rows.c[0].id, 3);
        CHECK_INT(rows.c[1].id, 4);
        rows.n = 0;
        CHECK_INT(ds_rows_by_pose(fx.d, &q, 0.01, collect, &rows), 1);
        q = gn_pose_none(); /* no role: every row */
        rows.n = 0;
        CHECK_INT(ds_rows_by_pose(fx.d, &q, 0, collect, &rows), 6);
        CHECK_INT(ds_rows_by_pose(fx.d, &q, 0, stop_at_two, NULL), -ECANCELED);
        CHECK_INT(ds_rows_by_pose(fx.d, &q, -1, collect, &rows), -EINVAL);
        teardown(&fx);
}

/* SHA-256 of a whole file, computed apart from the store (one OpenSSL call over the
 * file read back in one piece). */
static void independent_sha256(const char *path, char hex[65])
{
        unsigned char md[SHA256_DIGEST_LENGTH];
        FILE *fp = fopen(path, "rb");
        uint8_t *buf;
        long n;

        CHECK(fp && fseek(fp, 0, SEEK_END) == 0 && (n = ftell(fp)) > 0 &&
              fseek(fp, 0, SEEK_SET) == 0);
        buf = malloc((size_t)n);
        CHECK(buf && fread(buf, 1, (size_t)n, fp) == (size_t)n && fclose(fp) == 0);
        CHECK(n > 4 << 20); /* several 1 MiB write chunks */
        SHA256(buf, (size_t)n, md);
        for (int i = 0; i < SHA256_DIGEST_LENGTH; i++)
                snprintf(hex + 2 * i, 3, "%02x", md[i]);
        free(buf);
}

/* Camera-sized frames (2448x2048 RGB noise, 8 and 16 bits, ~15 and ~30 MB of PNG):
 * the checksum matches an independent hash of the file and the pixels round-trip. */
static void test_camera(void)
{
        struct fixture fx = {};
        struct gn_frame f, back = {};
        struct ds_capture c;
        char p[4400], hex[65];

        setup(&fx);
        for (int bits = 8; bits <= 16; bits += 8) {
                tu_frame(&f, 2448, 2048, 3, bits, (unsigned)bits, false);
                tu_capture(&c, "cam0", "l1", bits);
                CHECK_INT(ds_store(fx.d, &f, &c), 0);
                path_of(&fx, c.file, p, sizeof(p));
                independent_sha256(p, hex);
                CHECK_STR(c.sha256, hex);
                CHECK_INT(ds_load_image(fx.d, c.file, &back), 0);
                CHECK(tu_frames_equal(&f, &back));
                gn_frame_free_data(&f);
                gn_frame_free_data(&back);
        }
        CHECK_INT(ds_verify(fx.d), 0);
        teardown(&fx);
}

/* A thread marked with ds_forbid_thread (goniod's loop) aborts on dataset I/O in builds
 * with assertions; unmarked again, it may. */
static void test_forbid(void)
{
#ifdef NDEBUG
        exit(TEST_SKIP);
#else
        struct fixture fx = {};
        int status;
        pid_t pid;

        setup(&fx);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                ds_forbid_thread(true);
                (void)ds_count(fx.d);
                _exit(0);
        }
        CHECK(waitpid(pid, &status, 0) == pid);
        CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGABRT);
        ds_forbid_thread(true);
        ds_forbid_thread(false);
        CHECK_INT(ds_count(fx.d), 0);
        teardown(&fx);
#endif
}

static void touch(const struct fixture *fx, const char *rel)
{
        touch_text(fx, rel, "torn");
}

static void test_tmpfiles(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        char images[4200];

        setup(&fx);
        path_of(&fx, "images", images, sizeof(images));
        for (int i = 0; i < 4; i++)
                CHECK_INT(store(fx.d, 32, 16, 3, 16, "cam0", "l1", i, &c), 0);
        CHECK_INT(tu_count_tmp(fx.path), 0);
        CHECK_INT(tu_count(images, ""), 4);
        CHECK_INT(tu_count(images, ".png"), 4);
        fx.d = ds_close(fx.d);
        CHECK_INT(tu_count_tmp(fx.path), 0);

        /* what a crash leaves: a temp file, and a renamed image whose row never committed */
        touch(&fx, "images/000005_cam0_l1.png.tmp");
        touch(&fx, "images/000005_cam0_l1.png");
        touch(&fx, "images/000006_cam1_dark.png");
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK_INT(tu_count(images, ""), 7); /* readers leave them alone */
        CHECK_INT(store(fx.d, 32, 16, 1, 8, "cam2", "", 5, &c), 0);
        CHECK_INT(c.id, 5);
        CHECK(strcmp(c.file, "images/000005_cam2_laser.png") == 0); /* laser alone */
        CHECK_INT(tu_count(images, ""), 5);
        CHECK_INT(tu_count_tmp(fx.path), 0);
        CHECK_INT(ds_verify(fx.d), 0);
        teardown(&fx);
}

static void test_lock(void)
{
        struct fixture fx = {};
        struct ds *reader = NULL;
        struct ds_capture c;

        setup(&fx);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "l1", 0, &c), 0);
        CHECK_INT(ds_open(fx.path, &reader), 0);
        CHECK_INT(ds_count(reader), 1);
        CHECK_INT(store(reader, 8, 8, 1, 8, "cam0", "l1", 1, &c), -EBUSY);
        CHECK_INT(store(fx.d, 8, 8, 1, 8, "cam0", "l1", 2, &c), 0);
        CHECK_INT(ds_count(reader), 2);
        fx.d = ds_close(fx.d);
        CHECK_INT(store(reader, 8, 8, 1, 8, "cam0", "l1", 3, &c), 0);
        CHECK_INT(c.id, 3);
        fx.d = reader;
        teardown(&fx);
}

static void set_fsize(rlim_t soft)
{
        struct rlimit rl;

        CHECK(getrlimit(RLIMIT_FSIZE, &rl) == 0);
        rl.rlim_cur = soft;
        CHECK(setrlimit(RLIMIT_FSIZE, &rl) == 0);
}

/* After a failed store: the error, no row, no temp file, no image without a row. */
static void check_nothing_recorded(struct fixture *fx, int64_t rows)
{
        char images[4200];

        path_of(fx, "images", images, sizeof(images));
        CHECK_INT(ds_count(fx->d), rows);
        CHECK_INT(tu_count_tmp(fx->path), 0);
        CHECK_INT(tu_count(images, ""), rows);
        CHECK_INT(ds_verify(fx->d), 0);
}

static void test_fsize(void)
{
        struct fixture fx = {};
        struct ds_capture c;
        struct rlimit saved;

        CHECK(signal(SIGXFSZ, SIG_IGN) != SIG_ERR);
        CHECK(getrlimit(RLIMIT_FSIZE, &saved) == 0);
        setup(&fx);
        for (int i = 0; i < 2; i++)
                CHECK_INT(store(fx.d, 64, 64, 1, 8, "cam0", "l1", i, &c), 0);

        /* the image write fails: a 128x128 rgb16 noise PNG is ~98 KiB > 16 KiB */
        set_fsize(16 << 10);
        CHECK_INT(store(fx.d, 128, 128, 3, 16, "cam0", "l1", 2, &c), -EFBIG);
        set_fsize(saved.rlim_cur);
        check_nothing_recorded(&fx, 2);

        /* the image fits but the index's WAL (already > 16 KiB) cannot grow: the commit
         * fails and the image it would have named is removed */
        set_fsize(16 << 10);
        CHECK_INT(store(fx.d, 4, 4, 1, 8, "cam0", "l1", 3, &c), -EFBIG);
        set_fsize(saved.rlim_cur);
        check_nothing_recorded(&fx, 2);

        /* space is back: the next store works and takes the next id */
        CHECK_INT(store(fx.d, 128, 128, 3, 16, "cam0", "l1", 4, &c), 0);
        CHECK_INT(c.id, 3);
        check_nothing_recorded(&fx, 3);
        teardown(&fx);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"create", test_create},     {"roundtrip", test_roundtrip},
                {"verify", test_verify},     {"wal", test_wal},
                {"reopen", test_reopen},     {"tmpfiles", test_tmpfiles},
                {"lock", test_lock},         {"fsize", test_fsize},
                {"nullpose", test_nullpose}, {"refused", test_refused},
                {"migrate", test_migrate},   {"summary", test_summary},
                {"rows", test_rows},         {"bypose", test_bypose},
                {"camera", test_camera},     {"forbid", test_forbid},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
