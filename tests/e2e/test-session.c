/* test-session.c - scripted capture sessions end to end (issue 8): gonioctl session
 * plan/run/pause/resume/abort against goniod on gonio-sim, and a session that resumes after
 * kill -9 of goniod, of gonio-sim or of both, at seeded random moments, with every planned
 * capture present exactly once. Every row is compared with what gonio-sim rendered, and the
 * dataset with `dataset check` (ds_check). */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/clock.h"
#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "harness.h"
#include "tests/test.h"

/* 4 turntable x 2 light-arm positions x 2 lamps x 2 cameras + a laser frame per pose + a
 * dark per camera: 16 + 8 x 2 ... as the planner counts (checked against session.plan). */
static const char *const session_text = "name: s1\n"
                                        "dataset: ds1\n"
                                        "sweep:\n"
                                        "  turntable: { from: 0, to: 270, step: 90 }\n"
                                        "  light_arm: [0, 120]\n"
                                        "cameras: [cam0, cam1]\n"
                                        "lamps: [lamp0, lamp1]\n"
                                        "laser: true\n"
                                        "dark_frames: 1\n"
                                        "flat_frames: 1\n"
                                        "skip_occluded: false\n"
                                        "skip_glare: false\n"
                                        "metadata: { object: sphere, operator: e2e }\n";

/* Writes text as DIR/NAME and returns its path (static buffer per call site). */
static const char *session_file(struct rigenv *e, const char *name, const char *text, char *path,
                                size_t len)
{
        snprintf(path, len, "%s/%s", e->dir, name);
        write_file(path, text);
        return path;
}

static int64_t planned_captures(struct rigenv *e, const char *file)
{
        json_t *plan = ctl_ok(e, "session", "plan", file, NULL);
        int64_t n = json_integer_value(json_object_get(plan, "captures"));

        CHECK(n > 0);
        json_decref(plan);
        return n;
}

static void print_problem(const char *problem, void *userdata)
{
        fprintf(stderr, "dataset check: %s\n", problem);
}

/* The session is done with n captures, each once, rows matching the render log, and
 * ds_check finds nothing wrong. */
static void check_complete(struct rigenv *e, const char *dataset, const char *session, int64_t n)
{
        struct ds_session_info info = {0};
        char path[400];
        struct ds *d = NULL;

        snprintf(path, sizeof(path), "%s/%s", e->data, dataset);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_check(d, print_problem, NULL), 0);
        CHECK_INT(ds_session_get(d, session, &info), 0);
        if (strcmp(info.state, "done") != 0)
                fprintf(stderr, "session %s: %s (%s)\n", session, info.state, info.reason);
        CHECK_STR(info.state, "done");
        /* darks found in the dark library are imported rather than planned */
        CHECK(info.planned <= n); /* and every row is there: n, below */
        CHECK_INT(info.captured, info.planned);
        CHECK_INT(ds_count(d), n);
        ds_session_info_clear(&info);
        ds_close(d);
        CHECK_INT(check_dataset_roles(e, dataset, (1u << GN_ROLE_COUNT) - 1), n);
}

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

        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        n = planned_captures(e, file);
        st = ctl_ok(e, "status", NULL);
        CHECK(!json_is_true(json_object_get(st, "homed"))); /* planning moved nothing */
        json_decref(st);
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        check_complete(e, "ds1", "s1", n);
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
                session_file(e, "bad.yaml", cases[i].text, file, sizeof(file));
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

/* Prints a reply that is not a result (for the log of a failing run). */
static void print_reply(const char *what, json_t *reply)
{
        char *text = json_dumps(reply, JSON_COMPACT);

        fprintf(stderr, "%s: %s\n", what, text ? text : "?");
        free(text);
}

/* Starts the session over a raw connection (answered once it runs) and returns that fd. */
static int start_raw(struct rigenv *e, const char *file)
{
        char *text = NULL, req[8192];
        size_t len = 0;
        FILE *f = fopen(file, "re");
        json_t *p, *r;
        int fd = raw_connect(e);

        CHECK(f);
        CHECK(getdelim(&text, &len, 0, f) > 0);
        fclose(f);
        p = json_pack("{sssssss{ssss}}", "jsonrpc", "2.0", "method", "session.run", "id", "1",
                      "params", "file", file, "text", text);
        free(text);
        text = json_dumps(p, JSON_COMPACT);
        CHECK(text);
        snprintf(req, sizeof(req), "%s\n", text);
        free(text);
        json_decref(p);
        r = raw_call(fd, req);
        if (!json_object_get(r, "result"))
                print_reply("session.run", r);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        return fd;
}

static const char *session_state(struct rigenv *e, char *buf, size_t len)
{
        json_t *st = ctl_ok(e, "session", "status", NULL);

        snprintf(buf, len, "%s", json_string_value(json_object_get(st, "state")));
        json_decref(st);
        return buf;
}

/* Waits until the session is paused (or has no session), up to timeout seconds. */
static void wait_session(struct rigenv *e, const char *want, double timeout)
{
        char state[32];

        for (double t = 0; t < timeout; t += 0.05) {
                if (strcmp(session_state(e, state, sizeof(state)), want) == 0)
                        return;
                if (strcmp(state, "none") == 0)
                        break; /* it ended: waiting longer will not help */
                usleep(50000);
        }
        fprintf(stderr, "session state %s, expected %s\n", state, want);
        CHECK(!"timeout waiting for the session");
}

/* pause stops at a capture boundary with lamps and laser off; resume completes it. */
static void test_pause(struct rigenv *e)
{
        char file[400];
        int64_t n;
        json_t *st;
        int fd;

        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        n = planned_captures(e, file);
        fd = start_raw(e, file);
        usleep(300000);
        json_decref(ctl_ok(e, "session", "pause", NULL));
        wait_session(e, "paused", 30);
        st = ctl_ok(e, "status", NULL);
        CHECK(!json_is_true(json_object_get(st, "laser")));
        json_decref(st);
        /* the session owns the rig: other clients cannot move it meanwhile */
        CHECK_INT(ctl(e, NULL, "move", "turntable", "10", NULL), 9);
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        close(fd);
        check_complete(e, "ds1", "s1", n);
}

/* A fault during the session (the drives' bus unplugged) pauses it with the cause;
 * resume after the drives return completes it. */
static void test_fault(struct rigenv *e)
{
        char file[400];
        int64_t n;
        json_t *st;
        int fd;

        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        n = planned_captures(e, file);
        fd = start_raw(e, file);
        usleep(200000);
        sim_request(e, "{\"cmd\":\"unplug\",\"bus\":\"drives\",\"ms\":1500}\n");
        wait_session(e, "paused", 30);
        st = ctl_ok(e, "session", "status", NULL);
        CHECK(strlen(json_string_value(json_object_get(st, "reason"))) > 0);
        json_decref(st);
        usleep(1600000); /* the drives are back */
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        close(fd);
        check_complete(e, "ds1", "s1", n);
}

/* A fault pauses the session; it resumes by itself once the device is back. */
static void test_autoresume(struct rigenv *e)
{
        char file[400], state[32];
        int64_t n;
        int fd;

        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        n = planned_captures(e, file);
        fd = start_raw(e, file);
        usleep(200000);
        sim_request(e, "{\"cmd\":\"unplug\",\"bus\":\"drives\",\"ms\":1000}\n");
        wait_session(e, "paused", 30);
        for (int i = 0; i < 300 && strcmp(session_state(e, state, sizeof(state)), "none"); i++)
                usleep(100000); /* no client resumes it */
        close(fd);
        check_complete(e, "ds1", "s1", n);
}

/* The darks of a session in one dataset are reused by a session in another (the data
 * directory's dark library): taken once, imported into the second, named by its rows. */
static void test_darklib(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char file[400], path[400], *text = strdup(session_text);
        struct ds *d = NULL;
        int64_t n;

        CHECK(text);
        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        memcpy(strstr(text, "dataset: ds1"), "dataset: ds2", 12);
        session_file(e, "s2.yaml", text, file, sizeof(file));
        free(text);
        n = planned_captures(e, file);
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        snprintf(path, sizeof(path), "%s/ds2", e->data);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_session_get(d, "s1", &info), 0);
        CHECK_STR(info.state, "done");
        CHECK_INT(info.planned, n - 2); /* one dark per camera came from the library */
        CHECK_INT(ds_count(d), n);
        CHECK(ds_find_dark(d, "cam0", 20000, 1.0, 0) > 0);
        CHECK_INT(ds_check(d, print_problem, NULL), 0);
        ds_session_info_clear(&info);
        ds_close(d);
        check_references(e, "ds2");
}

/* After a crash of goniod the unfinished session can be given up without running it. */
static void test_abandon(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char file[400], path[400];
        struct ds *d = NULL;
        int fd;

        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        fd = start_raw(e, file);
        usleep(300000);
        rigenv_crash_daemon(e);
        close(fd);
        CHECK_INT(ctl(e, NULL, "session", "abort", NULL), 0);
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 6); /* nothing left to resume */
        snprintf(path, sizeof(path), "%s/ds1", e->data);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_session_get(d, "s1", &info), 0);
        CHECK_STR(info.state, "aborted");
        CHECK(info.captured < info.planned);
        ds_session_info_clear(&info);
        CHECK_INT(ds_check(d, print_problem, NULL), 0);
        ds_close(d);
}

/* kill -9 of goniod, gonio-sim or both at seeded random moments, twice, each followed by a
 * resume; the session ends complete, every capture once. */
static void test_kill(struct rigenv *e, const char *who, unsigned seed)
{
        bool daemon = strchr(who, 'd'), sim = strchr(who, 's');
        char file[400];
        int64_t n;
        int fd;

        srand(seed);
        session_file(e, "s1.yaml", session_text, file, sizeof(file));
        n = planned_captures(e, file);
        fd = start_raw(e, file);
        for (int k = 0; k < 2; k++) {
                json_t *r = NULL;

                usleep(100000 + rand() % 1200000);
                if (sim)
                        rigenv_crash_sim(e);
                if (daemon)
                        rigenv_crash_daemon(e);
                if (!daemon)
                        wait_session(e, "paused", 30);
                close(fd);
                fd = raw_connect(e);
                r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"session.resume\"}\n");
                if (!json_object_get(r, "result"))
                        print_reply("session.resume", r);
                json_decref(r);
        }
        close(fd);
        for (int i = 0; i < 600; i++) { /* the session ends or pauses (a kill hit its end) */
                char state[32];
                if (strcmp(session_state(e, state, sizeof(state)), "none") == 0)
                        break;
                if (strcmp(state, "paused") == 0)
                        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
                usleep(100000);
        }
        check_complete(e, "ds1", "s1", n);
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
        else if (strncmp(c, "kill-", 5) == 0 && strchr(c + 5, '-'))
                test_kill(&e, c + 5, (unsigned)atoi(strchr(c + 5, '-') + 1));
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return 0;
}
