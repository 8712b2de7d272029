/* ds-util.c - helpers shared by the dataset store tests (see ds-util.h). */
#include <dirent.h>
#include <ftw.h>
#include <sqlite3.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ds-util.h"
#include "tests/test.h"

char *tu_tmpdir(void)
{
        const char *base = getenv("TMPDIR");
        char *p = NULL;

        CHECK(asprintf(&p, "%s/gonio-ds-XXXXXX", base && *base ? base : "/tmp") > 0);
        CHECK(mkdtemp(p) != NULL);
        return p;
}

static int rm_one(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
        return remove(path) < 0 ? -1 : 0;
}

void tu_rm_rf(const char *path)
{
        (void)nftw(path, rm_one, 16, FTW_DEPTH | FTW_PHYS);
}

void tu_frame(struct gn_frame *f, int w, int h, int channels, int bits, unsigned seed, bool pad)
{
        uint32_t s = seed * 2654435761u + 1;

        CHECK(gn_frame_alloc(f, w, h, channels, bits) == 0);
        if (pad) {
                free(f->data);
                f->stride += 8; /* padded rows, still aligned for 16-bit samples */
                f->data = calloc(f->stride, (size_t)h);
                CHECK(f->data);
        }
        for (int y = 0; y < h; y++)
                for (int x = 0; x < w * channels; x++) {
                        s = s * 1103515245u + 12345u;
                        if (bits == 16)
                                ((uint16_t *)(f->data + (size_t)y * f->stride))[x] =
                                        (uint16_t)(s >> 8);
                        else
                                f->data[(size_t)y * f->stride + x] = (uint8_t)(s >> 16);
                }
}

bool tu_frames_equal(const struct gn_frame *a, const struct gn_frame *b)
{
        size_t row = (size_t)a->width * a->channels * (a->bits / 8);

        if (a->width != b->width || a->height != b->height || a->channels != b->channels ||
            a->bits != b->bits)
                return false;
        for (int y = 0; y < a->height; y++)
                if (memcmp(a->data + (size_t)y * a->stride, b->data + (size_t)y * b->stride, row) !=
                    0)
                        return false;
        return true;
}

void tu_capture(struct ds_capture *c, const char *camera, const char *lamps, int i)
{
        memset(c, 0, sizeof(*c));
        snprintf(c->session, sizeof(c->session), "sess-%d", i / 10);
        c->pose.deg[GN_ROLE_TURNTABLE] = 12.5 * i;
        c->pose.deg[GN_ROLE_LIGHT_ARM] = -30.25 + i;
        c->pose.deg[GN_ROLE_CAMERA_ARM] = 45.0 / (i + 1);
        c->pose.lamps = *lamps ? 1u << (i % 3) : 0;
        c->pose.lasers = i % 2;
        snprintf(c->camera, sizeof(c->camera), "%s", camera);
        snprintf(c->lamps, sizeof(c->lamps), "%s", lamps);
        c->exposure_us = 1000 + i;
        c->gain = 1.5 + i * 0.125;
        c->t_request_ns = 1700000000000000000ull + (uint64_t)i * 1000;
        c->t_exposure_ns = c->t_request_ns + 500;
}

int tu_count(const char *dir, const char *suffix)
{
        DIR *d = opendir(dir);
        struct dirent *de;
        int n = 0;

        CHECK(d);
        while ((de = readdir(d))) {
                size_t len = strlen(de->d_name), sl = strlen(suffix);

                if (strcmp(de->d_name, ".") == 0 || strcmp(de->d_name, "..") == 0)
                        continue;
                n += len >= sl && strcmp(de->d_name + len - sl, suffix) == 0;
        }
        closedir(d);
        return n;
}

int tu_count_tmp(const char *dataset)
{
        char images[4096];

        snprintf(images, sizeof(images), "%s/images", dataset);
        return tu_count(dataset, ".tmp") + tu_count(images, ".tmp");
}

void tu_make_schema1(const char *path, const char *extra_sql)
{
        char index[4200];
        sqlite3 *db;

        snprintf(index, sizeof(index), "%s/index.sqlite", path);
        CHECK(sqlite3_open_v2(index, &db, SQLITE_OPEN_READWRITE, NULL) == SQLITE_OK);
        CHECK(sqlite3_exec(db,
                           "DROP TABLE captures; DROP TABLE names; DROP TABLE sessions;"
                           "DROP TABLE plan;"
                           "CREATE TABLE captures (id INTEGER PRIMARY KEY,"
                           " session TEXT NOT NULL DEFAULT '',"
                           " turntable_deg REAL NOT NULL, light_arm_deg REAL NOT NULL,"
                           " camera_arm_deg REAL NOT NULL, camera TEXT NOT NULL,"
                           " lamps TEXT NOT NULL, laser INTEGER NOT NULL,"
                           " exposure_us INTEGER NOT NULL, gain REAL NOT NULL,"
                           " t_request_ns INTEGER NOT NULL, t_exposure_ns INTEGER NOT NULL,"
                           " t_stored_ns INTEGER NOT NULL, file TEXT NOT NULL UNIQUE,"
                           " sha256 TEXT NOT NULL, width INTEGER NOT NULL,"
                           " height INTEGER NOT NULL, pixfmt TEXT NOT NULL);"
                           "UPDATE meta SET value = '1' WHERE key = 'schema_version';"
                           "PRAGMA user_version = 0;",
                           NULL, NULL, NULL) == SQLITE_OK);
        CHECK(!extra_sql || sqlite3_exec(db, extra_sql, NULL, NULL, NULL) == SQLITE_OK);
        CHECK(sqlite3_close(db) == SQLITE_OK);
}

void tu_sql(const char *path, const char *sql)
{
        char index[4200];
        sqlite3 *db;

        snprintf(index, sizeof(index), "%s/index.sqlite", path);
        CHECK_INT(sqlite3_open_v2(index, &db, SQLITE_OPEN_READWRITE, NULL), SQLITE_OK);
        if (sqlite3_exec(db, sql, NULL, NULL, NULL) != SQLITE_OK) {
                fprintf(stderr, "%s: %s\n", sql, sqlite3_errmsg(db));
                exit(1);
        }
        CHECK_INT(sqlite3_close(db), SQLITE_OK);
}

int64_t tu_sql_int(const char *path, const char *sql)
{
        char index[4200];
        sqlite3 *db;
        sqlite3_stmt *s;
        int64_t v;

        snprintf(index, sizeof(index), "%s/index.sqlite", path);
        CHECK_INT(sqlite3_open_v2(index, &db, SQLITE_OPEN_READONLY, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_prepare_v2(db, sql, -1, &s, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_step(s), SQLITE_ROW);
        v = sqlite3_column_int64(s, 0);
        sqlite3_finalize(s);
        CHECK_INT(sqlite3_close(db), SQLITE_OK);
        return v;
}

void tu_make_schema3(const char *path)
{
        tu_sql(path, "BEGIN;"
                     "CREATE TABLE captures_v3 (id INTEGER PRIMARY KEY,"
                     " session TEXT NOT NULL DEFAULT '',"
                     " turntable_deg REAL, light_arm_deg REAL, camera_arm_deg REAL,"
                     " camera TEXT NOT NULL, lamps TEXT NOT NULL,"
                     " lamp_bits INTEGER NOT NULL DEFAULT 0, laser INTEGER NOT NULL,"
                     " exposure_us INTEGER NOT NULL, gain REAL NOT NULL,"
                     " t_request_ns INTEGER NOT NULL, t_exposure_ns INTEGER NOT NULL,"
                     " t_stored_ns INTEGER NOT NULL, file TEXT NOT NULL UNIQUE,"
                     " sha256 TEXT NOT NULL, width INTEGER NOT NULL, height INTEGER NOT NULL,"
                     " pixfmt TEXT NOT NULL);"
                     "INSERT INTO captures_v3 SELECT id, session, turntable_deg, light_arm_deg,"
                     " camera_arm_deg, camera, lamps, lamp_bits, laser, exposure_us, gain,"
                     " t_request_ns, t_exposure_ns, t_stored_ns, file, sha256, width, height,"
                     " pixfmt FROM captures;"
                     "DROP TABLE captures; DROP TABLE sessions; DROP TABLE plan;"
                     "ALTER TABLE captures_v3 RENAME TO captures;"
                     "CREATE INDEX captures_pose ON captures"
                     " (session, turntable_deg, light_arm_deg, camera_arm_deg);"
                     "UPDATE meta SET value = '3' WHERE key = 'schema_version';"
                     "PRAGMA user_version = 3;"
                     "COMMIT;");
}
