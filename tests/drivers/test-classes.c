/* test-classes.c - the pure parts of the device classes: soft limits and wrap-around,
 * the trapezoidal move time, the backend registry, option tables, the errno mapping. */
#include <errno.h>
#include <modbus/modbus.h>

#include "drivers/axis/axis.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/camera.h"
#include "drivers/registry.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"
#include "tests/test.h"

static void test_limits(void)
{
        struct rig_axis_conf arm = {.name = "arm", .min_deg = -170, .max_deg = 170};
        struct rig_axis_conf tt = {.name = "tt", .continuous = true};
        struct axis a = {.conf = &arm}, t = {.conf = &tt};
        double d;

        d = 170.0;
        CHECK_INT(axis_check_target(&a, &d), 0);
        CHECK_NEAR(d, 170.0, 0);
        d = -170.5;
        CHECK_INT(axis_check_target(&a, &d), -ERANGE);
        d = NAN;
        CHECK_INT(axis_check_target(&a, &d), -ERANGE);
        d = 725.0;
        CHECK_INT(axis_check_target(&t, &d), 0);
        CHECK_NEAR(d, 5.0, 1e-9);
        d = -90.0;
        CHECK_INT(axis_check_target(&t, &d), 0);
        CHECK_NEAR(d, 270.0, 1e-9);
        d = INFINITY;
        CHECK_INT(axis_check_target(&t, &d), -ERANGE);
}

static void test_move_time(void)
{
        /* 90 deg at 90 deg/s, 180 deg/s^2: 0.5 s ramps cover 45 deg, 45 deg cruise 0.5 s */
        CHECK_NEAR(axis_move_time(90, 90, 180), 1.5, 1e-12);
        CHECK_NEAR(axis_move_time(-90, 90, 180), 1.5, 1e-12);
        /* 20 deg never reaches full speed: 2 * sqrt(20 / 180) */
        CHECK_NEAR(axis_move_time(20, 90, 180), 2.0 * sqrt(20.0 / 180.0), 1e-12);
        /* exactly at the triangle/trapezoid boundary both formulas agree: 45 deg -> 1 s */
        CHECK_NEAR(axis_move_time(45, 90, 180), 1.0, 1e-12);
        CHECK_NEAR(axis_move_time(45 - 1e-9, 90, 180), 1.0, 1e-6);
        CHECK_NEAR(axis_move_time(0, 90, 180), 0.0, 0);
        CHECK_NEAR(axis_move_time(30, 10, 0), 3.0, 1e-12); /* no accel: constant speed */
        CHECK(isinf(axis_move_time(30, 0, 10)));
}

/* The travel of a move, decided once above the backends: the shortest way round (a tie
 * going up) unless the rig file fixes the direction; a limited axis goes straight. */
static void test_travel(void)
{
        struct rig_axis_conf c = {.continuous = true};

        CHECK_NEAR(axis_travel(&c, 350, 10), 20, 1e-12); /* up across 360 */
        CHECK_NEAR(axis_travel(&c, 10, 350), -20, 1e-12);
        CHECK_NEAR(axis_travel(&c, 370, 5), -5, 1e-12);
        CHECK_NEAR(axis_travel(&c, 0, 180), 180, 1e-12); /* a tie goes up */
        CHECK_NEAR(axis_travel(&c, 180, 0), 180, 1e-12);
        CHECK_NEAR(axis_travel(&c, 90, 90), 0, 1e-12);
        c.direction = 1; /* only up */
        CHECK_NEAR(axis_travel(&c, 10, 350), 340, 1e-12);
        CHECK_NEAR(axis_travel(&c, 350, 10), 20, 1e-12);
        c.direction = -1; /* only down */
        CHECK_NEAR(axis_travel(&c, 350, 10), -340, 1e-12);
        CHECK_NEAR(axis_travel(&c, 10, 350), -20, 1e-12);
        c = (struct rig_axis_conf){.continuous = false, .min_deg = -170, .max_deg = 170};
        CHECK_NEAR(axis_travel(&c, 160, -160), -320, 1e-12); /* no wrap on a limited axis */
}

static void test_registry(void)
{
        const struct axis_ops *ax = registry_axis("modbus");
        const struct sw_ops *sw = registry_switch("modbus-coil");

        CHECK(ax && strcmp(ax->name, "modbus") == 0);
        CHECK(ax->open && ax->poll && ax->move_abs && ax->stop && ax->home);
        CHECK(opt_find(ax->opts, ax->n_opts, OPT_POSITION) != NULL);
        CHECK(opt_find(ax->opts, ax->n_opts, OPT_EXPOSURE) == NULL);
        CHECK(sw && strcmp(sw->name, "modbus-coil") == 0);
        CHECK(opt_find(sw->opts, sw->n_opts, OPT_STATE)->flags == (OPT_GET | OPT_SET));
        CHECK(registry_axis("gcode-nonexistent") == NULL);
        CHECK(registry_switch(NULL) == NULL);
        CHECK(registry_camera("no-such-camera") == NULL);
        CHECK(registry_camera("sim") && registry_camera("sim")->capture);
        CHECK(strcmp(opt_key_name(OPT_EXPOSURE), "exposure") == 0);
        CHECK(strcmp(opt_key_name((enum opt_key)99), "unknown") == 0);
}

static void test_new_unknown(void)
{
        struct rig_bus_conf bc = {.name = "b", .type = RIG_BUS_SIM, .port = "/x/frames.sock"};
        struct rig_axis_conf ac = {.name = "a", .backend.name = "nope"};
        struct bus *b = NULL;
        struct axis *ax = NULL;

        CHECK_INT(bus_new_sync(&bc, &b), 0);
        CHECK_INT(axis_new(&ac, b, &ax), -ENOENT);
        CHECK(ax == NULL);
        strcpy(ac.backend.name, "modbus");
        CHECK_INT(axis_new(&ac, b, &ax), 0);
        CHECK_INT(axis_poll(ax), -ENOTCONN); /* not opened */
        /* a conf built by hand has no backend settings (unit, profile): open refuses it */
        CHECK_INT(axis_open(ax), -EINVAL);
        CHECK_STR_CONTAINS(ax->last_error, "no Modbus settings");
        CHECK(axis_free(ax) == NULL);
        CHECK(bus_free(b) == NULL);
}

/* The camera's option table is the one source of its control ranges. */
static void test_cam_check_request(void)
{
        struct rig_bus_conf bc = {.name = "frames", .type = RIG_BUS_SIM, .port = "/x/f.sock"};
        struct rig_camera_conf cc = {.name = "cam1", .backend.name = "sim"};
        struct bus *b = NULL;
        struct cam *c = NULL;
        char msg[128];

        CHECK_INT(bus_new_sync(&bc, &b), 0);
        CHECK_INT(cam_new(&cc, b, &c), 0);
        CHECK_INT(cam_check_request(c, NULL, msg, sizeof(msg)), 0);
        CHECK_STR(msg, "");
        CHECK_INT(cam_check_request(c, &(struct cam_request){.gain = 100}, msg, sizeof(msg)),
                  -ERANGE);
        CHECK_STR(msg, "gain 100 outside [0.1, 64]");
        CHECK_INT(cam_check_request(c, &(struct cam_request){.gain = 64, .exposure_us = 10000000},
                                    msg, sizeof(msg)),
                  0);
        CHECK_INT(cam_check_request(c, &(struct cam_request){.exposure_us = 10000001}, msg,
                                    sizeof(msg)),
                  -ERANGE);
        CHECK_STR(msg, "exposure 10000001 outside [1, 10000000]");
        CHECK_INT(cam_check_request(c, &(struct cam_request){.bits = 12}, NULL, 0), -EINVAL);
        CHECK_INT(cam_capture(c, &(struct cam_request){.gain = 0.05}, NULL), -ERANGE);
        CHECK_STR(c->last_error,
                  "camera 'cam1' [sim@f.sock]: Failed to capture: gain 0.05 outside [0.1, 64]");
        CHECK_INT(cam_stream_start(c, &(struct cam_request){.gain = 65}), -ERANGE);
        CHECK(cam_free(c) == NULL);
        CHECK(bus_free(b) == NULL);
}

static void test_errno_map(void)
{
        CHECK_INT(mbus_errno(ETIMEDOUT), -ETIMEDOUT);
        CHECK_INT(mbus_errno(EMBXSFAIL), -EPROTO);
        CHECK_INT(mbus_errno(EMBXILVAL), -EPROTO);
        CHECK_INT(mbus_errno(EMBBADCRC), -EPROTO);
        CHECK_INT(mbus_errno(EMBBADDATA), -EPROTO);
        CHECK_INT(mbus_errno(ECONNRESET), -EIO);
        CHECK_INT(mbus_errno(-EPIPE), -EIO);
}

int main(void)
{
        test_limits();
        test_move_time();
        test_travel();
        test_registry();
        test_new_unknown();
        test_errno_map();
        test_cam_check_request();
        return 0;
}
