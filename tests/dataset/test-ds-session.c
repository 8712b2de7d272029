/* test-ds-session.c - sessions in a real dataset directory: migration of a schema-3
 * index, session records and plans, exactly-once storing of plan items, resume after a
 * writer died without closing, ds_check against each kind of damage, the dark library
 * and the .lp light files.
 *
 * Usage: test-ds-session CASE (one meson test per case). */
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <sqlite3.h>
#include <stdint.h>
#include <string.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "ds-util.h"
#include "tests/test.h"

static const char rig_text[] = "rig: test-rig\nlamps:\n  - { name: l0 }\n  - { name: l1 }\n"
                               "  - { name: l2 }\n";
static const char *const lamp_names[] = {"l0", "l1", "l2"};

struct fixture {
        char *tmp;
        char path[4096];
        struct ds *d;
};

static void setup(struct fixture *fx)
{
        fx->tmp = tu_tmpdir();
        snprintf(fx->path, sizeof(fx->path), "%s/ds", fx->tmp);
        CHECK_INT(ds_create(fx->path, "sessions", rig_text, &fx->d), 0);
}

static void teardown(struct fixture *fx)
{
        fx->d = ds_close(fx->d);
        tu_rm_rf(fx->tmp);
        free(fx->tmp);
}

static void path_of(const struct fixture *fx, const char *rel, char *out, size_t len)
{
        snprintf(out, len, "%s/%s", fx->path, rel);
}

static void touch(const struct fixture *fx, const char *rel)
{
        char p[4400];
        FILE *fp;

        path_of(fx, rel, p, sizeof(p));
        fp = fopen(p, "w");
        CHECK(fp && fputs("torn", fp) >= 0 && fclose(fp) == 0);
}

static int images(const struct fixture *fx)
{
        char p[4400];

        path_of(fx, "images", p, sizeof(p));
        return tu_count(p, "");
}

/* Item seq of a plan over two cameras and three lamps: cameras alternate, lamps cycle,
 * the turntable turns 10 degrees every 6 items, no light arm, camera arm at 30. */
static struct ds_plan_item plan_item(int64_t seq)
{
        struct ds_plan_item it = {.seq = seq, .shot = (seq - 1) / 2, .bracket = 0};

        snprintf(it.camera, sizeof(it.camera), "cam%d", (int)((seq - 1) % 2));
        snprintf(it.kind, sizeof(it.kind), "image");
        it.pose = gn_pose_none();
        it.pose.deg[GN_ROLE_TURNTABLE] = 10.0 * (double)((seq - 1) / 6);
        it.pose.deg[GN_ROLE_CAMERA_ARM] = 30.0;
        it.pose.lamps = 1u << ((seq - 1) % 3);
        it.exposure_us = 2000;
        it.gain = 1.5;
        return it;
}

static void make_plan(struct ds_plan_item *items, size_t n)
{
        for (size_t i = 0; i < n; i++)
                items[i] = plan_item((int64_t)i + 1);
}

/* The row a runner stores for plan item it: the recorded angles off by jitter degrees. */
static void item_capture(struct ds_capture *c, const char *session, const struct ds_plan_item *it,
                         double jitter)
{
        memset(c, 0, sizeof(*c));
        snprintf(c->session, sizeof(c->session), "%s", session);
        c->plan_seq = it->seq;
        snprintf(c->camera, sizeof(c->camera), "%s", it->camera);
        snprintf(c->kind, sizeof(c->kind), "%s", it->kind);
        c->bracket = it->bracket;
        c->pose = it->pose;
        for (int k = 0; k < GN_ROLE_COUNT; k++)
                c->pose.deg[k] += jitter; /* NAN stays NAN */
        CHECK(gn_pose_lamp_list(&c->pose, lamp_names, 3, c->lamps, sizeof(c->lamps)) >= 0);
        c->exposure_us = it->exposure_us;
        c->gain = it->gain;
        c->t_request_ns = 1700000000000000000ull + (uint64_t)it->seq * 1000000;
        c->t_exposure_ns = c->t_request_ns + 500;
}

static int store_capture(struct ds *d, struct ds_capture *c)
{
        struct gn_frame f;
        int r;

        tu_frame(&f, 8, 6, 1, 8, (unsigned)c->plan_seq, false);
        r = ds_store(d, &f, c);
        gn_frame_free_data(&f);
        return r;
}

/* Stores the row of plan item it of session; returns ds_store's result. */
static int store_item(struct ds *d, const char *session, const struct ds_plan_item *it)
{
        struct ds_capture c;

        item_capture(&c, session, it, 0.01);
        return store_capture(d, &c);
}

struct items {
        struct ds_plan_item it[64];
        size_t n;
};

static int collect_item(const struct ds_plan_item *it, void *userdata)
{
        struct items *items = userdata;

        CHECK(items->n < 64);
        items->it[items->n++] = *it;
        return 0;
}

static void check_item_equal(const struct ds_plan_item *a, const struct ds_plan_item *b)
{
        CHECK_INT(a->seq, b->seq);
        CHECK_INT(a->shot, b->shot);
        CHECK_STR(a->camera, b->camera);
        CHECK_STR(a->kind, b->kind);
        CHECK_INT(a->bracket, b->bracket);
        CHECK(gn_pose_equal(&a->pose, &b->pose, 0));
        for (int k = 0; k < GN_ROLE_COUNT; k++)
                CHECK(isnan(a->pose.deg[k]) == isnan(b->pose.deg[k]));
        CHECK_INT(a->exposure_us, b->exposure_us);
        CHECK(a->gain == b->gain);
}

/* ---- migration ---- */

struct rows {
        struct ds_capture c[16];
        int n;
};

static int collect_row(const struct ds_capture *c, void *ud)
{
        struct rows *rows = ud;

        CHECK(rows->n < 16);
        rows->c[rows->n++] = *c;
        return 0;
}

/* An index of schema 3 with rows opens as schema 4: the rows keep everything and read
 * as images outside sessions; sessions work at once. */
static void test_migrate_v3(void)
{
        struct fixture fx = {};
        struct ds_capture c[3];
        struct rows rows = {};
        struct ds_plan_item it = plan_item(1);
        struct gn_frame f;
        struct stat st;
        char p[4400];

        setup(&fx);
        for (int i = 0; i < 3; i++) {
                tu_frame(&f, 8, 8, 1, 8, (unsigned)i, false);
                tu_capture(&c[i], "cam0", "l1", i);
                CHECK_INT(ds_store(fx.d, &f, &c[i]), 0);
                gn_frame_free_data(&f);
        }
        fx.d = ds_close(fx.d);
        tu_make_schema3(fx.path);
        CHECK_INT(tu_sql_int(fx.path, "PRAGMA user_version"), 3);
        CHECK_INT(tu_sql_int(fx.path, "SELECT count(*) FROM sqlite_master WHERE name IN"
                                      " ('sessions', 'plan', 'captures_plan')"),
                  0);
        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK_INT(tu_sql_int(fx.path, "PRAGMA user_version"), 4);
        CHECK_INT(tu_sql_int(fx.path, "SELECT value FROM meta WHERE key = 'schema_version'"), 4);
        CHECK_INT(tu_sql_int(fx.path, "SELECT count(*) FROM sqlite_master WHERE name IN"
                                      " ('sessions', 'plan', 'captures_plan')"),
                  3);
        CHECK_INT(ds_rows(fx.d, 0, -1, collect_row, &rows), 3);
        for (int i = 0; i < 3; i++) {
                CHECK_INT(rows.c[i].id, c[i].id);
                CHECK_STR(rows.c[i].file, c[i].file);
                CHECK_STR(rows.c[i].sha256, c[i].sha256);
                CHECK_STR(rows.c[i].session, c[i].session);
                CHECK(gn_pose_equal(&rows.c[i].pose, &c[i].pose, 0));
                CHECK_STR(rows.c[i].kind, "image");
                CHECK_INT(rows.c[i].plan_seq, 0);
                CHECK_INT(rows.c[i].bracket, 0);
                CHECK_INT(rows.c[i].dark_id + rows.c[i].flat_id, 0);
                CHECK_INT(rows.c[i].size, 0); /* not recorded before schema 4 */
        }
        CHECK_INT(ds_check(fx.d, NULL, NULL), 0);
        CHECK_INT(ds_session_begin(fx.d, "after", NULL, NULL, NULL, NULL, &it, 1), 0);
        CHECK_INT(store_item(fx.d, "after", &it), 0);
        CHECK_INT(ds_count(fx.d), 4);
        rows.n = 0;
        CHECK_INT(ds_rows(fx.d, 3, -1, collect_row, &rows), 1);
        path_of(&fx, rows.c[0].file, p, sizeof(p));
        CHECK(stat(p, &st) == 0 && rows.c[0].size == st.st_size); /* recorded from now on */
        teardown(&fx);
}

/* ---- records ---- */

static void check_begin_refused(struct fixture *fx)
{
        struct ds_plan_item items[3];
        struct ds_session_info info;

        make_plan(items, 3);
        CHECK_INT(ds_session_begin(fx->d, "s1", NULL, NULL, NULL, NULL, items, 3), -EEXIST);
        items[2].seq = 1; /* duplicate seq: nothing of the session is recorded */
        CHECK_INT(ds_session_begin(fx->d, "bad", NULL, NULL, NULL, NULL, items, 3), -EINVAL);
        CHECK_INT(ds_session_get(fx->d, "bad", &info), -ENOENT);
        CHECK_INT(tu_sql_int(fx->path, "SELECT count(*) FROM plan WHERE session = 'bad'"), 0);
        make_plan(items, 3);
        snprintf(items[1].kind, sizeof(items[1].kind), "bogus");
        CHECK_INT(ds_session_begin(fx->d, "bad", NULL, NULL, NULL, NULL, items, 3), -EINVAL);
        items[1] = plan_item(2);
        items[0].seq = 0;
        CHECK_INT(ds_session_begin(fx->d, "bad", NULL, NULL, NULL, NULL, items, 3), -EINVAL);
        CHECK_INT(ds_session_get(fx->d, "bad", &info), -ENOENT);
}

static void check_states(struct fixture *fx)
{
        struct ds_plan_item it = plan_item(1);
        struct ds_session_info info;
        char name[DS_NAME_MAX];

        CHECK_INT(ds_session_unfinished(fx->d, name, sizeof(name)), 0);
        CHECK_STR(name, "s1");
        CHECK_INT(ds_session_begin(fx->d, "s2", "f", "r", "[]", "{}", &it, 1), 0);
        CHECK_INT(ds_session_unfinished(fx->d, name, sizeof(name)), 0);
        CHECK_STR(name, "s2"); /* the newest */
        CHECK_INT(ds_session_set_state(fx->d, "s2", "done", "all captured"), 0);
        CHECK_INT(ds_session_get(fx->d, "s2", &info), 0);
        CHECK_STR(info.state, "done");
        CHECK_STR(info.reason, "all captured");
        CHECK_INT(strlen(info.stopped), 20);
        ds_session_info_clear(&info);
        CHECK_INT(ds_session_unfinished(fx->d, name, sizeof(name)), 0);
        CHECK_STR(name, "s1");
        CHECK_INT(ds_session_set_state(fx->d, "s1", "paused", "ENOSPC"), 0);
        CHECK_INT(ds_session_unfinished(fx->d, name, sizeof(name)), 0);
        CHECK_INT(ds_session_set_state(fx->d, "s1", "aborted", NULL), 0);
        CHECK_INT(ds_session_unfinished(fx->d, name, sizeof(name)), -ENOENT);
        CHECK_INT(ds_session_set_state(fx->d, "nosuch", "done", NULL), -ENOENT);
        CHECK_INT(ds_session_set_state(fx->d, "s1", "sleeping", NULL), -EINVAL);
}

static void check_summary(struct fixture *fx)
{
        struct ds_summary sum;
        json_t *j, *s;
        char p[4400];

        CHECK_INT(ds_summary(fx->d, &sum), 0);
        CHECK_INT(sum.n_sessions, 2);
        CHECK_STR(sum.sessions[0].name, "s1");
        CHECK_STR(sum.sessions[0].state, "aborted");
        CHECK_INT(sum.sessions[0].planned, 5);
        CHECK_INT(sum.sessions[0].captured, 1);
        CHECK_STR(sum.sessions[1].name, "s2");
        fx->d = ds_close(fx->d);
        path_of(fx, "dataset.json", p, sizeof(p));
        j = json_load_file(p, 0, NULL);
        CHECK(j);
        CHECK_INT(json_array_size(json_object_get(j, "sessions")), 2);
        s = json_array_get(json_object_get(j, "sessions"), 0);
        CHECK_STR(json_string_value(json_object_get(s, "name")), "s1");
        CHECK_STR(json_string_value(json_object_get(s, "state")), "aborted");
        CHECK_INT(json_integer_value(json_object_get(s, "planned")), 5);
        CHECK_INT(json_integer_value(json_object_get(s, "captured")), 1);
        CHECK_INT(json_integer_value(json_object_get(j, "schema_version")), 4);
        json_decref(j);
}

/* A session's start record and plan, read back; what begin refuses; states; summary. */
static void test_begin(void)
{
        static const int order[] = {4, 2, 5, 1, 3}; /* given out of order */
        struct ds_plan_item items[5];
        struct ds_session_info info;
        struct items pending = {};
        struct fixture fx = {};

        setup(&fx);
        for (int i = 0; i < 5; i++)
                items[i] = plan_item(order[i]);
        items[0].pose.lasers = 1;
        items[0].bracket = 2;
        snprintf(items[0].kind, sizeof(items[0].kind), "laser");
        CHECK_INT(ds_session_begin(fx.d, "s1", "file: yes\n", rig_text, "{\"plan\":1}",
                                   "{\"who\":\"me\"}", items, 5),
                  0);
        CHECK_INT(ds_session_get(fx.d, "s1", &info), 0);
        CHECK_STR(info.name, "s1");
        CHECK_STR(info.state, "running");
        CHECK_INT(strlen(info.started), 20);
        CHECK_STR(info.stopped, "");
        CHECK_INT(info.planned, 5);
        CHECK_INT(info.captured, 0);
        CHECK_STR(info.file_text, "file: yes\n");
        CHECK_STR(info.rig_text, rig_text);
        CHECK_STR(info.plan_json, "{\"plan\":1}");
        CHECK_STR(info.metadata_json, "{\"who\":\"me\"}");
        ds_session_info_clear(&info);
        CHECK_INT(ds_plan_pending(fx.d, "s1", collect_item, &pending), 5);
        for (int i = 0; i < 5; i++) {
                CHECK_INT(pending.it[i].seq, i + 1); /* seq order */
                for (int j = 0; j < 5; j++)
                        if (items[j].seq == i + 1)
                                check_item_equal(&pending.it[i], &items[j]);
        }
        CHECK_INT(ds_plan_pending(fx.d, "nosuch", collect_item, &pending), -ENOENT);
        CHECK_INT(store_item(fx.d, "s1", &items[3]), 0);
        check_begin_refused(&fx);
        check_states(&fx);
        check_summary(&fx);
        teardown(&fx);
}

/* ---- exactly once ---- */

static void test_once(void)
{
        struct ds_plan_item items[4];
        struct ds_session_info info;
        struct items pending = {};
        struct fixture fx = {};
        struct ds_capture c;

        setup(&fx);
        make_plan(items, 4);
        CHECK_INT(ds_session_begin(fx.d, "s", NULL, NULL, NULL, NULL, items, 4), 0);
        CHECK_INT(store_item(fx.d, "s", &items[1]), 0);
        CHECK_INT(store_item(fx.d, "s", &items[1]), -EEXIST);
        CHECK_STR_CONTAINS(ds_last_error(fx.d), "plan item 2 of session 's' is row 1");
        CHECK_INT(images(&fx), 1);
        CHECK_INT(tu_count_tmp(fx.path), 0);
        CHECK_INT(ds_count(fx.d), 1);
        item_capture(&c, "s", &items[0], 0);
        c.plan_seq = 9; /* not in the plan */
        CHECK_INT(store_capture(fx.d, &c), -EINVAL);
        item_capture(&c, "", &items[0], 0); /* a plan item needs its session */
        CHECK_INT(store_capture(fx.d, &c), -EINVAL);
        item_capture(&c, "s", &items[0], 0);
        snprintf(c.kind, sizeof(c.kind), "bogus");
        CHECK_INT(store_capture(fx.d, &c), -EINVAL);
        CHECK_INT(images(&fx), 1);
        CHECK_INT(ds_plan_pending(fx.d, "s", collect_item, &pending), 3);
        CHECK_INT(pending.it[0].seq, 1);
        CHECK_INT(pending.it[1].seq, 3);
        CHECK_INT(pending.it[2].seq, 4);
        for (size_t i = 0; i < pending.n; i++)
                CHECK_INT(store_item(fx.d, "s", &pending.it[i]), 0);
        for (size_t i = 0; i < 4; i++)
                CHECK_INT(store_item(fx.d, "s", &items[i]), -EEXIST);
        CHECK_INT(ds_plan_pending(fx.d, "s", collect_item, &pending), 0);
        CHECK_INT(ds_session_get(fx.d, "s", &info), 0);
        CHECK_INT(info.captured, 4);
        ds_session_info_clear(&info);
        CHECK_INT(images(&fx), 4);
        CHECK_INT(ds_check(fx.d, NULL, NULL), 0);
        teardown(&fx);
}

/* ---- resume after a crash ---- */

/* The writer of a child stores items 1..half, leaves what a crash mid-store leaves (an
 * image renamed before its row, a temporary file) and dies without closing. */
static void crash_child(const char *path, const struct ds_plan_item *items, size_t half)
{
        struct ds *d = NULL;
        pid_t pid = fork();
        int status;

        CHECK(pid >= 0);
        if (pid == 0) {
                if (ds_open(path, &d) < 0)
                        _exit(2);
                for (size_t i = 0; i < half; i++)
                        if (store_item(d, "s", &items[i]) < 0)
                                _exit(3);
                _exit(0); /* no ds_close: the WAL is not checkpointed, no json written */
        }
        CHECK(waitpid(pid, &status, 0) == pid);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

static void count_problem(const char *problem, void *userdata)
{
        fprintf(stderr, "problem: %s\n", problem);
        (*(int *)userdata)++;
}

static void test_crash(void)
{
        struct ds_plan_item items[10];
        struct items pending = {};
        struct fixture fx = {};
        int problems = 0;

        setup(&fx);
        make_plan(items, 10);
        CHECK_INT(ds_session_begin(fx.d, "s", NULL, NULL, NULL, NULL, items, 10), 0);
        fx.d = ds_close(fx.d);
        crash_child(fx.path, items, 5);
        /* the items the dead writer was storing (another order than the resume's) */
        touch(&fx, "images/000006_cam0_l0.png");
        touch(&fx, "images/000007_cam1_l1.png.tmp");

        CHECK_INT(ds_open(fx.path, &fx.d), 0);
        CHECK_INT(ds_plan_pending(fx.d, "s", collect_item, &pending), 5);
        for (int i = 0; i < 5; i++)
                CHECK_INT(pending.it[i].seq, 6 + i);
        CHECK_INT(ds_check(fx.d, count_problem, &problems), 2); /* the orphan and the tmp */
        CHECK_INT(problems, 2);
        for (size_t i = 0; i < pending.n; i++)
                CHECK_INT(store_item(fx.d, "s", &pending.it[i]), 0);
        CHECK_INT(ds_session_set_state(fx.d, "s", "done", NULL), 0);
        CHECK_INT(tu_count_tmp(fx.path), 0);
        CHECK_INT(images(&fx), 10);
        CHECK_INT(ds_plan_pending(fx.d, "s", collect_item, &pending), 0);
        CHECK_INT(tu_sql_int(fx.path, "SELECT count(DISTINCT plan_seq) FROM captures"
                                      " WHERE session = 's'"),
                  10);
        CHECK_INT(ds_count(fx.d), 10);
        CHECK_INT(ds_check(fx.d, count_problem, &problems), 0);
        teardown(&fx);
}

/* A child stores the 40 items of session "s" of the closed dataset at path, telling the
 * parent through fd after its first `after` stores; SIGKILLed somewhere after that. */
static pid_t kill_child(const char *path, const struct ds_plan_item *items, int after, int fd)
{
        struct ds *d = NULL;
        pid_t pid = fork();

        CHECK(pid >= 0);
        if (pid > 0)
                return pid;
        CHECK_INT(ds_open(path, &d), 0);
        for (int i = 0; i < 40; i++) {
                if (i == after)
                        CHECK(write(fd, "k", 1) == 1);
                CHECK_INT(store_item(d, "s", &items[i]), 0);
        }
        pause(); /* the kill comes */
        _exit(1);
}

/* kill -9 of the writer at seeded random moments (after a random number of stores, a
 * random fraction of a store later): the resumed session is complete, each plan item
 * exactly once, ds_check clean. */
static void test_kill(void)
{
        struct ds_plan_item items[40];

        make_plan(items, 40);
        for (unsigned seed = 1; seed <= 10; seed++) {
                struct fixture fx = {};
                struct items pending = {};
                int status, problems = 0, pipefd[2];
                unsigned state = seed;
                pid_t pid;
                char k;

                setup(&fx);
                CHECK_INT(ds_session_begin(fx.d, "s", NULL, NULL, NULL, NULL, items, 40), 0);
                fx.d = ds_close(fx.d);
                CHECK(pipe(pipefd) == 0);
                pid = kill_child(fx.path, items, rand_r(&state) % 40, pipefd[1]);
                CHECK(read(pipefd[0], &k, 1) == 1);
                usleep((useconds_t)(rand_r(&state) % 10000));
                CHECK(kill(pid, SIGKILL) == 0 && waitpid(pid, &status, 0) == pid);
                CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
                close(pipefd[0]);
                close(pipefd[1]);
                CHECK_INT(ds_open(fx.path, &fx.d), 0);
                CHECK(ds_plan_pending(fx.d, "s", collect_item, &pending) >= 0);
                for (size_t i = 0; i < pending.n; i++)
                        CHECK_INT(store_item(fx.d, "s", &pending.it[i]), 0);
                CHECK_INT(tu_sql_int(fx.path, "SELECT count(DISTINCT plan_seq) FROM captures"), 40);
                CHECK_INT(ds_count(fx.d), 40);
                CHECK_INT(images(&fx), 40);
                CHECK_INT(ds_check(fx.d, count_problem, &problems), 0);
                fprintf(stderr, "seed %u: killed with %zu of 40 to resume\n", seed, pending.n);
                teardown(&fx);
        }
}

/* ---- check ---- */

#define CHECK_ITEMS 6

/* A good dataset: a dark frame outside sessions, then session "s" of CHECK_ITEMS items
 * referring to it. Returns the first item's row id. */
static int64_t good_dataset(struct fixture *fx)
{
        struct ds_plan_item items[CHECK_ITEMS];
        struct ds_capture c, dark;

        setup(fx);
        tu_capture(&dark, "cam0", "", 2);
        snprintf(dark.kind, sizeof(dark.kind), "dark");
        dark.session[0] = 0;
        CHECK_INT(store_capture(fx->d, &dark), 0);
        make_plan(items, CHECK_ITEMS);
        CHECK_INT(ds_session_begin(fx->d, "s", NULL, NULL, NULL, NULL, items, CHECK_ITEMS), 0);
        for (int i = 0; i < CHECK_ITEMS; i++) {
                item_capture(&c, "s", &items[i], 0.04); /* within the 0.05 degree tolerance */
                c.dark_id = dark.id;
                CHECK_INT(store_capture(fx->d, &c), 0);
        }
        return dark.id + 1;
}

struct found {
        int n;
        char text[4096];
};

static void record_problem(const char *problem, void *userdata)
{
        struct found *f = userdata;

        fprintf(stderr, "problem: %s\n", problem);
        f->n++;
        strncat(f->text, problem, sizeof(f->text) - strlen(f->text) - 1);
}

/* Closes the writer and runs ds_check on a new handle: exactly n problems, their text
 * containing each of the words. */
static void expect_problems(struct fixture *fx, int n, const char *const *words)
{
        struct found found = {};
        struct ds *reader = NULL;

        fx->d = ds_close(fx->d);
        CHECK_INT(ds_open(fx->path, &reader), 0);
        CHECK_INT(ds_check(reader, record_problem, &found), n);
        CHECK_INT(found.n, n);
        for (; *words; words++)
                CHECK_STR_CONTAINS(found.text, *words);
        ds_close(reader);
}

static void flip_byte(struct fixture *fx, const char *rel, long at)
{
        char p[4400];
        FILE *fp;
        int ch;

        path_of(fx, rel, p, sizeof(p));
        fp = fopen(p, "r+b");
        CHECK(fp && fseek(fp, at, SEEK_SET) == 0);
        ch = fgetc(fp);
        CHECK(ch != EOF && fseek(fp, at, SEEK_SET) == 0 && fputc(ch ^ 1, fp) != EOF);
        CHECK(fclose(fp) == 0);
}

static void damage_missing(struct fixture *fx, const char *file)
{
        char p[4400];

        path_of(fx, file, p, sizeof(p));
        CHECK(unlink(p) == 0);
        expect_problems(fx, 1, (const char *const[]){file, "is missing", NULL});
}

static void damage_byte(struct fixture *fx, const char *file)
{
        flip_byte(fx, file, 40);
        expect_problems(fx, 1, (const char *const[]){file, "does not match its checksum", NULL});
}

static void damage_truncate(struct fixture *fx, const char *file)
{
        char p[4400];

        path_of(fx, file, p, sizeof(p));
        CHECK(truncate(p, 50) == 0);
        expect_problems(fx, 1, (const char *const[]){file, "is 50 bytes, its row says", NULL});
}

static void damage_orphan(struct fixture *fx, const char *file)
{
        touch(fx, "images/000099_cam0_l1.png");
        expect_problems(fx, 1, (const char *const[]){"images/000099_cam0_l1.png has no row", NULL});
}

static void damage_tmp(struct fixture *fx, const char *file)
{
        touch(fx, "images/000099_cam0_l1.png.tmp");
        touch(fx, "rig.yaml.tmp");
        expect_problems(fx, 2,
                        (const char *const[]){"images/000099_cam0_l1.png.tmp is a temporary",
                                              "rig.yaml.tmp is a temporary", NULL});
}

/* A second row of plan item 2, inserted with SQL: refused while the unique index is
 * there; with the index dropped, ds_check says both. */
static void damage_duplicate(struct fixture *fx, const char *file)
{
        static const char dup[] =
                "INSERT INTO captures (id, session, turntable_deg, camera_arm_deg, camera,"
                " lamps, lamp_bits, laser, exposure_us, gain, t_request_ns, t_exposure_ns,"
                " t_stored_ns, file, sha256, width, height, pixfmt, plan_seq, kind, bracket)"
                " SELECT 100, session, turntable_deg, camera_arm_deg, camera, lamps, lamp_bits,"
                " laser, exposure_us, gain, t_request_ns, t_exposure_ns, t_stored_ns,"
                " file || '.dup.png', sha256, width, height, pixfmt, plan_seq, kind, bracket"
                " FROM captures WHERE plan_seq = 2";
        char index[4400], from[4400], to[4500];
        sqlite3 *db;

        path_of(fx, "index.sqlite", index, sizeof(index));
        CHECK_INT(sqlite3_open_v2(index, &db, SQLITE_OPEN_READWRITE, NULL), SQLITE_OK);
        CHECK_INT(sqlite3_exec(db, dup, NULL, NULL, NULL) & 0xff, SQLITE_CONSTRAINT);
        CHECK_INT(sqlite3_close(db), SQLITE_OK);
        tu_sql(fx->path, "DROP INDEX captures_plan");
        tu_sql(fx->path, dup);
        path_of(fx, "images/000003_cam1_l1.png", from, sizeof(from)); /* item 2's image */
        snprintf(to, sizeof(to), "%s.dup.png", from);
        CHECK(link(from, to) == 0);
        expect_problems(fx, 2,
                        (const char *const[]){"lacks captures_plan",
                                              "Plan item 2 of session 's' has 2 rows (ids 3, 100)",
                                              NULL});
}

/* Rows off their plan: one stored for the wrong camera 0.1 degree off, one naming an
 * item the plan does not have (with SQL: ds_store refuses it). */
static void damage_plan(struct fixture *fx, const char *file)
{
        struct ds_plan_item it = plan_item(1);
        struct ds_capture c;

        CHECK_INT(ds_session_begin(fx->d, "m", NULL, NULL, NULL, NULL, &it, 1), 0);
        item_capture(&c, "m", &it, 0.1);
        snprintf(c.camera, sizeof(c.camera), "cam1");
        CHECK_INT(store_capture(fx->d, &c), 0);
        tu_sql(fx->path, "UPDATE captures SET plan_seq = 77 WHERE id = 2");
        expect_problems(fx, 3,
                        (const char *const[]){"disagrees with plan item 1 of session 'm' in: "
                                              "camera turntable camera_arm.",
                                              "Row 2 (images/000002_cam0_l0.png) names plan item "
                                              "77 of session 's', which does not exist",
                                              "Session 's' records 6 captures, 5 of its", NULL});
}

/* Counts and references that do not add up. */
static void damage_counts(struct fixture *fx, const char *file)
{
        struct ds_plan_item items[2];

        make_plan(items, 2);
        CHECK_INT(ds_session_begin(fx->d, "half", NULL, NULL, NULL, NULL, items, 2), 0);
        CHECK_INT(store_item(fx->d, "half", &items[0]), 0);
        CHECK_INT(ds_session_set_state(fx->d, "half", "done", NULL), 0);
        tu_sql(fx->path, "UPDATE sessions SET planned = 7 WHERE name = 's';"
                         "UPDATE captures SET dark_id = 2 WHERE id = 3;"
                         "UPDATE captures SET flat_id = 999 WHERE id = 4");
        expect_problems(fx, 4,
                        (const char *const[]){"Session 'half' is done, yet 1 of its 2",
                                              "Session 's' records 7 planned captures, its plan "
                                              "has 6 items",
                                              "Row 3 (images/000003_cam1_l1.png) refers to dark "
                                              "frame 2, which is not a dark row",
                                              "refers to flat frame 999", NULL});
}

/* An index that no longer matches its table: SQLite's integrity check says so. */
static void damage_integrity(struct fixture *fx, const char *file)
{
        tu_sql(fx->path, "PRAGMA writable_schema = ON;"
                         "UPDATE sqlite_master SET sql = 'CREATE INDEX captures_pose ON captures"
                         " (camera)' WHERE name = 'captures_pose'");
        expect_problems(fx, 1 + CHECK_ITEMS,
                        (const char *const[]){"SQLite's integrity check of index.sqlite: row 1 "
                                              "missing from index captures_pose.",
                                              NULL});
}

/* ds_check is clean on a good dataset and finds each kind of damage done to one. */
static void test_check(void)
{
        static void (*const damages[])(struct fixture * fx, const char *file) = {
                damage_missing,   damage_byte, damage_truncate, damage_orphan,    damage_tmp,
                damage_duplicate, damage_plan, damage_counts,   damage_integrity,
        };

        for (size_t i = 0; i < sizeof(damages) / sizeof(damages[0]); i++) {
                struct fixture fx = {};
                struct rows rows = {};
                int64_t first = good_dataset(&fx);

                CHECK_INT(ds_check(fx.d, NULL, NULL), 0);
                CHECK_INT(ds_rows(fx.d, first - 1, 1, collect_row, &rows), 1);
                damages[i](&fx, rows.c[0].file); /* the first item's image */
                teardown(&fx);
        }
}

/* On a second handle while another holds the writer's lock, a store in flight (its temp
 * file, its image renamed before the row) is no problem; once the writer is gone, it is. */
static void test_check_live(void)
{
        struct fixture fx = {};
        struct ds *reader = NULL;

        good_dataset(&fx);
        touch(&fx, "images/000009_cam0_l0.png.tmp");
        touch(&fx, "images/000009_cam0_l0.png");
        touch(&fx, "images/000002_cam0_l0.png.x"); /* below the last row: never in flight */
        CHECK_INT(ds_open(fx.path, &reader), 0);
        CHECK_INT(ds_check(reader, NULL, NULL), 1);
        fx.d = ds_close(fx.d);
        CHECK_INT(ds_check(reader, NULL, NULL), 3);
        ds_close(reader);
        teardown(&fx);
}

/* ---- the dark library ---- */

static int64_t store_dark(struct ds *d, const char *camera, int exposure_us, double gain,
                          uint64_t t, const char *kind)
{
        struct ds_capture c;

        tu_capture(&c, camera, "", 0);
        snprintf(c.kind, sizeof(c.kind), "%s", kind);
        c.exposure_us = exposure_us;
        c.gain = gain;
        c.t_exposure_ns = t;
        CHECK_INT(store_capture(d, &c), 0);
        return c.id;
}

static void test_dark(void)
{
        struct fixture fx = {};
        int64_t a, b;

        setup(&fx);
        CHECK_INT(ds_find_dark(fx.d, "cam0", 1000, 1.0, 0), 0);
        a = store_dark(fx.d, "cam0", 1000, 1.0, 100, "dark");
        b = store_dark(fx.d, "cam0", 1000, 1.0, 300, "dark");
        store_dark(fx.d, "cam0", 1000, 1.0, 900, "image"); /* not a dark frame */
        store_dark(fx.d, "cam0", 2000, 1.0, 900, "dark");
        store_dark(fx.d, "cam0", 1000, 2.0, 900, "dark");
        store_dark(fx.d, "cam1", 1000, 1.0, 900, "dark");
        CHECK_INT(ds_find_dark(fx.d, "cam0", 1000, 1.0, 0), b); /* the newest */
        CHECK_INT(ds_find_dark(fx.d, "cam0", 1000, 1.0 + 1e-9, 300), b);
        CHECK_INT(ds_find_dark(fx.d, "cam0", 1000, 1.0, 301), 0); /* too old */
        fx.d = ds_close(fx.d);
        CHECK_INT(ds_open(fx.path, &fx.d), 0); /* a library across sessions and handles */
        CHECK_INT(ds_find_dark(fx.d, "cam0", 1000, 1.0, 50), b);
        CHECK(a != b);
        CHECK_INT(ds_find_dark(fx.d, "cam2", 1000, 1.0, 0), 0);
        teardown(&fx);
}

/* ---- .lp files ---- */

/* Lamp k lights from azimuth 90 k degrees, 45 degrees up. */
static int lamp_dir(const struct ds_capture *c, double dir[3], void *userdata)
{
        int k = __builtin_ctz(c->pose.lamps);
        double a = k * M_PI / 2;

        if (userdata)
                return *(int *)userdata;
        dir[0] = cos(a) / sqrt(2);
        dir[1] = sin(a) / sqrt(2);
        dir[2] = 1 / sqrt(2);
        return 0;
}

static void read_text(const struct fixture *fx, const char *rel, char *buf, size_t len)
{
        char p[4400];
        FILE *fp;
        size_t n;

        path_of(fx, rel, p, sizeof(p));
        fp = fopen(p, "r");
        CHECK(fp);
        n = fread(buf, 1, len - 1, fp);
        buf[n] = 0;
        fclose(fp);
}

/* Stores the plan of the lp test: 3 views x 3 single lamps, and in view (cam0, tt 0)
 * what an .lp file leaves out: two lamps, bracket 1, a dark frame, the laser. */
static void lp_session(struct fixture *fx, char files[9][256])
{
        static const struct {
                const char *cam;
                double tt;
        } views[] = {{"cam0", 0}, {"cam0", 22.5}, {"cam1", 0}};
        struct ds_plan_item items[13];
        struct ds_capture c;
        int n = 0;

        for (int v = 0; v < 3; v++)
                for (int k = 0; k < 3; k++, n++) {
                        items[n] = plan_item(n + 1);
                        snprintf(items[n].camera, DS_NAME_MAX, "%s", views[v].cam);
                        items[n].pose.deg[GN_ROLE_TURNTABLE] = views[v].tt;
                        items[n].pose.deg[GN_ROLE_LIGHT_ARM] = 15.0 * k;
                        items[n].pose.lamps = 1u << k;
                }
        for (; n < 13; n++) {
                items[n] = items[0]; /* cam0, tt 0 */
                items[n].seq = n + 1;
        }
        items[9].pose.lamps = 3;
        items[10].bracket = 1;
        snprintf(items[11].kind, sizeof(items[11].kind), "dark");
        items[11].pose.lamps = 0;
        snprintf(items[12].kind, sizeof(items[12].kind), "laser");
        items[12].pose.lasers = 1;
        CHECK_INT(ds_session_begin(fx->d, "rti 1", NULL, NULL, NULL, NULL, items, 13), 0);
        for (int i = 12; i >= 0; i--) { /* ids against seq order: files list by id */
                item_capture(&c, "rti 1", &items[i], i % 2 ? 0.004 : -0.004);
                CHECK_INT(store_capture(fx->d, &c), 0);
                if (i < 9)
                        snprintf(files[i], 256, "%s", c.file);
        }
}

static void test_lp(void)
{
        struct fixture fx = {};
        char files[9][256], want[2048], got[2048], p[4400];
        int skip = 1, stop = -ECANCELED;

        setup(&fx);
        lp_session(&fx, files);
        CHECK_INT(ds_write_lp(fx.d, "rti 1", lamp_dir, NULL), 3);
        /* ids descend with seq: l2's image comes first */
        snprintf(want, sizeof(want),
                 "3\n../../%s -0.707107 0.000000 0.707107\n../../%s 0.000000 0.707107 0.707107\n"
                 "../../%s 0.707107 0.000000 0.707107\n",
                 files[2], files[1], files[0]);
        read_text(&fx, "lp/rti-1/cam0_tt0_ca30.lp", got, sizeof(got));
        CHECK_STR(got, want);
        snprintf(want, sizeof(want),
                 "3\n../../%s -0.707107 0.000000 0.707107\n../../%s 0.000000 0.707107 0.707107\n"
                 "../../%s 0.707107 0.000000 0.707107\n",
                 files[5], files[4], files[3]);
        read_text(&fx, "lp/rti-1/cam0_tt22.5_ca30.lp", got, sizeof(got));
        CHECK_STR(got, want);
        read_text(&fx, "lp/rti-1/cam1_tt0_ca30.lp", got, sizeof(got));
        CHECK_STR_CONTAINS(got, files[8]);
        path_of(&fx, "lp/rti-1/../../", p, sizeof(p)); /* paths resolve from the file's dir */
        strncat(p, files[0], sizeof(p) - strlen(p) - 1);
        CHECK(access(p, R_OK) == 0);
        path_of(&fx, "lp/rti-1", p, sizeof(p));
        CHECK_INT(tu_count(p, ""), 3);
        CHECK_INT(tu_count(p, ".tmp"), 0);
        CHECK_INT(ds_write_lp(fx.d, "rti 1", lamp_dir, &skip), 0); /* all left out */
        CHECK_INT(ds_write_lp(fx.d, "rti 1", lamp_dir, &stop), -ECANCELED);
        CHECK_INT(ds_write_lp(fx.d, "nosuch", lamp_dir, NULL), 0);
        CHECK_INT(ds_check(fx.d, NULL, NULL), 0);
        teardown(&fx);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"migrate-v3", test_migrate_v3}, {"begin", test_begin}, {"once", test_once},
                {"crash", test_crash},           {"kill", test_kill},   {"check", test_check},
                {"check-live", test_check_live}, {"dark", test_dark},   {"lp", test_lp},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
