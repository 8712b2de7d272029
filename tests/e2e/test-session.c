/* test-session.c - scripted capture sessions end to end (issue 8): gonioctl session
 * plan/run/pause/resume/abort against goniod on gonio-sim, and a session that resumes after
 * kill -9 of goniod, of gonio-sim or of both, at seeded random moments, with every planned
 * capture present exactly once. Every row is compared with what gonio-sim rendered, and the
 * dataset with `dataset check` (ds_check). */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "common/clock.h"
#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "harness.h"
#include "tests/test.h"

/* Flips one byte in the middle of the dataset's first image. */
static void corrupt_first_image(struct rigenv *e, const char *dataset)
{
        char cmd[600];

        snprintf(cmd, sizeof(cmd),
                 "f=$(ls %s/%s/images/000001_*.png) && printf 'X' | dd of=\"$f\" bs=1 "
                 "seek=200 conv=notrunc status=none",
                 e->data, dataset);
        CHECK(system(cmd) == 0);
}

static int check_refs(const struct ds_capture *c, void *userdata)
{
        bool ref = strcmp(c->kind, "image") == 0 || strcmp(c->kind, "laser") == 0;

        if (ref && (c->dark_id <= 0 || c->flat_id <= 0))
                fprintf(stderr, "row %lld (%s): dark %lld, flat %lld\n", (long long)c->id, c->kind,
                        (long long)c->dark_id, (long long)c->flat_id);
        CHECK(!ref || (c->dark_id > 0 && c->flat_id > 0));
        (*(int *)userdata) += ref;
        return 0;
}

/* Every image and laser row of dataset names its dark frame and flat field. */
static void check_references(struct rigenv *e, const char *dataset)
{
        char path[400];
        struct ds *d = NULL;
        int n = 0;

        snprintf(path, sizeof(path), "%s/%s", e->data, dataset);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK(ds_rows(d, 0, -1, check_refs, &n) > 0);
        CHECK(n > 0);
        ds_close(d);
}

/* plan moves nothing; run captures the plan, once, with .lp files and the records. */
static void test_run(struct rigenv *e)
{
        char file[400], lp[600];
        int64_t n;
        json_t *st;

        sess_write(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        n = sess_planned(e, file, NULL);
        st = ctl_ok(e, "status", NULL);
        CHECK(!json_is_true(json_object_get(st, "homed"))); /* planning moved nothing */
        json_decref(st);
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        sess_check_complete(e, "ds1", "s1", n);
        check_references(e, "ds1");
        snprintf(lp, sizeof(lp), "%s/ds1/lp/s1", e->data);
        CHECK(access(lp, F_OK) == 0);
        /* a second run of the same session name is refused: resume it, or rename */
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 9);
        /* gonioctl dataset check: clean, then one changed byte is found and named */
        CHECK_INT(ctl(e, NULL, "dataset", "check", "ds1", NULL), 0);
        corrupt_first_image(e, "ds1");
        {
                char *argv[] = {
                        (char *)e->gonioctl, "--socket", e->sock, "dataset", "check", "ds1", NULL};
                char err[1024];
                CHECK_INT(run_capture(argv, NULL, 0, err, sizeof(err)), 7);
                CHECK(strstr(err, "000001_"));
        }
}

/* Each operator mistake is refused with file, line and key, and nothing moves. */
static void test_badfile(struct rigenv *e)
{
        static const struct {
                const char *text, *where;
        } cases[] = {
                {"dataset: d\ncameras: [nocam]\n", ":2: key 'cameras'"},
                {"dataset: d\nsweep:\n  camera_arm: [0, 200]\n", ":3: key 'sweep.camera_arm'"},
                {"sweep:\n  turntable: [0, 90]\n", "key 'dataset'"},
                {"dataset: d\nexposure_us: -5\n", ":2: key 'exposure_us'"},
                {"dataset: d\nlamps: [lamp0, lamp9]\n", ":2: key 'lamps'"},
                {"dataset: d\nfrobnicate: 1\n", ":2: key 'frobnicate'"},
        };
        char file[400], err[1024];
        json_t *st;

        for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
                char *argv[] = {
                        (char *)e->gonioctl, "--socket", e->sock, "session", "run", file, NULL};
                sess_write(e, "bad.yaml", cases[i].text, file, sizeof(file));
                CHECK_INT(run_capture(argv, NULL, 0, err, sizeof(err)), 6);
                if (!strstr(err, cases[i].where) || !strstr(err, "bad.yaml"))
                        fprintf(stderr, "case %zu: expected '%s' in: %s\n", i, cases[i].where, err);
                CHECK(strstr(err, "bad.yaml") && strstr(err, cases[i].where));
        }
        st = ctl_ok(e, "status", NULL);
        CHECK_STR(json_string_value(json_object_get(st, "state")), "idle");
        CHECK(!json_is_true(json_object_get(st, "homed")));
        json_decref(st);
}

/* pause stops at a capture boundary with lamps and laser off; resume completes it. */
static void test_pause(struct rigenv *e)
{
        int64_t n;
        json_t *st;
        int fd;

        fd = sess_start_default(e, &n);
        usleep(300000);
        json_decref(ctl_ok(e, "session", "pause", NULL));
        sess_wait(e, "paused", 30);
        st = ctl_ok(e, "status", NULL);
        CHECK(!json_is_true(json_object_get(st, "laser")));
        json_decref(st);
        /* the session owns the rig: other clients cannot move it meanwhile */
        CHECK_INT(ctl(e, NULL, "move", "turntable", "10", NULL), 9);
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        close(fd);
        sess_check_complete(e, "ds1", "s1", n);
}

/* A fault during the session (the drives' bus unplugged) pauses it with the cause;
 * resume after the drives return completes it. */
static void test_fault(struct rigenv *e)
{
        int64_t n;
        json_t *st;
        int fd;

        fd = sess_start_default(e, &n);
        usleep(200000);
        sim_request(e, "{\"cmd\":\"unplug\",\"bus\":\"drives\",\"ms\":1500}\n");
        sess_wait(e, "paused", 30);
        st = ctl_ok(e, "session", "status", NULL);
        CHECK(strlen(json_string_value(json_object_get(st, "reason"))) > 0);
        json_decref(st);
        usleep(1600000); /* the drives are back */
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        close(fd);
        sess_check_complete(e, "ds1", "s1", n);
}

/* A fault pauses the session; it resumes by itself once the device is back. */
static void test_autoresume(struct rigenv *e)
{
        char state[32];
        int64_t n;
        int fd;

        fd = sess_start_default(e, &n);
        usleep(200000);
        sim_request(e, "{\"cmd\":\"unplug\",\"bus\":\"drives\",\"ms\":1000}\n");
        sess_wait(e, "paused", 30);
        for (double end = now_s() + 30;
             strcmp(sess_state(e, state, sizeof(state)), "none") && now_s() < end;)
                usleep(100000); /* no client resumes it */
        close(fd);
        sess_check_complete(e, "ds1", "s1", n);
}

/* The darks of a session in one dataset are reused by a session in another (the data
 * directory's dark library): taken once, imported into the second, named by its rows. */
static void test_darklib(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char file[400], path[400], *text = strdup(e2e_session_text);
        struct ds *d = NULL;
        int64_t n;

        CHECK(text);
        sess_write(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        memcpy(strstr(text, "dataset: ds1"), "dataset: ds2", 12);
        sess_write(e, "s2.yaml", text, file, sizeof(file));
        free(text);
        n = sess_planned(e, file, NULL);
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        sess_info(e, "ds2", "s1", &info);
        CHECK_STR(info.state, "done");
        CHECK_INT(info.planned, n - 2); /* one dark per camera came from the library */
        ds_session_info_clear(&info);
        snprintf(path, sizeof(path), "%s/ds2", e->data);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_count(d), n);
        CHECK(ds_find_dark(d, "cam0", 20000, 1.0, 0) > 0);
        ds_close(d);
        CHECK_INT(sess_problems(e, "ds2"), 0);
        check_references(e, "ds2");
}

/* The state of session.status over a raw connection (fast enough to hit short windows). */
static void raw_session_state(int fd, char *buf, size_t len)
{
        json_t *r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":7,\"method\":\"session.status\"}\n");

        snprintf(buf, len, "%s",
                 json_string_value(json_object_get(json_object_get(r, "result"), "state")));
        json_decref(r);
}

/* A client's stop pauses the session; a resume sent the moment it is paused, while the
 * stopped axis may still be coming to rest, runs it to the end (it waits for the axis). */
static void test_stopresume(struct rigenv *e)
{
        char state[32] = "";
        int64_t n;
        int fd;
        json_t *r;

        fd = sess_start_default(e, &n);
        json_decref(wait_state(e, "moving", 30));
        json_decref(raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":5,\"method\":\"stop\"}\n"));
        for (double end = now_s() + 30; strcmp(state, "paused") != 0 && now_s() < end;)
                raw_session_state(fd, state, sizeof(state)); /* no sleep: resume at once */
        CHECK_STR(state, "paused");
        r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":6,\"method\":\"session.resume\"}\n");
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        for (double end = now_s() + 60; now_s() < end; usleep(50000)) {
                raw_session_state(fd, state, sizeof(state));
                if (strcmp(state, "none") == 0)
                        break;
                CHECK(strcmp(state, "paused") != 0); /* never paused again */
        }
        close(fd);
        sess_check_complete(e, "ds1", "s1", n);
}

/* What a store or a write cut short by a crash may leave in ds1: temporary files (of an
 * image, the rig file, an .lp file) and an image without its row. */
static const char *const leftovers[] = {"images/000999_cam0_lamp0.png.tmp",
                                        "images/000998_cam0_lamp0.png", "rig.yaml.tmp",
                                        "lp/s1/cam0.lp.tmp"};

/* After a crash of goniod the unfinished session can be given up without running it; what
 * the crash left is removed from its dataset before anything reads it. */
static void test_abandon(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char path[400];
        int fd;

        fd = sess_start_default(e, NULL);
        usleep(300000);
        rigenv_crash_daemon(e);
        snprintf(path, sizeof(path), "%s/ds1/lp", e->data);
        CHECK(mkdir(path, 0755) == 0 || errno == EEXIST);
        snprintf(path, sizeof(path), "%s/ds1/lp/s1", e->data);
        CHECK(mkdir(path, 0755) == 0 || errno == EEXIST);
        for (size_t i = 0; i < ELEMENTSOF(leftovers); i++) {
                snprintf(path, sizeof(path), "%s/ds1/%s", e->data, leftovers[i]);
                write_file(path, "torn");
        }
        close(fd);
        CHECK_INT(ctl(e, NULL, "session", "abort", NULL), 0);
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 6); /* nothing left to resume */
        sess_info(e, "ds1", "s1", &info);
        CHECK_STR(info.state, "aborted");
        CHECK(info.captured < info.planned);
        ds_session_info_clear(&info);
        CHECK_INT(sess_problems(e, "ds1"), 0); /* goniod holds ds1: leftovers look in flight */
        for (size_t i = 0; i < ELEMENTSOF(leftovers); i++) {
                snprintf(path, sizeof(path), "%s/ds1/%s", e->data, leftovers[i]);
                if (access(path, F_OK) == 0)
                        fprintf(stderr, "%s was left\n", leftovers[i]);
                CHECK(access(path, F_OK) < 0 && errno == ENOENT);
        }
}

/* kill -9 of goniod, gonio-sim or both at seeded random moments, twice, each followed by a
 * resume; the session ends complete, every capture once. */
static void test_kill(struct rigenv *e, const char *who, unsigned seed)
{
        const char *const whos[] = {who, who};
        char file[400];
        int64_t n;

        srand(seed);
        sess_write(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        n = sess_planned(e, file, NULL);
        sess_run_killing(e, file, whos, 2);
        sess_check_complete(e, "ds1", "s1", n);
}

int main(int argc, char **argv)
{
        struct rigenv e;
        const char *c = argc == 5 ? argv[4] : "";

        /* goniod gonioctl gonio-sim CASE */
        CHECK(argc == 5);
        rigenv_start(&e, argv, 10);
        if (strcmp(c, "run") == 0)
                test_run(&e);
        else if (strcmp(c, "badfile") == 0)
                test_badfile(&e);
        else if (strcmp(c, "pause") == 0)
                test_pause(&e);
        else if (strcmp(c, "fault") == 0)
                test_fault(&e);
        else if (strcmp(c, "autoresume") == 0)
                test_autoresume(&e);
        else if (strcmp(c, "abandon") == 0)
                test_abandon(&e);
        else if (strcmp(c, "darklib") == 0)
                test_darklib(&e);
        else if (strcmp(c, "stopresume") == 0)
                test_stopresume(&e);
        else if (strncmp(c, "kill-", 5) == 0 && strchr(c + 5, '-'))
                test_kill(&e, c + 5, (unsigned)atoi(strchr(c + 5, '-') + 1));
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return 0;
}
