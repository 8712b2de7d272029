/* test-motion.c - the trapezoidal motion model of the emulated drives (sim/motion.c). */
#include <errno.h>
#include <math.h>

#include "sim/motion.h"
#include "tests/sim/simtest.h"

/* 90 deg at 90 deg/s, 180 deg/s^2: 0.5 s up (22.5 deg), 0.5 s cruise (45), 0.5 s down. */
static void test_trapezoid(void)
{
        struct motion m;

        CHECK(motion_plan(&m, 10.0, 5.0, 95.0, 90.0, 180.0) == 0);
        CHECK_NEAR(m.t_total, 1.5, 1e-12);
        CHECK_NEAR(motion_end_time(&m), 11.5, 1e-12);
        CHECK_NEAR(motion_position(&m, 9.0), 5.0, 1e-12);
        CHECK_NEAR(motion_position(&m, 10.5), 5.0 + 22.5, 1e-9);
        CHECK_NEAR(motion_position(&m, 10.75), 5.0 + 45.0, 1e-9);
        CHECK_NEAR(motion_position(&m, 11.0), 5.0 + 67.5, 1e-9);
        CHECK_NEAR(motion_position(&m, 12.0), 95.0, 1e-12);
        CHECK_NEAR(motion_velocity(&m, 10.75), 90.0, 1e-9);
        CHECK_NEAR(motion_velocity(&m, 10.25), 45.0, 1e-9);
        CHECK(motion_moving(&m, 11.4));
        CHECK(!motion_moving(&m, 11.5));
        CHECK_NEAR(motion_duration(90.0, 90.0, 180.0), 1.5, 1e-12);
        CHECK_NEAR(motion_duration(-90.0, 90.0, 180.0), 1.5, 1e-12);
        for (double d = 0.0; d <= 90.0; d += 7.5) /* through all three phases */
                CHECK_NEAR(motion_position(&m, motion_time_at(&m, d)), 5.0 + d, 1e-9);
        CHECK_NEAR(motion_time_at(&m, 200.0), 11.5, 1e-12);
}

/* 10 deg at 90 deg/s, 180 deg/s^2 never reaches 90 deg/s: peak sqrt(10*180). */
static void test_triangle(void)
{
        struct motion m;

        CHECK(motion_plan(&m, 0.0, 0.0, -10.0, 90.0, 180.0) == 0);
        CHECK_NEAR(m.v_peak, sqrt(1800.0), 1e-9);
        CHECK_NEAR(m.t_total, 2.0 * sqrt(10.0 / 180.0), 1e-12);
        CHECK_NEAR(motion_position(&m, m.t_total / 2), -5.0, 1e-9);
        CHECK(motion_velocity(&m, m.t_total / 2 - 1e-6) < 0.0);
        CHECK_NEAR(motion_target(&m), -10.0, 1e-12);
        CHECK_NEAR(motion_time_at(&m, 5.0), m.t_total / 2, 1e-9);
        CHECK_NEAR(motion_position(&m, motion_time_at(&m, 7.0)), -7.0, 1e-9);
}

/* Position is continuous and monotonic, speed never above the limit. */
static void test_continuity(void)
{
        struct motion m;
        double last = 0.0;

        CHECK(motion_plan(&m, 0.0, 0.0, 200.0, 30.0, 60.0) == 0);
        for (double t = 0.0; t <= m.t_total + 0.1; t += 1e-3) {
                double p = motion_position(&m, t);
                CHECK(p >= last - 1e-12);
                CHECK(p - last <= 30.0 * 1e-3 + 1e-9);
                CHECK(fabs(motion_velocity(&m, t)) <= 30.0 + 1e-9);
                last = p;
        }
        CHECK_NEAR(last, 200.0, 1e-12);
}

static void test_halt_rest_invalid(void)
{
        struct motion m;

        CHECK(motion_plan(&m, 0.0, 0.0, 90.0, 90.0, 180.0) == 0);
        double at = motion_position(&m, 0.6);
        motion_halt(&m, 0.6);
        CHECK_NEAR(motion_position(&m, 5.0), at, 1e-12);
        CHECK(!motion_moving(&m, 0.6));

        motion_rest(&m, 3.0, 42.0);
        CHECK_NEAR(motion_position(&m, 0.0), 42.0, 1e-12);
        CHECK(!motion_moving(&m, 3.0));

        CHECK(motion_plan(&m, 0.0, 0.0, 1.0, 0.0, 1.0) == -EINVAL);
        CHECK(motion_plan(&m, 0.0, 0.0, 1.0, 1.0, -1.0) == -EINVAL);
        CHECK_NEAR(motion_position(&m, 10.0), 42.0, 1e-12); /* untouched */
        CHECK(motion_plan(&m, 1.0, 7.0, 7.0, 1.0, 1.0) == 0);
        CHECK(!motion_moving(&m, 1.0));
}

int main(void)
{
        test_trapezoid();
        test_triangle();
        test_continuity();
        test_halt_rest_invalid();
        return 0;
}
