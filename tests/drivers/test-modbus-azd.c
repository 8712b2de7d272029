/* test-modbus-azd.c - the "modbus" axis driver with the built-in "azd" profile (Oriental
 * Motor AZ series) against gonio-sim's emulated AZ drives over a real pty, sharing the line
 * with a gonio-default drive: homing, a move with the generic drive's timing, the direct
 * data block and feedback position as the map says, a speed of its own, soft limits, the
 * shortest way round, stop mid-move, and injected faults: no reply, exception, a stall
 * (alarm 0x10 until ALM-RST) and a move that ends short. Also the errors of the profile
 * key in a rig file. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "drivers/axis/axis.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/registry.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-azd\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: '@DIR@/drives',\n"
        "      timeout_ms: 100, retries: 2 }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1, profile: azd, scale: 1000 },\n"
        "      continuous: true, max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3, profile: azd },\n"
        "      limits: [-170, 170], max_speed: 10, accel: 20, settle_ms: 20 }\n"
        "  - { name: light_arm, modbus: { bus: drives, unit: 2 },\n"
        "      limits: [-170, 170], max_speed: 10, accel: 20, settle_ms: 20 }\n";

/* Positions at rest: one step of the arm's default scale (100 steps/deg). */
#define POS_TOL 0.01

struct fixture {
        struct testrig rig;
        struct bus *drives;
        struct axis *tt, *arm, *light;
};

/* Reads the int32 at reg (upper word first) of the axis's unit. Register addresses and bits
 * in this file are the numbers of docs/modbus-profile.md, not the driver's header. */
static int32_t read_i32(struct axis *ax, int reg)
{
        const struct mbax_conf *c = ax->conf->backend.conf;
        uint16_t regs[2];

        CHECK_INT(mbus_read_regs(bus_transport(ax->bus), c->unit, reg, 2, regs), 2);
        return mbax_get_i32(false, regs);
}

static void test_home(struct fixture *f)
{
        testrig_home_all((struct axis *[]){f->tt, f->arm}, 2, POS_TOL);
        CHECK(read_i32(f->arm, 0x007e) & 0x0010 /* HOME-END */);
}

/* 0 -> 150 deg at 10 deg/s, 20 deg/s^2 takes what the gonio-default drive takes (15.5 s of
 * emulated time, 0.775 s real), on the AZ and on the generic drive beside it. The direct
 * data block holds what docs/modbus-profile.md says, its trigger back at 0. */
static void test_move_timing(struct fixture *f)
{
        static const int32_t block[8] = {0, 1, 15000, 1000, 2000, 2000, 1000, 0};
        double expect = axis_move_time(150.0, 10.0, 20.0) / TESTRIG_TIME_SCALE, took[2], t0;
        struct axis *ax[2] = {f->arm, f->light};
        uint16_t regs[16];

        CHECK_INT(axis_home(f->light), 0);
        testrig_wait_in_position(f->light);
        t0 = testrig_now();
        CHECK_INT(axis_move_abs(f->arm, 150.0), 0);
        CHECK_INT(axis_move_abs(f->light, 150.0), 0); /* side by side */
        for (int i = 0; i < 2; i++) {
                testrig_wait_stopped(ax[i], 10.0);
                took[i] = testrig_now() - t0;
                fprintf(stderr, "%s: move 150 deg: %.3f s, model %.3f s\n", ax[i]->conf->name,
                        took[i], expect);
                CHECK(took[i] >= 0.85 * expect);
                CHECK(took[i] <= expect + 3.0);
        }
        for (int i = 0; i < 2; i++) {
                testrig_wait_in_position(ax[i]);
                CHECK_NEAR(ax[i]->state.position_deg, 150.0, POS_TOL);
        }
        CHECK(fabs(took[0] - took[1]) < 0.25 * expect); /* one timing model for both */
        CHECK_INT(read_i32(f->arm, 0x00cc), 15000);
        CHECK_INT(mbus_read_regs(bus_transport(f->arm->bus), 3, 0x0058, 16, regs), 16);
        for (int i = 0; i < 8; i++)
                CHECK_INT(mbax_get_i32(false, regs + 2 * i), block[i]);
}

/* A speed of its own goes into the next direct data operation, in Hz; 150 -> 100 deg. */
static void test_set_speed(struct fixture *f)
{
        double expect = axis_move_time(50.0, 5.0, 20.0) / TESTRIG_TIME_SCALE, took;

        CHECK_INT(axis_set_rates(f->arm, 20.0, 0), -ERANGE);
        CHECK_INT(axis_set_rates(f->arm, 5.0, 0), 0);
        CHECK_INT(axis_move_abs(f->arm, 100.0), 0);
        CHECK_INT(read_i32(f->arm, 0x005e), 500);
        took = testrig_wait_stopped(f->arm, 10.0);
        fprintf(stderr, "move 50 deg at 5 deg/s: %.3f s, model %.3f s\n", took, expect);
        CHECK(took >= 0.85 * expect);
        testrig_wait_in_position(f->arm);
        CHECK_INT(axis_set_rates(f->arm, 0, 0), 0); /* max_speed again: test_stop_mid_move */
}

static void test_soft_limits(struct fixture *f)
{
        testrig_check_limits(f->arm, 100.0, POS_TOL);
}

/* 0 -> 350 goes back 10 deg (feedback -10000 at 1000 steps/deg), 350 -> 10 forward. */
static void test_shortest_way(struct fixture *f)
{
        CHECK_INT(axis_move_abs(f->tt, 350.0), 0);
        testrig_wait_in_position(f->tt);
        CHECK_NEAR(f->tt->state.position_deg, 350.0, 0.002);
        CHECK_INT(read_i32(f->tt, 0x00cc), -10000);
        CHECK_INT(axis_move_abs(f->tt, 10.0), 0);
        testrig_wait_in_position(f->tt);
        CHECK_INT(read_i32(f->tt, 0x00cc), 10000);
}

/* STOP mid-move (100 -> -150 at max_speed again) leaves the arm in between, at rest; the
 * inputs end all off. */
static void test_stop_mid_move(struct fixture *f)
{
        double p;

        CHECK_INT(axis_move_abs(f->arm, -150.0), 0);
        CHECK_INT(read_i32(f->arm, 0x005e), 1000);
        testrig_sleep(0.3);
        CHECK_INT(axis_stop(f->arm), 0);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(!f->arm->state.moving && !f->arm->state.in_position);
        p = f->arm->state.position_deg;
        CHECK(p < 100.0 - 1.0 && p > -140.0);
        CHECK_INT(read_i32(f->arm, 0x007c), 0);
        testrig_sleep(0.1);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK_NEAR(f->arm->state.position_deg, p, POS_TOL);
}

/* No reply: -ETIMEDOUT after the retries; an exception: -EPROTO, not retried. */
static void test_no_reply_and_exception(struct fixture *f)
{
        struct transport_stats s0, s1;
        double p;

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_TIMEOUT), 0);
        CHECK_INT(axis_poll(f->tt), -ETIMEDOUT);
        CHECK_STR_CONTAINS(f->tt->last_error,
                           "read driver output status and alarm (reg 0x007e): Connection timed "
                           "out");
        CHECK_INT(axis_poll(f->arm), 0); /* the other units still answer */

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_NONE), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK_NEAR(f->tt->state.position_deg, 10.0, 0.002);

        CHECK_INT(axis_poll(f->arm), 0);
        p = f->arm->state.position_deg;
        transport_get_stats(bus_transport(f->drives), &s0);
        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 3, SIM_FAULT_EXCEPTION), 0);
        CHECK_INT(axis_move_abs(f->arm, 20.0), -EPROTO);
        CHECK_STR_CONTAINS(f->arm->last_error, "write direct data operation (reg 0x0058): "
                                               "Slave device or server failure");
        transport_get_stats(bus_transport(f->drives), &s1);
        CHECK_INT(s1.retries, s0.retries);
        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 3, SIM_FAULT_NONE), 0);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK_NEAR(f->arm->state.position_deg, p, POS_TOL); /* the refused move never ran */
}

/* A stall mid-move: ALM-A with alarm 0x10 (excessive position deviation); a move during
 * the alarm starts nothing; ALM-RST clears it and the next move runs. */
static void test_stall(struct fixture *f)
{
        double p;

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_STALL), 0);
        CHECK_INT(axis_move_abs(f->tt, 100.0), 0);
        testrig_wait_stopped(f->tt, 10.0);
        CHECK(f->tt->state.fault && !f->tt->state.in_position);
        CHECK_INT(f->tt->state.fault_code, 0x10);
        CHECK_INT(read_i32(f->tt, 0x0080), 0x10);
        p = f->tt->state.position_deg;
        CHECK(p > 10.0 + 1.0 && p < 100.0 - 1.0);

        CHECK_INT(axis_move_abs(f->tt, 100.0), 0);
        testrig_sleep(0.1);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(f->tt->state.fault && !f->tt->state.moving);
        CHECK_NEAR(f->tt->state.position_deg, p, 0.002);

        CHECK_INT(axis_reset(f->tt), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(!f->tt->state.fault);
        CHECK_INT(f->tt->state.fault_code, 0);
        CHECK_INT(axis_move_abs(f->tt, 100.0), 0);
        testrig_wait_in_position(f->tt);
        CHECK_NEAR(f->tt->state.position_deg, 100.0, 0.002);
}

/* A move that ends short without an alarm: MOVE and IN-POS both off. */
static void test_short(struct fixture *f)
{
        double t0;

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_SHORT), 0);
        CHECK_INT(axis_move_abs(f->tt, 150.0), 0);
        testrig_wait_stopped(f->tt, 10.0);
        t0 = testrig_now();
        do {
                CHECK_INT(axis_poll(f->tt), 0);
                CHECK(!f->tt->state.moving && !f->tt->state.in_position && !f->tt->state.fault);
                testrig_sleep(0.01);
        } while (testrig_now() - t0 < 0.3);
        CHECK_NEAR(f->tt->state.position_deg, 147.0, 0.01);
        CHECK_INT(axis_move_abs(f->tt, 150.0), 0);
        testrig_wait_in_position(f->tt);
}

/* Loads a rig whose one axis has backend map `modbus` and extra `profiles`; returns the
 * error text ("" when it loads). */
static const char *load_error(const char *dir, const char *profiles, const char *modbus)
{
        static char err[512];
        struct rig_config *rc = NULL;
        char path[160];
        FILE *fp;

        snprintf(path, sizeof(path), "%s/bad.yaml", dir);
        CHECK((fp = fopen(path, "we")) != NULL);
        fprintf(fp,
                "rig: bad\n%sbuses:\n  - { name: b, type: modbus-rtu, port: /dev/null }\n"
                "axes:\n  - { name: a, modbus: %s }\n",
                profiles, modbus);
        CHECK(fclose(fp) == 0);
        err[0] = '\0';
        if (rigconf_load(path, registry_backends, &rc, err, sizeof(err)) == 0) {
                CHECK(((const struct mbax_conf *)rc->axes[0].backend.conf)->family == &mbax_azd);
                rigconf_free(rc);
        }
        CHECK(unlink(path) == 0);
        return err;
}

static void test_profile_key(const char *dir)
{
        CHECK_STR(load_error(dir, "", "{ bus: b, profile: azd }"), "");
        CHECK_STR_CONTAINS(load_error(dir, "", "{ bus: b, profile: azdx }"),
                           ":5: key 'profile': no register profile named 'azdx' (built in: "
                           "gonio-default, azd");
        CHECK_STR_CONTAINS(load_error(dir, "profiles:\n  - { name: azd, scale: 5 }\n",
                                      "{ bus: b, profile: azd }"),
                           ":7: key 'profile': profile 'azd' is built in");
        CHECK_STR_CONTAINS(load_error(dir, "", "{ bus: b, profile: azd, scale: 0 }"),
                           ":5: key 'scale'");
}

int main(void)
{
        struct fixture f = {};

        testrig_start(&f.rig, rig_yaml);
        test_profile_key(f.rig.dir);
        CHECK_INT(bus_new_sync(testrig_bus(&f.rig, "drives"), &f.drives), 0);
        f.tt = testrig_axis_open(&f.rig, f.drives, 0);
        f.arm = testrig_axis_open(&f.rig, f.drives, 1);
        f.light = testrig_axis_open(&f.rig, f.drives, 2);
        test_home(&f);
        test_move_timing(&f);
        test_set_speed(&f);
        test_soft_limits(&f);
        test_shortest_way(&f);
        test_stop_mid_move(&f);
        test_no_reply_and_exception(&f);
        test_stall(&f);
        test_short(&f);
        f.tt = axis_free(f.tt);
        f.arm = axis_free(f.arm);
        f.light = axis_free(f.light);
        f.drives = bus_free(f.drives);
        testrig_stop(&f.rig);
        return 0;
}
