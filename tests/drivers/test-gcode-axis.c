/* test-gcode-axis.c - the "gcode" axis and "gcode-laser" switch drivers against gonio-sim's
 * G-code controllers over real ptys: a Horus/Ciclop board (turntable + two lasers on one
 * line: a move answered at its end, polled without blocking the line; lasers refused while
 * it runs; G50 as home; the shortest way round; stop = reset + unlock) and a GRBL 1.1 board
 * (locked until $H; move answered at once, done by status; stop = feed hold + reset, no
 * alarm), and the injected faults: no reply, late reply, error replies. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/axis/axis.h"
#include "drivers/axis/gcode/link.h"
#include "drivers/switch/switch.h"
#include "drivers/transport/transport.h"
#include "sim/gcode_emu.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-gcode\n"
        "buses:\n"
        "  - { name: ciclop, type: serial, port: '@DIR@/ciclop', timeout_ms: 200 }\n"
        "  - { name: cnc, type: serial, port: '@DIR@/cnc', timeout_ms: 200 }\n"
        "axes:\n"
        "  - { name: turntable, continuous: true, max_speed: 30, accel: 60,\n"
        "      gcode: { bus: ciclop, flavor: horus, axis: X, steps_per_deg: 100 } }\n"
        "  - { name: camera_arm, limits: [-170, 170], max_speed: 30, accel: 60,\n"
        "      gcode: { bus: cnc, flavor: grbl, axis: X, steps_per_deg: 100 } }\n"
        "lamps:\n"
        "  - { name: right, elevation: 0, gcode-laser: { bus: ciclop, tool: 2 } }\n"
        "laser: { name: left, gcode-laser: { bus: ciclop, tool: 1 } }\n";

#define POS_TOL 0.006 /* half a step of 1/100 deg, and the 3 decimals of the reports */

struct fixture {
        struct testrig rig;
        struct bus *ciclop, *cnc;
        struct axis *tt, *arm;
        struct sw *laser, *right;
};

static bool sim_laser(struct fixture *f)
{
        struct gn_pose st;

        sim_emu_snapshot(f->rig.emu, &st);
        return st.lasers;
}

/* Polls until the axis has stopped; returns the seconds it took. */
static double wait_stopped(struct axis *ax, double limit_s)
{
        double t0 = testrig_now();

        do {
                CHECK_INT(axis_poll(ax), 0);
                if (!ax->state.moving)
                        return testrig_now() - t0;
                testrig_sleep(0.005);
        } while (testrig_now() - t0 < limit_s);
        fprintf(stderr, "axis '%s' still moving after %.1f s\n", ax->conf->name, limit_s);
        exit(1);
}

static void open_all(struct fixture *f)
{
        testrig_start(&f->rig, rig_yaml);
        CHECK_INT(bus_new_sync(testrig_bus(&f->rig, "ciclop"), &f->ciclop), 0);
        CHECK_INT(bus_new_sync(testrig_bus(&f->rig, "cnc"), &f->cnc), 0);
        CHECK_INT(axis_new(&f->rig.rc->axes[0], f->ciclop, &f->tt), 0);
        CHECK_INT(axis_new(&f->rig.rc->axes[1], f->cnc, &f->arm), 0);
        CHECK_INT(sw_new(&f->rig.rc->lasers[0], f->ciclop, &f->laser), 0);
        CHECK_INT(sw_new(&f->rig.rc->lamps[0], f->ciclop, &f->right), 0);
        CHECK_INT(axis_open(f->tt), 0);
        CHECK_INT(axis_open(f->arm), 0);
        CHECK_INT(sw_open(f->laser), 0);
        CHECK_INT(sw_open(f->right), 0);
}

static void close_all(struct fixture *f)
{
        sw_free(f->right);
        sw_free(f->laser);
        axis_free(f->tt);
        axis_free(f->arm);
        bus_free(f->ciclop);
        bus_free(f->cnc);
        testrig_stop(&f->rig);
}

/* Horus: home is G50; a move's "ok" comes at its end, read by the polls. */
static void test_horus_move(struct fixture *f)
{
        double expect = axis_move_time(90.0, 30.0, 60.0) / TESTRIG_TIME_SCALE, took;
        bool on;

        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(!f->tt->state.homed && f->tt->state.in_position);
        CHECK_INT(axis_home(f->tt), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(f->tt->state.homed && f->tt->state.enabled);
        CHECK_NEAR(f->tt->state.position_deg, 0.0, POS_TOL);

        CHECK_INT(axis_move_abs(f->tt, 90.0), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(f->tt->state.moving && !f->tt->state.in_position);
        /* the line is the board's until the move ends: the laser must wait */
        CHECK_INT(sw_set(f->laser, true), -EBUSY);
        CHECK_STR_CONTAINS(f->laser->last_error, "only when its motion has ended");
        took = wait_stopped(f->tt, 5.0);
        CHECK(took >= 0.8 * expect - 0.05 && took <= expect + 1.0);
        CHECK(f->tt->state.in_position && !f->tt->state.fault);
        CHECK_NEAR(f->tt->state.position_deg, 90.0, POS_TOL);

        CHECK_INT(sw_set(f->laser, true), 0);
        CHECK(sim_laser(f));
        CHECK_INT(sw_get(f->laser, &on), 0);
        CHECK(on);
        CHECK_INT(sw_get(f->right, &on), 0);
        CHECK(!on);
        CHECK_INT(sw_set(f->laser, false), 0);
        CHECK(!sim_laser(f));

        /* 90 -> 350 turns back 100 deg, not forward 260 */
        CHECK_INT(axis_move_abs(f->tt, 350.0), 0);
        took = wait_stopped(f->tt, 5.0);
        CHECK(took < axis_move_time(200.0, 30.0, 60.0) / TESTRIG_TIME_SCALE);
        CHECK_NEAR(f->tt->state.position_deg, 350.0, POS_TOL);
}

/* Horus stop: Ctrl-X kills the move (alarm), $X unlocks; the step count and the origin
 * stay; the reset switched the lasers off. */
static void test_horus_stop(struct fixture *f)
{
        bool on;

        CHECK_INT(sw_set(f->right, true), 0);
        CHECK_INT(axis_move_abs(f->tt, 190.0), 0); /* back 160 deg: 0.29 s */
        testrig_sleep(0.05);
        CHECK_INT(axis_stop(f->tt), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(!f->tt->state.moving && !f->tt->state.in_position && !f->tt->state.fault);
        CHECK(f->tt->state.homed);
        double stopped = f->tt->state.position_deg;
        CHECK(stopped < 350.0 - 1.0 && stopped > 190.0 + 1.0); /* part of the way */
        testrig_sleep(0.1);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK_NEAR(f->tt->state.position_deg, stopped, POS_TOL);
        CHECK_INT(sw_get(f->right, &on), 0);
        CHECK(!on);
        CHECK_INT(axis_move_abs(f->tt, 0.0), 0); /* unlocked: moves again */
        wait_stopped(f->tt, 5.0);
        CHECK(f->tt->state.in_position);
        CHECK_INT(axis_stop(f->tt), 0); /* at rest: no alarm, still in position */
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(f->tt->state.in_position && !f->tt->state.fault);
        CHECK_NEAR(f->tt->state.position_deg, 0.0, POS_TOL);
}

/* GRBL: locked until homed; a move is answered at once and done by status; stop is a
 * feed hold then a reset, which keeps position and homing. */
static void test_grbl(struct fixture *f)
{
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(!f->arm->state.homed && !f->arm->state.fault);
        CHECK_INT(axis_move_abs(f->arm, 10.0), -EPROTO);
        CHECK_STR_CONTAINS(f->arm->last_error, "error:9");
        CHECK_INT(axis_home(f->arm), 0); /* ~78 deg to the switch: 0.15 s */
        testrig_sleep(0.03);
        CHECK_INT(axis_stop(f->arm), 0); /* a hold does not stop homing: the reset does */
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(!f->arm->state.moving && !f->arm->state.homed && !f->arm->state.in_position);
        CHECK_INT(axis_home(f->arm), 0);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(f->arm->state.moving);
        wait_stopped(f->arm, 10.0);
        CHECK(f->arm->state.homed && f->arm->state.in_position);
        CHECK_NEAR(f->arm->state.position_deg, 0.0, POS_TOL);

        CHECK_INT(axis_move_abs(f->arm, -45.0), 0);
        wait_stopped(f->arm, 5.0);
        CHECK(f->arm->state.in_position);
        CHECK_NEAR(f->arm->state.position_deg, -45.0, POS_TOL);

        CHECK_INT(axis_move_abs(f->arm, 160.0), 0);
        testrig_sleep(0.05);
        CHECK_INT(axis_stop(f->arm), 0);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(!f->arm->state.moving && !f->arm->state.fault && f->arm->state.homed);
        CHECK(!f->arm->state.in_position); /* stopped short of its target */
        CHECK(f->arm->state.position_deg > -44.0 && f->arm->state.position_deg < 159.0);
        CHECK_INT(axis_move_abs(f->arm, 20.0), 0); /* no alarm: moves at once */
        wait_stopped(f->arm, 5.0);
        CHECK(f->arm->state.in_position);
        CHECK_NEAR(f->arm->state.position_deg, 20.0, POS_TOL);
        CHECK_INT(axis_stop(f->arm), 0); /* at rest: still in position, still homed */
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(f->arm->state.in_position && f->arm->state.homed);
        CHECK_NEAR(f->arm->state.position_deg, 20.0, POS_TOL);
}

/* No reply, a late reply: the poll times out naming what it waited for; once the board
 * answers again the next poll resets it and goes on, still homed (unhomed after a reopen). Error
 * replies fail the command with the board's words. */
static void test_faults(struct fixture *f)
{
        CHECK_INT(sim_emu_inject(f->rig.emu, "ciclop", 0, SIM_FAULT_TIMEOUT), 0);
        CHECK_INT(axis_poll(f->tt), -ETIMEDOUT);
        CHECK_STR_CONTAINS(f->tt->last_error, "no status report within 200 ms");
        CHECK_INT(sim_emu_inject(f->rig.emu, "ciclop", 0, SIM_FAULT_LATE), 0);
        CHECK_INT(axis_poll(f->tt), -ETIMEDOUT);
        CHECK_INT(sim_emu_inject(f->rig.emu, "ciclop", 0, SIM_FAULT_NONE), 0);
        testrig_sleep(2.0 * SIM_GCODE_LATE_MS / 1000.0); /* let the late bytes arrive */
        CHECK_INT(axis_poll(f->tt), 0); /* a soft reset on the open line: still homed */
        CHECK(f->tt->state.homed && !f->tt->state.fault);
        transport_close(bus_transport(f->ciclop)); /* a reopened port may have rebooted it */
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(!f->tt->state.homed && !f->tt->state.fault);

        CHECK_INT(sim_emu_inject(f->rig.emu, "ciclop", 0, SIM_FAULT_ERROR), 0);
        CHECK_INT(sw_set(f->laser, true), -EPROTO);
        CHECK_STR_CONTAINS(f->laser->last_error, "'M71 T1': error: Unsupported command");
        CHECK(!sim_laser(f));
        CHECK_INT(sim_emu_inject(f->rig.emu, "cnc", 0, SIM_FAULT_ERROR), 0);
        CHECK_INT(axis_move_abs(f->arm, 30.0), -EPROTO);
        CHECK_STR_CONTAINS(f->arm->last_error, "error:20");
        CHECK_INT(sim_emu_inject(f->rig.emu, "cnc", 0, SIM_FAULT_NONE), 0);
        CHECK_INT(sim_emu_inject(f->rig.emu, "ciclop", 0, SIM_FAULT_NONE), 0);
        CHECK_INT(sw_set(f->laser, true), 0);
        CHECK(sim_laser(f));
}

int main(void)
{
        struct fixture f = {0};

        open_all(&f);
        test_horus_move(&f);
        test_horus_stop(&f);
        test_grbl(&f);
        test_faults(&f);
        close_all(&f);
        return 0;
}
