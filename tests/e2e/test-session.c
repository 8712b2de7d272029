/* test-session.c - scripted capture sessions end to end (issue 8): gonioctl session
 * plan/run/pause/resume/abort against goniod on gonio-sim, and a session that resumes after
 * kill -9 of goniod, of gonio-sim or of both, at seeded random moments, with every planned
 * capture present exactly once. Every row is compared with what gonio-sim rendered, and the
 * dataset with `dataset check` (ds_check). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

/* plan moves nothing; run captures the plan, once, with .lp files and the records. */
static void test_run(struct rigenv *e)
{
        char file[400], lp[600];
        int64_t n;
        json_t *st;

        session_file(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        n = planned_captures(e, file);
        st = ctl_ok(e, "status", NULL);
        CHECK(!json_is_true(json_object_get(st, "homed"))); /* planning moved nothing */
        json_decref(st);
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        check_complete(e, "ds1", "s1", n);
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

/* pause stops at a capture boundary with lamps and laser off; resume completes it. */
static void test_pause(struct rigenv *e)
{
        char file[400];
        int64_t n;
        json_t *st;
        int fd;

        session_file(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        n = planned_captures(e, file);
        fd = session_start_raw(e, file);
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

        session_file(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        n = planned_captures(e, file);
        fd = session_start_raw(e, file);
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

/* kill -9 of goniod, gonio-sim or both at seeded random moments, twice, each followed by a
 * resume; the session ends complete, every capture once. */
static void test_kill(struct rigenv *e, const char *who, unsigned seed)
{
        const char *const kills[] = {who, who};
        char file[400];
        int64_t n;

        srand(seed);
        session_file(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        n = planned_captures(e, file);
        session_run_killing(e, file, kills, 2);
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
        else if (strncmp(c, "kill-", 5) == 0 && strchr(c + 5, '-'))
                test_kill(&e, c + 5, (unsigned)atoi(strchr(c + 5, '-') + 1));
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return 0;
}
