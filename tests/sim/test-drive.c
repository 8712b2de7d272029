/* test-drive.c - the protocol-free drive model (sim/drive.c) on an explicit clock:
 * homing sets the reference, a move settles into position, stop, a stall latches its
 * fault until reset, and a short stop ends before the target with neither in-position
 * nor a fault. */
#include <errno.h>
#include <math.h>

#include "sim/drive.h"
#include "tests/sim/simtest.h"

static const struct rig_axis_conf axis = {
        .name = "arm",
        .role = -1,
        .min_deg = -170,
        .max_deg = 170,
        .max_speed = 30,
        .accel = 60,
        .settle_ms = 100,
};

/* A moment just after the drive's current motion has ended and settled. */
static double settled(const struct sim_drive *d)
{
        return motion_end_time(&d->mo) + d->settle_s + 1e-6;
}

static void test_home_and_move(void)
{
        struct sim_drive d;

        sim_drive_init(&d, &axis);
        CHECK(!sim_drive_status(&d, 0.0).homed);
        CHECK(sim_drive_home(&d, 0.0, 30, 60) == 0);
        double t = settled(&d);
        struct sim_drive_status st = sim_drive_status(&d, t);
        CHECK(st.homed && st.in_position && st.home_switch && !st.moving);
        CHECK_NEAR(sim_drive_physical(&d, t), 0.0, 1e-9);
        CHECK_NEAR(sim_drive_position(&d, t), 0.0, 1e-9);

        CHECK(sim_drive_move(&d, t, 20.0, 30, 60) == 0);
        CHECK(sim_drive_status(&d, t + 0.1).moving);
        CHECK(!sim_drive_status(&d, t + 0.1).in_position);
        double end = motion_end_time(&d.mo);
        CHECK(!sim_drive_status(&d, end + 0.05).in_position); /* settling */
        t = settled(&d);
        CHECK(sim_drive_status(&d, t).in_position);
        CHECK_NEAR(sim_drive_angle(&d, t), 20.0, 1e-9);

        CHECK(sim_drive_move(&d, t, 0.0, 0, 60) == -EINVAL);
        CHECK(sim_drive_move(&d, t, 0.0, 30, 60) == 0);
        sim_drive_stop(&d, t + 0.3);
        double at = sim_drive_position(&d, t + 0.3);
        CHECK(at > 0.0 && at < 20.0);
        CHECK_NEAR(sim_drive_position(&d, t + 5.0), at, 1e-12);
        CHECK(!sim_drive_status(&d, t + 5.0).in_position);
}

static void test_faults(void)
{
        struct sim_drive d;
        double t = 0.0;

        sim_drive_init(&d, &axis);
        double from = sim_drive_position(&d, t);

        sim_drive_inject(&d, t, SIM_DRIVE_STALL); /* at rest: the next move */
        CHECK(sim_drive_move(&d, t, from + 20.0, 30, 60) == 0);
        t = settled(&d) + 2.0;
        struct sim_drive_status st = sim_drive_status(&d, t);
        CHECK(st.fault && !st.moving && !st.in_position && d.fault_code == SIM_DRIVE_FAULT_STALL);
        CHECK_NEAR(sim_drive_position(&d, t), from + 10.0, 1e-9); /* half-way, symmetric */
        CHECK(sim_drive_move(&d, t, from, 30, 60) == -EIO);
        sim_drive_reset(&d);
        CHECK(sim_drive_move(&d, t, from, 30, 60) == 0);

        sim_drive_inject(&d, t + 0.1, SIM_DRIVE_SHORT); /* while moving: this move */
        t = settled(&d) + 2.0;
        st = sim_drive_status(&d, t);
        CHECK(!st.fault && !st.moving && !st.in_position && d.fault_code == 0);
        CHECK_NEAR(sim_drive_position(&d, t), from + SIM_DRIVE_SHORT_DEG, 1e-9);

        sim_drive_inject(&d, t, SIM_DRIVE_SHORT);
        sim_drive_inject(&d, t, SIM_DRIVE_OK); /* cancelled */
        CHECK(sim_drive_move(&d, t, from, 30, 60) == 0);
        t = settled(&d);
        CHECK(sim_drive_status(&d, t).in_position);
        CHECK_NEAR(sim_drive_position(&d, t), from, 1e-9);
}

int main(void)
{
        test_home_and_move();
        test_faults();
        return 0;
}
