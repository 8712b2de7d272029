/* test-frame-server.c - gonio-sim's frame server through the sim camera backend
 * (cam_new/cam_capture on a bus_new_sync bus) and through a raw socket client: frames
 * follow the turntable and the lamps of the emulated rig, malformed requests get an
 * error line on a connection that keeps working, camera and Modbus faults injected
 * over the socket have their effect, a frame records the rig's state at the start and
 * end of its exposure, and the render log repeats every frame's header. */
#include <errno.h>
#include <math.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <jansson.h>

#include "common/cleanup.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/camera.h"
#include "sim/frame_server.h"
#include "tests/sim/simtest.h"
#include "tests/test-frame.h"

#define TIME_SCALE 20.0

struct rig {
        char dir[64];
        struct rig_config *rc;
        struct sim_scene *scene;
        struct sim_emu *emu;
        struct sim_frame_server *fs;
        modbus_t *drives, *relays;
        struct bus *bus;
        struct cam *cam;
};

static void rig_up(struct rig *t)
{
        char err[512] = "", log[128];

        t->rc = simtest_rig(t->dir, false);
        snprintf(log, sizeof log, "%s/render.log", t->dir);
        CHECK(sim_scene_new(t->rc, &t->scene, err, sizeof err) == 0);
        CHECK(sim_emu_new(t->rc, TIME_SCALE, &t->emu) == 0);
        CHECK(sim_frame_server_new(t->rc, t->scene, t->emu,
                                   &(struct sim_fs_options){TIME_SCALE, log}, &t->fs) == 0);
        t->drives = simtest_modbus(t->dir, "drives");
        t->relays = simtest_modbus(t->dir, "relays");
        CHECK(modbus_set_slave(t->relays, 10) == 0);
        CHECK(bus_new_sync(rigconf_bus(t->rc, "frames"), &t->bus) == 0);
        CHECK(cam_new(&t->rc->cameras[0], t->bus, &t->cam) == 0);
        CHECK(cam_open(t->cam) == 0);
        /* Home every axis: light arm and camera arm at 0 light the camera's side. */
        for (int unit = 1; unit <= 3; unit++)
                CHECK(simtest_command(t->drives, unit, 0.0, SIMTEST_CMD_HOME) == 1);
        for (int unit = 1; unit <= 3; unit++)
                simtest_wait_status(t->drives, unit, SIMTEST_ST_HOMED | SIMTEST_ST_INPOS,
                                    SIMTEST_ST_HOMED | SIMTEST_ST_INPOS, 5.0);
}

static void rig_down(struct rig *t)
{
        cam_free(t->cam);
        bus_free(t->bus);
        modbus_close(t->drives);
        modbus_free(t->drives);
        modbus_close(t->relays);
        modbus_free(t->relays);
        sim_frame_server_free(t->fs);
        sim_emu_free(t->emu);
        sim_scene_free(t->scene);
        rigconf_free(t->rc);
        simtest_rmdir(t->dir);
}

static void capture(struct rig *t, struct gn_frame *f)
{
        CHECK(cam_capture(t->cam, NULL, f) == 0);
        CHECK(f->width == 160 && f->height == 120 && f->bits == 8);
        CHECK(f->exposure_us == 20000);
}

/* Frames follow the lamps and the turntable; a second frame in the same state differs
 * only by sensor noise, the baseline for "changed". */
static void test_frames_follow_rig(struct rig *t)
{
        struct gn_frame lit = {0}, again = {0}, dark = {0}, turned = {0};

        CHECK(modbus_write_bit(t->relays, 0, 1) == 1);
        capture(t, &lit);
        capture(t, &again);
        CHECK(again.seq == lit.seq + 1);
        double noise = test_frame_mean_abs_diff(&lit, &again);
        CHECK(test_frame_mean(&lit) > 5.0);

        CHECK(modbus_write_bit(t->relays, 0, 0) == 1);
        capture(t, &dark);
        CHECK(test_frame_mean(&dark) < 0.5 * test_frame_mean(&lit));

        CHECK(modbus_write_bit(t->relays, 0, 1) == 1);
        CHECK(simtest_command(t->drives, 1, 90.0, SIMTEST_CMD_MOVE) == 1);
        simtest_wait_status(t->drives, 1, SIMTEST_ST_MOVING | SIMTEST_ST_INPOS, SIMTEST_ST_INPOS,
                            5.0);
        capture(t, &turned);
        fprintf(stderr, "mean lit %.2f dark %.2f; diff noise %.3f turned %.3f\n",
                test_frame_mean(&lit), test_frame_mean(&dark), noise,
                test_frame_mean_abs_diff(&lit, &turned));
        CHECK(test_frame_mean_abs_diff(&lit, &turned) > 2.0 * noise + 0.5);

        gn_frame_free_data(&lit);
        gn_frame_free_data(&again);
        gn_frame_free_data(&dark);
        gn_frame_free_data(&turned);
}

static int raw_connect(const char *path)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        struct timeval tv = {.tv_sec = 10};

        int fd = socket(AF_UNIX, SOCK_STREAM, 0);
        CHECK(fd >= 0);
        snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
        CHECK(connect(fd, (struct sockaddr *)&sa, sizeof sa) == 0);
        CHECK(setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv) == 0);
        return fd;
}

/* Sends line (with its newline) and parses the one reply line. */
static json_t *raw_request(int fd, const char *line)
{
        char buf[SIM_FS_LINE_MAX * 4];
        size_t n = 0;
        json_error_t err;

        CHECK(send(fd, line, strlen(line), MSG_NOSIGNAL) == (ssize_t)strlen(line));
        while (n == 0 || buf[n - 1] != '\n') {
                CHECK(n < sizeof buf);
                ssize_t k = recv(fd, buf + n, 1, 0); /* one byte: never past the line */
                CHECK(k == 1);
                n += 1;
        }
        json_t *o = json_loadb(buf, n, 0, &err);
        CHECK(o);
        return o;
}

static void inject(const char *path, const char *line)
{
        int fd = raw_connect(path);
        json_t *o = raw_request(fd, line);
        CHECK(json_is_true(json_object_get(o, "ok")));
        json_decref(o);
        close(fd);
}

/* Faults of the camera injected over the socket: a dropped frame is a timeout; one
 * disconnect is bridged by the backend's reconnect, two are not. */
static void test_camera_faults(struct rig *t, const char *path)
{
        struct gn_frame f = {0};

        inject(path, "{\"cmd\":\"inject\",\"camera\":\"cam0\",\"fault\":\"drop\"}\n");
        CHECK(cam_capture(t->cam, NULL, &f) == -ETIMEDOUT);
        capture(t, &f);
        gn_frame_free_data(&f);

        inject(path, "{\"cmd\":\"inject\",\"camera\":\"cam0\",\"fault\":\"disconnect\"}\n");
        capture(t, &f);
        gn_frame_free_data(&f);

        inject(path, "{\"cmd\":\"inject\",\"camera\":\"cam0\",\"fault\":\"disconnect\","
                     "\"count\":2}\n");
        CHECK(cam_capture(t->cam, NULL, &f) == -ECONNRESET);
        capture(t, &f);
        gn_frame_free_data(&f);
}

static void expect_error(int fd, const char *line, const char *err)
{
        json_t *o = raw_request(fd, line);

        CHECK(json_is_false(json_object_get(o, "ok")));
        CHECK(strcmp(json_string_value(json_object_get(o, "error")), err) == 0);
        CHECK(json_string_value(json_object_get(o, "message")));
        json_decref(o);
}

/* Malformed requests each get an error line, and the same connection keeps serving. */
static void test_malformed(const char *path)
{
        static char longline[SIM_FS_LINE_MAX + 100];
        int fd = raw_connect(path);

        expect_error(fd, "{bad json\n", "EINVAL");
        expect_error(fd, "[1,2]\n", "EINVAL");
        expect_error(fd, "{\"cmd\":\"fly\"}\n", "EINVAL");
        expect_error(fd, "{\"cmd\":\"render\",\"camera\":\"nope\"}\n", "ENOENT");
        expect_error(fd, "{\"cmd\":\"render\",\"camera\":\"cam0\",\"bits\":12}\n", "EINVAL");
        expect_error(fd, "{\"cmd\":\"render\",\"camera\":\"cam0\",\"truth\":[\"x\"]}\n", "EINVAL");
        expect_error(fd, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":9,\"fault\":\"crc\"}\n",
                     "ENOENT");
        memset(longline, 'x', sizeof longline - 2);
        longline[sizeof longline - 2] = '\n';
        expect_error(fd, longline, "EMSGSIZE");

        json_t *o = raw_request(fd, "{\"cmd\":\"state\"}\n");
        CHECK(json_is_true(json_object_get(o, "ok")));
        json_t *lamps = json_object_get(json_object_get(o, "state"), "lamps");
        CHECK(json_array_size(lamps) == 2 && json_is_true(json_array_get(lamps, 0)));
        json_decref(o);

        o = raw_request(fd, "{\"cmd\":\"geometry\"}\n");
        json_t *cam = json_array_get(json_object_get(o, "cameras"), 0);
        CHECK(json_integer_value(json_object_get(cam, "width")) == 160);
        CHECK(json_array_size(json_object_get(cam, "R")) == 9);
        CHECK(json_array_size(json_object_get(o, "lamps")) == 2);
        CHECK(json_is_object(json_object_get(o, "laser")));
        json_decref(o);
        close(fd);
}

/* Reads and drops n bytes of fd. */
static void raw_skip(int fd, size_t n)
{
        char buf[4096];

        while (n > 0) {
                ssize_t k = recv(fd, buf, MIN(n, sizeof buf), 0);
                CHECK(k > 0);
                n -= (size_t)k;
        }
}

static double turntable(json_t *header, const char *key)
{
        json_t *v = json_object_get(json_object_get(header, key), "turntable");

        CHECK(json_is_number(v));
        return json_number_value(v);
}

/* The last line of the render log, parsed. */
static json_t *last_logged(const char *dir, int *lines)
{
        char path[128], line[4096], last[4096] = "";
        json_error_t err;

        snprintf(path, sizeof path, "%s/render.log", dir);
        FILE *f = fopen(path, "r");
        CHECK(f);
        for (*lines = 0; fgets(line, sizeof line, f); (*lines)++)
                memcpy(last, line, sizeof last);
        fclose(f);
        json_t *o = json_loads(last, 0, &err);
        CHECK(o);
        return o;
}

/* A frame exposed while the turntable moves: the header's state is the start of the
 * exposure, state_mid (the state rendered) its middle and state_end its end, the exposure lasts
 * exposure_us / time scale of wall time, and the render log holds one line per frame with the
 * header's values. */
static void test_exposure(struct rig *t, const char *path, int frames_before)
{
        int fd = raw_connect(path), lines;

        /* From 90 to -180 deg: 3.5 s of emulated time, 175 ms of real time. */
        CHECK(simtest_command(t->drives, 1, -180.0, SIMTEST_CMD_MOVE) == 1);
        double t0 = simtest_now();
        json_t *h = raw_request(fd, "{\"cmd\":\"render\",\"camera\":\"cam0\","
                                    "\"exposure_us\":400000}\n");
        double took = simtest_now() - t0;
        CHECK(json_is_true(json_object_get(h, "ok")));
        raw_skip(fd, (size_t)json_integer_value(json_object_get(h, "bytes")));
        double a = turntable(h, "state"), m = turntable(h, "state_mid"),
               b = turntable(h, "state_end");
        double moved = remainder(a - b, 360.0); /* backwards, wrapped to [0, 360) */
        fprintf(stderr, "exposure: turntable %.2f -> %.2f in %.3f s\n", a, b, took);
        CHECK(took >= 0.4 / TIME_SCALE);
        /* Moving all the exposure long (unless the machine is very slow), and never faster
         * than max_speed over the request's time. */
        CHECK(moved > 5.0);
        CHECK(moved <= 90.0 * took * TIME_SCALE + 1e-6);
        CHECK(remainder(a - m, 360.0) > 0 && remainder(m - b, 360.0) > 0); /* on the way */

        json_t *l = last_logged(t->dir, &lines);
        CHECK(lines == frames_before + 1);
        static const char *const keys[] = {"seq",  "camera", "timestamp_ns", "exposure_us",
                                           "gain", "state",  "state_mid",    "state_end"};
        for (size_t i = 0; i < ELEMENTSOF(keys); i++)
                CHECK(json_equal(json_object_get(l, keys[i]), json_object_get(h, keys[i])));
        CHECK(json_integer_value(json_object_get(l, "exposure_us")) == 400000);
        json_decref(l);
        json_decref(h);
        close(fd);
        simtest_wait_status(t->drives, 1, SIMTEST_ST_MOVING | SIMTEST_ST_INPOS, SIMTEST_ST_INPOS,
                            5.0);
}

/* Modbus faults injected over the frame socket reach the emulated drive. */
static void test_modbus_fault(struct rig *t, const char *path)
{
        uint16_t v;

        inject(path,
               "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":2,\"fault\":\"exception\"}\n");
        CHECK(modbus_set_slave(t->drives, 2) == 0);
        CHECK(modbus_read_registers(t->drives, SIMTEST_R_STATUS, 1, &v) == -1 &&
              errno == EMBXSFAIL);
        inject(path, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":2,\"fault\":\"none\"}\n");
        CHECK(simtest_reg(t->drives, 2, SIMTEST_R_STATUS) & 1);

        /* A short stop: the move ends, not in position, no fault. */
        inject(path, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":2,\"fault\":\"short\"}\n");
        CHECK(simtest_command(t->drives, 2, 30.0, SIMTEST_CMD_MOVE) == 1);
        simtest_wait_status(t->drives, 2, SIMTEST_ST_MOVING, 0, 5.0);
        usleep(20000); /* past settle_ms (80 ms emulated) */
        CHECK(!(simtest_reg(t->drives, 2, SIMTEST_R_STATUS) &
                (SIMTEST_ST_INPOS | SIMTEST_ST_FAULT)));
}

int main(void)
{
        struct rig t = {0};
        char path[300];

        rig_up(&t);
        snprintf(path, sizeof path, "%s/frames.sock", t.dir);
        test_frames_follow_rig(&t);
        test_camera_faults(&t, path);
        test_malformed(path);
        test_modbus_fault(&t, path);
        test_exposure(&t, path, 7); /* frames rendered above; failed ones are not logged */
        rig_down(&t);
        CHECK(access(path, F_OK) < 0 && errno == ENOENT);
        return 0;
}
