/* test-scan.c - the capture of laser scans through the whole stack (gonio-sim, goniod,
 * gonioctl): a continuous scan whose stored angles agree with the state gonio-sim rendered
 * each frame in, a stop-and-go scan with a laser-off and a laser-on frame at every step,
 * faults of the drive and of the camera during a continuous scan (laser off, motion stopped,
 * a clear error), the refusals while a session or a scan owns the rig, and the end of a
 * scan whose client went away. */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/pose.h"
#include "dataset/ds.h"
#include "harness.h"
#include "tests/test.h"

/* Stored angles against the angle gonio-sim rendered each frame at: interpolation between
 * read-backs, with the read-backs' timing and half the exposure as the error budget. */
#define ANGLE_TOL_DEG 0.05
#define TIME_SCALE    2.0 /* the other cases */
#define MAX_FRAMES    4096

static char **args;

/* The render log: the turntable at each frame's start, middle (rendered) and end, by
 * timestamp. */
struct frame_log {
        size_t n;
        uint64_t t[MAX_FRAMES];
        double start[MAX_FRAMES], mid[MAX_FRAMES], end[MAX_FRAMES];
        bool laser[MAX_FRAMES];
};

static void load_render_log(struct rigenv *e, struct frame_log *fl)
{
        char path[400], line[8192];
        FILE *f;

        snprintf(path, sizeof(path), "%s/render.log", e->dir);
        CHECK((f = fopen(path, "re")));
        fl->n = 0;
        while (fl->n < MAX_FRAMES && fgets(line, sizeof(line), f)) {
                json_t *j = json_loads(line, 0, NULL), *st = json_object_get(j, "state");
                CHECK(j);
                fl->t[fl->n] = (uint64_t)json_integer_value(json_object_get(j, "timestamp_ns"));
                fl->start[fl->n] = json_number_value(json_object_get(st, "turntable"));
                fl->mid[fl->n] = json_number_value(
                        json_object_get(json_object_get(j, "state_mid"), "turntable"));
                fl->end[fl->n] = json_number_value(
                        json_object_get(json_object_get(j, "state_end"), "turntable"));
                fl->laser[fl->n++] = json_is_true(json_object_get(st, "laser"));
                json_decref(j);
        }
        fclose(f);
}

struct check {
        const struct frame_log *fl;
        double worst;
        int64_t laser_on;
};

static int check_angle(const struct ds_capture *c, void *userdata)
{
        struct check *k = userdata;
        const struct frame_log *fl = k->fl;
        size_t i = 0;
        double err;

        while (i < fl->n && fl->t[i] != c->t_exposure_ns)
                i++;
        CHECK(i < fl->n); /* every row is a frame gonio-sim rendered */
        /* gonio-sim renders the frame in the state at mid-exposure (state_mid), the instant
         * goniod interpolates the row's angle at. An exposure that a loaded machine stretched
         * moves state_end, not the image. */
        err = gn_angle_distance(c->pose.deg[GN_ROLE_TURNTABLE], fl->mid[i]);
        if (err > ANGLE_TOL_DEG)
                fprintf(stderr, "row %lld: turntable %.4f, rendered %.4f (%.4f..%.4f)\n",
                        (long long)c->id, c->pose.deg[GN_ROLE_TURNTABLE], fl->mid[i], fl->start[i],
                        fl->end[i]);
        CHECK(err <= ANGLE_TOL_DEG);
        CHECK(c->pose.lasers == fl->laser[i]);
        CHECK_STR(c->kind, "image");
        k->worst = fmax(k->worst, err);
        k->laser_on += c->pose.lasers;
        return 0;
}

/* Checks every row of dataset name against the render log; returns the rows with laser on. */
static int64_t check_angles(struct rigenv *e, const char *name)
{
        static struct frame_log fl;
        struct check k = {.fl = &fl};
        char path[400];
        struct ds *d = NULL;

        load_render_log(e, &fl);
        snprintf(path, sizeof(path), "%s/%s", e->data, name);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_rows(d, 0, -1, check_angle, &k), ds_count(d));
        ds_close(d);
        fprintf(stderr, "%s: worst angle error %.4f deg\n", name, k.worst);
        return k.laser_on;
}

static bool laser_on(json_t *st)
{
        return json_is_true(json_object_get(json_object_get(st, "laser"), "on"));
}

/* The laser is off and no axis moves (read back from the devices). */
static void check_safe(struct rigenv *e)
{
        json_t *st = NULL, *ax;
        bool moving = true;
        size_t i;

        for (double end = now_s() + 10; moving && now_s() < end;) {
                json_decref(st);
                usleep(50000);
                st = ctl_ok(e, "status", NULL);
                moving = laser_on(st);
                json_array_foreach(json_object_get(st, "axes"), i, ax) moving =
                        moving || json_is_true(json_object_get(ax, "moving"));
        }
        if (moving)
                print_json("status", st);
        CHECK(!moving);
        json_decref(st);
}

static void start(struct rigenv *e, double time_scale)
{
        rigenv_start(e, args, time_scale);
        json_decref(ctl_ok(e, "home", NULL));
}

static void test_continuous(void)
{
        struct rigenv e;
        json_t *r;

        start(&e, 1); /* at the speed of a real rig: the read-backs' timing as it will be */
        r = ctl_ok(&e, "scan", "c1", "--no-mesh", "--start", "0", "--end", "200", "--step", "0.45",
                   "--camera", "cam0", "--exposure", "2000", NULL);
        print_json("scan", r);
        CHECK_INT(json_integer_value(json_object_get(r, "positions")), 445);
        CHECK_INT(json_integer_value(json_object_get(r, "legs")), 2);
        /* coverage is timing: on a loaded shared machine gonio-sim may render late */
        CHECK(json_integer_value(json_object_get(r, "stored")) >= 445 * 3 / 4);
        /* never more frames than angles: gonio-sim's camera keeps to its 30 frames/s */
        CHECK(json_integer_value(json_object_get(r, "stored")) <= 445 + 2);
        CHECK(json_number_value(json_object_get(r, "max_gap_deg")) < 10);
        CHECK_NEAR(json_number_value(json_object_get(r, "speed_deg_s")), 0.45 * 30, 1e-9);
        CHECK_INT(check_angles(&e, "c1"), json_integer_value(json_object_get(r, "stored")));
        json_decref(r);
        check_safe(&e);
        rigenv_stop(&e);
}

/* At each turntable angle of the row, one frame with the laser off and one with it on. */
static int count_pair(const struct ds_capture *c, void *userdata)
{
        int *seen = userdata;
        int k = (int)lround(c->pose.deg[GN_ROLE_TURNTABLE] / 4.5);

        CHECK(k >= 0 && k < 5 && fabs(c->pose.deg[GN_ROLE_TURNTABLE] - k * 4.5) < 0.01);
        if (c->pose.lasers || !c->pose.lamps) /* the laser frame and its unlit reference */
                CHECK_STR(c->lamps, "");
        else
                CHECK_STR(c->lamps, "lamp0");
        seen[k] += c->pose.lasers ? 1 : c->pose.lamps ? 16 : 256;
        return 0;
}

static void test_stop_and_go(void)
{
        struct rigenv e;
        int seen[5] = {0};
        char path[400];
        struct ds *d = NULL;

        start(&e, TIME_SCALE);
        CHECK_INT(ctl(&e, NULL, "scan", "s1", "--no-mesh", "--mode", "stop", "--start", "0",
                      "--end", "18", "--step", "4.5", "--camera", "cam0", "--exposure", "2000",
                      "--lamps", "lamp0", NULL),
                  0);
        CHECK_INT(check_dataset_roles(&e, "s1", (1u << GN_ROLE_COUNT) - 1), 15);
        snprintf(path, sizeof(path), "%s/s1", e.data);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_rows(d, 0, -1, count_pair, seen), 15);
        ds_close(d);
        for (int k = 0; k < 5; k++)
                CHECK_INT(seen[k], 273); /* one lamp (16), one unlit (256), one laser (1) */
        check_safe(&e);
        rigenv_stop(&e);
}

/* Starts a continuous scan of a half turn on a raw connection and waits for its first stored
 * frames; returns the fd (the reply comes on it). */
static int scan_raw(struct rigenv *e)
{
        int fd = raw_connect(e);

        CHECK(fd >= 0);
        json_decref(ctl_ok(e, "dataset", "create", "f1", NULL));
        json_decref(raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"hello\",\"params\":"
                                 "{\"client\":\"test\",\"protocol\":1}}\n"));
        const char *req = "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"scan.continuous\",\"params\":"
                          "{\"dataset\":\"f1\",\"camera\":\"cam0\",\"from\":0,\"to\":180,"
                          "\"step\":0.45,\"exposure_us\":2000}}\n";
        CHECK(write(fd, req, strlen(req)) == (ssize_t)strlen(req));
        for (int i = 0; i < 5; i++)
                json_decref(raw_wait_note(fd, "capture.stored", NULL, 20));
        return fd;
}

/* The reply of the scan on fd is an error whose message contains want. */
static void expect_error(int fd, const char *want)
{
        json_t *r = raw_call(fd, "");
        const char *msg =
                json_string_value(json_object_get(json_object_get(r, "error"), "message"));

        print_json("scan reply", r);
        CHECK(msg);
        CHECK_STR_CONTAINS(msg, want);
        CHECK(json_integer_value(json_object_get(
                      json_object_get(json_object_get(json_object_get(r, "error"), "data"), "scan"),
                      "stored")) >= 5);
        json_decref(r);
}

static void test_drive_fault(void)
{
        struct rigenv e;
        int fd;

        start(&e, TIME_SCALE);
        fd = scan_raw(&e);
        sim_request(&e, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":1,\"fault\":\"stall\"}\n");
        expect_error(fd, "fault code 1");
        check_safe(&e);
        close(fd);
        rigenv_stop(&e);
}

static void test_camera_fault(void)
{
        struct rigenv e;
        int fd;

        start(&e, TIME_SCALE);
        fd = scan_raw(&e);
        sim_request(&e, "{\"cmd\":\"inject\",\"camera\":\"cam0\",\"fault\":\"drop\"}\n");
        expect_error(fd, "camera 'cam0'");
        check_safe(&e);
        json_decref(ctl_ok(&e, "move", "turntable", "10", NULL)); /* no fault latched */
        close(fd);
        rigenv_stop(&e);
}

/* While a scan runs: other clients' moves, captures, dataset changes, sessions and scans are
 * refused naming it; stop ends it (canceled). While a session runs, a scan is refused. */
static void test_refusals(void)
{
        struct rigenv e;
        int fd;

        start(&e, TIME_SCALE);
        fd = scan_raw(&e);
        CHECK_INT(ctl(&e, NULL, "move", "light_arm", "10", NULL), 9);
        CHECK_INT(ctl(&e, NULL, "capture", NULL), 9);
        CHECK_INT(ctl(&e, NULL, "dataset", "close", NULL), 9);
        CHECK_INT(ctl(&e, NULL, "laser", "off", NULL), 9);
        CHECK_INT(ctl(&e, NULL, "scan", "f1", "--start", "0", "--end", "10", NULL), 9);
        json_decref(ctl_ok(&e, "stop", NULL));
        expect_error(fd, "stopped");
        check_safe(&e);
        close(fd);
        fd = sess_start_default(&e, NULL);
        CHECK_INT(ctl(&e, NULL, "scan", "f1", "--start", "0", "--end", "10", NULL), 9);
        sess_wait(&e, "none", 90); /* done */
        close(fd);
        rigenv_stop(&e);
}

static void test_disconnect(void)
{
        struct rigenv e;

        start(&e, TIME_SCALE);
        close(scan_raw(&e));
        check_safe(&e);
        json_decref(ctl_ok(&e, "move", "turntable", "10", NULL)); /* the rig is free again */
        rigenv_stop(&e);
}

/* SIGTERM to goniod during a scan: the scan ends with the rig's safe state, goniod exits
 * cleanly and at once, the laser off in gonio-sim. */
static void test_shutdown(void)
{
        struct rigenv e;
        json_t *st;
        int fd, status;

        start(&e, TIME_SCALE);
        fd = scan_raw(&e);
        double t0 = gn_monotonic_ns() * 1e-9;

        CHECK(kill(e.daemon, SIGTERM) == 0);
        CHECK(waitpid(e.daemon, &status, 0) == e.daemon);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
        /* the scan ended with the safe state: goniod did not wait out its 5 s shutdown limit */
        CHECK(gn_monotonic_ns() * 1e-9 - t0 < 4.0);
        e.daemon = 0;
        st = sim_query(&e, "{\"cmd\":\"state\"}\n");
        CHECK(!json_is_true(json_object_get(json_object_get(st, "state"), "laser")));
        json_decref(st);
        close(fd);
        rigenv_stop(&e);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"continuous", test_continuous},   {"stop-and-go", test_stop_and_go},
                {"drive-fault", test_drive_fault}, {"camera-fault", test_camera_fault},
                {"refusals", test_refusals},       {"disconnect", test_disconnect},
                {"shutdown", test_shutdown},
        };

        CHECK(argc >= 4);
        args = argv;
        return TEST_RUN_CASES(cases, argc - 3, argv + 3);
}
