/* test-rig.c - goniod's rig and capture pipeline in process (libgoniod), against
 * gonio-sim's Modbus emulators and frame server running in the same process on ptys
 * and a Unix socket: exposures hold the pose and refuse changes, unhomed axes record
 * no angle, a stopped axis is followed until it stands still, and a capture that
 * partly fails reports each camera's outcome with the stored row.
 * Usage: test-rig CASE */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "common/clock.h"
#include "daemon/capture.h"
#include "daemon/rig.h"
#include "sim/frame_server.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-rig\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: '@DIR@/drives' }\n"
        "  - { name: relays, type: modbus-rtu, port: '@DIR@/relays' }\n"
        "  - { name: frames, type: sim, port: '@DIR@/frames.sock' }\n"
        "axes:\n"
        "  - { name: tt, role: turntable, modbus: { bus: drives, unit: 1 },\n"
        "      continuous: true, max_speed: 90, accel: 180, settle_ms: 10 }\n"
        "  - { name: light_arm, modbus: { bus: drives, unit: 2 }, continuous: true,\n"
        "      max_speed: 45, accel: 90, settle_ms: 10,\n"
        "      backlash: 3, deadband: 0.02, move_retries: 2 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3 }, limits: [-170, 170],\n"
        "      max_speed: 30, accel: 60, settle_ms: 10 }\n"
        "lamps:\n"
        "  - { name: lamp0, modbus-coil: { bus: relays, unit: 10, coil: 0 },\n"
        "      elevation: 30, radius: 450, intensity: 4.0e5 }\n"
        "  - { name: lamp1, modbus-coil: { bus: relays, unit: 10, coil: 1 },\n"
        "      elevation: 60, radius: 450, intensity: 4.0e5 }\n"
        "cameras:\n"
        "  - { name: cam0, sim: { bus: frames }, elevation: 20, distance: 500,\n"
        "      target: [0, 0, 30], width: 64, height: 48, fx: 96, fy: 96 }\n"
        "  - { name: cam1, sim: { bus: frames }, elevation: 50, distance: 500,\n"
        "      target: [0, 0, 30], width: 64, height: 48, fx: 96, fy: 96 }\n"
        "scene:\n"
        "  seed: 1\n"
        "  object: { shape: sphere, size: 60, pose: { translate: [30, 0, 30] } }\n";

#define POSE_TOL_DEG 0.01

struct fixture {
        struct testrig t;
        struct sim_scene *scene;
        struct sim_frame_server *fs;
        sd_event *event;
        struct rig *rig;
        int done;   /* completions seen */
        int result; /* of the last plain completion */
        struct rig_exposure exp;
        struct capture_result res;
};

static void on_done(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct fixture *f = userdata;

        f->result = result;
        f->done++;
}

static void on_exposed(struct rig *rig, struct rig_exposure *e, void *userdata)
{
        struct fixture *f = userdata;

        f->exp = *e;
        for (size_t i = 0; i < e->n_shots; i++)
                f->exp.shots[i].frame = (struct gn_frame){0}; /* frames stay the rig's */
        f->done++;
}

static void on_captured(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct fixture *f = userdata;

        f->res = *res;
        f->done++;
}

/* Runs the loop until done reaches want (fails after 20 s). */
static void run_until(struct fixture *f, int want)
{
        double end = testrig_now() + 20;

        while (f->done < want) {
                CHECK(testrig_now() < end);
                CHECK(sd_event_run(f->event, 100 * 1000) >= 0);
        }
}

/* Runs the loop for s seconds. */
static void run_for(struct fixture *f, double s)
{
        double end = testrig_now() + s;

        while (testrig_now() < end)
                CHECK(sd_event_run(f->event, 10 * 1000) >= 0);
}

static void start(struct fixture *f, const char *yaml)
{
        char err[512] = "";

        testrig_start(&f->t, yaml);
        CHECK_INT(sim_scene_new(f->t.rc, &f->scene, err, sizeof(err)), 0);
        if (f->t.rc->n_cameras > 0)
                CHECK_INT(sim_frame_server_new(f->t.rc, f->scene, f->t.emu, NULL, &f->fs), 0);
        CHECK_INT(sd_event_new(&f->event), 0);
        CHECK_INT(rig_new(f->event, f->t.rc, NULL, NULL, &f->rig), 0);
        CHECK_STR(rig_state(f->rig), "idle");
}

static void stop(struct fixture *f)
{
        rig_safe_state(f->rig);
        while (rig_pending(f->rig) > 0)
                CHECK(sd_event_run(f->event, 100 * 1000) >= 0);
        f->rig = rig_free(f->rig);
        sd_event_unref(f->event);
        sim_frame_server_free(f->fs);
        sim_scene_free(f->scene);
        testrig_stop(&f->t);
}

static void home_all(struct fixture *f)
{
        int want = f->done;

        for (size_t i = 0; i < f->t.rc->n_axes; i++, want++)
                CHECK_INT(rig_home(f->rig, i, on_done, f), 0);
        run_until(f, want);
        CHECK_INT(f->result, 0);
}

static void move(struct fixture *f, int axis, double deg)
{
        CHECK_INT(rig_move(f->rig, axis, &deg, false, on_done, f), 0);
        run_until(f, f->done + 1);
        CHECK_INT(f->result, 0);
}

static void lamp(struct fixture *f, int i, bool on)
{
        CHECK_INT(rig_switch(f->rig, i, on, on_done, f), 0);
        run_until(f, f->done + 1);
        CHECK_INT(f->result, 0);
}

/* The emulated rig's state as gonio-sim renders it, with the rig's roles only. */
static struct gn_pose sim_pose(struct fixture *f)
{
        struct gn_pose p;

        sim_emu_snapshot(f->t.emu, &p);
        return p;
}

/* During an exposure moves and switching are refused, and its pose is the devices'. */
static void test_expose(struct fixture *f)
{
        static const int cams[] = {0, 1};
        struct gn_pose truth;
        double deg = 10;

        home_all(f);
        move(f, 0, 123.4);
        move(f, 2, -20);
        lamp(f, 1, true);
        CHECK_INT(rig_expose(f->rig, cams, 2, &(struct cam_request){0}, on_exposed, f), 0);
        CHECK_STR(rig_state(f->rig), "capturing");
        CHECK_INT(rig_move(f->rig, 0, &deg, false, on_done, f), -EBUSY);
        CHECK(strstr(rig_busy_reason(f->rig), "capture"));
        CHECK_INT(rig_switch(f->rig, 0, true, on_done, f), -EBUSY);
        CHECK_INT(rig_expose(f->rig, cams, 1, &(struct cam_request){0}, on_exposed, f), -EBUSY);
        run_until(f, f->done + 1);
        CHECK_STR(rig_state(f->rig), "idle");
        truth = sim_pose(f);
        CHECK(gn_pose_equal(&f->exp.pose, &truth, POSE_TOL_DEG));
        CHECK_NEAR(f->exp.pose.deg[GN_ROLE_TURNTABLE], 123.4, POSE_TOL_DEG);
        CHECK_INT(f->exp.pose.lamps, 1u << 1);
        CHECK_INT(f->exp.n_shots, 2);
        CHECK_INT(f->exp.shots[0].result, 0);
        CHECK_INT(f->exp.shots[1].result, 0);
        /* a switch that has not finished refuses an exposure */
        CHECK_INT(rig_switch(f->rig, 0, true, on_done, f), 0);
        CHECK_INT(rig_expose(f->rig, cams, 1, &(struct cam_request){0}, on_exposed, f), -EBUSY);
        CHECK(strstr(rig_busy_reason(f->rig), "lamp0"));
        run_until(f, f->done + 1);
}

/* Axes that are not homed have no angle in the world frame: the pose says so. */
static void test_unhomed(struct fixture *f)
{
        struct gn_pose p = rig_pose(f->rig);

        CHECK(!gn_pose_has(&p, GN_ROLE_TURNTABLE));
        CHECK(!gn_pose_has(&p, GN_ROLE_CAMERA_ARM));
        home_all(f);
        p = rig_pose(f->rig);
        CHECK(gn_pose_has(&p, GN_ROLE_TURNTABLE));
}

/* A stop is followed until the drive stands still; then the pose is the drive's. */
static void test_stop(struct fixture *f)
{
        struct gn_pose truth, p;
        double deg = 170;
        int want;

        home_all(f);
        want = f->done + 1;
        CHECK_INT(rig_move(f->rig, 2, &deg, false, on_done, f), 0);
        run_for(f, 2.0 / TESTRIG_TIME_SCALE); /* 2 s of emulated motion, of about 6 */
        rig_stop(f->rig, NULL);
        run_until(f, want);
        CHECK_INT(f->result, -ECANCELED);
        CHECK_STR(rig_state(f->rig), "stopping");
        while (strcmp(rig_state(f->rig), "stopping") == 0)
                CHECK(sd_event_run(f->event, 100 * 1000) >= 0);
        CHECK_STR(rig_state(f->rig), "idle");
        truth = sim_pose(f);
        p = rig_pose(f->rig);
        CHECK(gn_pose_equal(&p, &truth, POSE_TOL_DEG));
        CHECK(p.deg[GN_ROLE_CAMERA_ARM] < 150); /* stopped, not left to arrive */
}

/* Moves axis i to deg and runs the loop until done, recording the extremes of the
 * emulated axis of role on the way. Returns the move's result. */
static int move_tracking(struct fixture *f, int i, double deg, int role, double *lo, double *hi)
{
        int want = f->done + 1;
        double end = testrig_now() + 20;

        *lo = INFINITY, *hi = -INFINITY;
        CHECK_INT(rig_move(f->rig, i, &deg, false, on_done, f), 0);
        while (f->done < want) {
                double a = sim_pose(f).deg[role];
                *lo = fmin(*lo, a), *hi = fmax(*hi, a);
                CHECK(testrig_now() < end);
                CHECK(sd_event_run(f->event, 2 * 1000) >= 0);
        }
        return f->result;
}

/* Backlash 3 deg upwards: a move down overshoots by 3 deg and comes back up; a move up
 * goes straight; both end within the deadband. */
static void test_backlash(struct fixture *f)
{
        double lo, hi;

        home_all(f);
        move(f, 1, 100);
        CHECK_INT(move_tracking(f, 1, 50, GN_ROLE_LIGHT_ARM, &lo, &hi), 0);
        CHECK(lo < 50 - 2.5); /* went past, to 47 */
        CHECK_NEAR(sim_pose(f).deg[GN_ROLE_LIGHT_ARM], 50, 0.02);
        CHECK_INT(move_tracking(f, 1, 60, GN_ROLE_LIGHT_ARM, &lo, &hi), 0);
        CHECK(lo > 50 - 0.05 && hi < 60 + 0.05); /* straight up */
        CHECK_NEAR(sim_pose(f).deg[GN_ROLE_LIGHT_ARM], 60, 0.02);
}

/* A drive that stops short is sent again while retries are left; the move then succeeds. */
static void test_retry(struct fixture *f)
{
        struct gn_pose p;

        home_all(f);
        CHECK_INT(sim_emu_inject(f->t.emu, "drives", 2, SIM_FAULT_SHORT), 0);
        move(f, 1, 200);
        CHECK_STR(rig_state(f->rig), "idle");
        p = sim_pose(f);
        CHECK_NEAR(p.deg[GN_ROLE_LIGHT_ARM], 200, 0.02);
}

/* Without retries a short stop is a missed move: the move fails and the rig faults. */
static void test_missed(struct fixture *f)
{
        double deg = 90;

        home_all(f);
        CHECK_INT(sim_emu_inject(f->t.emu, "drives", 3, SIM_FAULT_SHORT), 0);
        CHECK_INT(rig_move(f->rig, 2, &deg, false, on_done, f), 0);
        run_until(f, f->done + 1);
        CHECK(f->result < 0);
        CHECK_STR(rig_state(f->rig), "fault");
        CHECK(strstr(rig_last_error(f->rig), "missed its target 90.000"));
}

static const char abs_yaml[] =
        "rig: test-absolute\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: '@DIR@/drives' }\n"
        "axes:\n"
        "  - { name: tt, role: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      absolute_encoder: true, settle_ms: 10 }\n";

/* An axis with an absolute encoder moves and has an angle without homing. */
static void test_absolute(struct fixture *f)
{
        struct gn_pose p = rig_pose(f->rig);

        CHECK(gn_pose_has(&p, GN_ROLE_TURNTABLE));
        move(f, 0, 45);
        p = rig_pose(f->rig);
        CHECK_NEAR(p.deg[GN_ROLE_TURNTABLE], 45, POSE_TOL_DEG);
}

static void inject_drop(struct fixture *f, const char *camera)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        char line[128], reply[256];
        int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

        CHECK(fd >= 0);
        snprintf(sa.sun_path, sizeof(sa.sun_path), "%s/frames.sock", f->t.dir);
        CHECK(connect(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0);
        snprintf(line, sizeof(line), "{\"cmd\":\"inject\",\"camera\":\"%s\",\"fault\":\"drop\"}\n",
                 camera);
        CHECK(write(fd, line, strlen(line)) == (ssize_t)strlen(line));
        CHECK(read(fd, reply, sizeof(reply)) > 0);
        CHECK(strstr(reply, "\"ok\": true") || strstr(reply, "\"ok\":true"));
        close(fd);
}

/* One camera fails: the other's row is committed and reported as stored. */
static void test_partial(struct fixture *f)
{
        static const int cams[] = {0, 1};
        struct capture *cp = NULL;
        struct ds *d = NULL;
        char dir[] = "/tmp/gonio-test-rig-XXXXXX", path[64], cmd[96];

        home_all(f);
        CHECK(mkdtemp(dir));
        snprintf(path, sizeof(path), "%s/ds", dir);
        CHECK_INT(ds_create(path, "ds", NULL, &d), 0);
        CHECK_INT(capture_new(f->event, f->rig, NULL, NULL, &cp), 0);
        CHECK_INT(capture_attach(cp, d, "ds", 0), 0);
        inject_drop(f, "cam1");
        CHECK_INT(capture_take(cp, cams, 2, &(struct cam_request){0},
                               &(struct capture_tag){.session = "s1"}, on_captured, f),
                  0);
        run_until(f, f->done + 1);
        CHECK_INT(f->res.n_shots, 2);
        CHECK_INT(f->res.shots[0].result, 0);
        CHECK(f->res.shots[0].row.id > 0);
        CHECK_STR(f->res.shots[0].row.session, "s1");
        CHECK_NEAR(f->res.shots[0].row.pose.deg[GN_ROLE_TURNTABLE], sim_pose(f).deg[0],
                   POSE_TOL_DEG);
        CHECK_INT(f->res.shots[1].result, -ETIMEDOUT);
        CHECK_STR(f->res.shots[1].row.camera, "cam1");
        CHECK(strstr(f->res.shots[1].msg, "cam1"));
        CHECK_INT(capture_dataset_count(cp), 1);
        CHECK_INT(capture_in_flight(cp), 0);
        d = capture_detach(cp);
        CHECK_INT(ds_count(d), 1);
        ds_close(d);
        capture_free(cp);
        snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
        CHECK(system(cmd) == 0);
}

int main(int argc, char **argv)
{
        static const struct {
                const char *name;
                void (*fn)(struct fixture *f);
                const char *yaml;
        } cases[] = {
                {"expose", test_expose, rig_yaml},     {"unhomed", test_unhomed, rig_yaml},
                {"stop", test_stop, rig_yaml},         {"partial", test_partial, rig_yaml},
                {"backlash", test_backlash, rig_yaml}, {"retry", test_retry, rig_yaml},
                {"missed", test_missed, rig_yaml},     {"absolute", test_absolute, abs_yaml},
        };
        struct fixture f = {};

        CHECK(argc == 2);
        for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
                if (strcmp(argv[1], cases[i].name) != 0)
                        continue;
                start(&f, cases[i].yaml);
                cases[i].fn(&f);
                stop(&f);
                return 0;
        }
        fprintf(stderr, "unknown case '%s'\n", argv[1]);
        return 1;
}
