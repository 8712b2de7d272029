/* test-gpio-proto.c - the pure parts of the GPIO backends (drivers/axis/gpio/proto.c,
 * drivers/switch/gpio/proto.c): the trapezoidal step schedule against the class's move-time
 * model and its speed limit, degrees and steps the shortest way round, and the rig-file maps
 * with their errors. The backends themselves run on gpio-sim in the kernel lane
 * (tests/kernel/gpio-backends.c). */
#include "common/yconf.h"
#include "drivers/axis/gpio/proto.h"
#include "drivers/switch/gpio/proto.h"
#include "tests/test.h"

/* Every interval of p at least 1/v (the speed never exceeds v) and times increasing. */
static void check_speed_bound(const struct gpst_profile *p)
{
        double prev = 0;

        for (long k = 1; k <= p->n; k++) {
                double t = gpst_step_time(p, k);

                CHECK(t > prev);
                CHECK(t - prev >= 1.0 / p->v - 1e-9);
                prev = t;
        }
}

static void test_trapezoid(void)
{
        struct gpst_profile p;

        CHECK_INT(gpst_profile_init(&p, 1000, 100, 200), 0);
        CHECK_NEAR(p.total, axis_move_time(1000, 100, 200), 1e-9);
        CHECK_NEAR(p.total, 10.5, 1e-9);
        CHECK_NEAR(gpst_step_time(&p, 1), sqrt(2.0 / 200), 1e-12);
        CHECK_NEAR(gpst_step_time(&p, 1000), p.total, 1e-9);
        CHECK_NEAR(gpst_step_time(&p, 500) - gpst_step_time(&p, 499), 0.01, 1e-9); /* cruise */
        for (long k = 1; k < 1000; k++) /* the ramps mirror each other */
                CHECK_NEAR(gpst_step_time(&p, k) + gpst_step_time(&p, 1000 - k), p.total, 1e-9);
        check_speed_bound(&p);
}

static void test_triangle(void)
{
        struct gpst_profile p;

        CHECK_INT(gpst_profile_init(&p, 10, 100, 200), 0); /* 25 steps of ramp would be needed */
        CHECK_NEAR(p.total, axis_move_time(10, 100, 200), 1e-9);
        CHECK_NEAR(p.total, 2 * sqrt(10.0 / 200), 1e-9);
        CHECK_NEAR(gpst_step_time(&p, 5), p.total / 2, 1e-9);
        CHECK_NEAR(gpst_step_time(&p, 10), p.total, 1e-9);
        check_speed_bound(&p);
        CHECK_INT(gpst_profile_init(&p, 1, 100, 200), 0);
        CHECK_NEAR(gpst_step_time(&p, 1), p.total, 1e-12);
}

static void test_no_ramp(void)
{
        struct gpst_profile p;

        CHECK_INT(gpst_profile_init(&p, 50, 25, 0), 0);
        CHECK_NEAR(p.total, 2.0, 1e-12);
        CHECK_NEAR(gpst_step_time(&p, 1), 0.04, 1e-12);
        CHECK_NEAR(gpst_step_time(&p, 37), 37 * 0.04, 1e-12);
        CHECK_INT(gpst_profile_init(&p, 50, 25, INFINITY), 0);
        CHECK_NEAR(gpst_step_time(&p, 50), 2.0, 1e-12);
        CHECK_INT(gpst_profile_init(&p, 50, INFINITY, 10), -EINVAL);
        CHECK_INT(gpst_profile_init(&p, 50, 0, 10), -EINVAL);
        CHECK_INT(gpst_profile_init(&p, -1, 10, 10), -EINVAL);
        CHECK_INT(gpst_profile_init(&p, 0, 10, 10), 0);
        CHECK_NEAR(p.total, 0, 0);
}

static void test_steps(void)
{
        int64_t s;

        CHECK_INT(gpst_deg_to_steps(100, 12.345, &s), 0);
        CHECK_INT(s, 1235);
        CHECK_INT(gpst_deg_to_steps(100, -0.004, &s), 0);
        CHECK_INT(s, 0);
        CHECK_INT(gpst_deg_to_steps(100, NAN, &s), -ERANGE);
        CHECK_INT(gpst_deg_to_steps(1e7, 1e12, &s), -ERANGE);
        CHECK_NEAR(gpst_steps_to_deg(100, -100, false), -1.0, 1e-12);
        CHECK_NEAR(gpst_steps_to_deg(100, -100, true), 359.0, 1e-9);
        CHECK_NEAR(gpst_steps_to_deg(100, 72000 + 50, true), 0.5, 1e-9);
        /* a travel the axis class chose, from the step counter: across the wrap and back */
        CHECK_INT(gpst_travel_steps(100, 35900, 2.0, &s), 0);
        CHECK_INT(s, 36100);
        CHECK_INT(gpst_travel_steps(100, 100, -2.0, &s), 0);
        CHECK_INT(s, -100);
        CHECK_INT(gpst_travel_steps(100, 0, 1e18, &s), -ERANGE);
}

/* Parses text (one map) with parse; returns its result, the error in err. */
static int parse(int (*fn)(struct yconf *, struct fy_node *, const struct rig_config *, void *,
                           struct rig_addr *),
                 const char *text, void *conf, char *err, size_t errlen)
{
        struct yconf yc = {};
        struct rig_addr addr = {.key = "x"};
        int r;

        err[0] = '\0';
        CHECK_INT(yconf_open_string(&yc, "rig.yaml", text, err, errlen), 0);
        r = fn(&yc, yconf_root(&yc), NULL, conf, &addr);
        if (r == 0)
                CHECK(addr.key == NULL);
        yconf_close(&yc);
        return r;
}

static void test_stepper_map(void)
{
        struct gpst_conf c;
        char err[256];

        CHECK_INT(parse(gpst_parse_conf,
                        "{ bus: io, chip: gonio-gpio, step: 0, dir: dir, enable: enable,\n"
                        "  home: home, limit_max: 8, steps_per_deg: 10,\n"
                        "  active_low: [enable, home], home_dir: 1, home_speed: 2.5 }",
                        &c, err, sizeof(err)),
                  0);
        CHECK_STR(c.chip, "gonio-gpio");
        CHECK_STR(c.lines[GPST_STEP], "0");
        CHECK_STR(c.lines[GPST_DIR], "dir");
        CHECK_STR(c.lines[GPST_LIMIT_MAX], "8");
        CHECK_STR(c.lines[GPST_LIMIT_MIN], "");
        CHECK(c.active_low[GPST_ENABLE] && c.active_low[GPST_HOME] && !c.active_low[GPST_STEP]);
        CHECK_NEAR(c.steps_per_deg, 10, 0);
        CHECK_INT(c.home_dir, 1);
        CHECK_NEAR(c.home_speed, 2.5, 0);
        CHECK_INT(parse(gpst_parse_conf, "{ chip: c, step: 0, dir: 1, steps_per_deg: 10 }", &c, err,
                        sizeof(err)),
                  0);
        CHECK_INT(c.home_dir, -1);
        CHECK_INT(parse(gpst_parse_conf, "{ chip: c, dir: 1, steps_per_deg: 10 }", &c, err,
                        sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "key 'step'");
        CHECK_INT(parse(gpst_parse_conf, "{ chip: c, step: 0, dir: 1 }", &c, err, sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "steps_per_deg");
        CHECK_INT(parse(gpst_parse_conf,
                        "{ chip: c, step: 0, dir: 1, steps_per_deg: 1,\n  active_low: [stpe] }", &c,
                        err, sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "rig.yaml:2");
        CHECK_STR_CONTAINS(err, "'stpe' is not a line of the axis");
        CHECK_INT(parse(gpst_parse_conf, "{ chip: c, step: 0, dir: 1, home: 0, steps_per_deg: 1 }",
                        &c, err, sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "line 0 is also 'step'");
        CHECK_INT(parse(gpst_parse_conf,
                        "{ chip: c, step: 0, dir: 1, steps_per_deg: 1, home_dir: 0 }", &c, err,
                        sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "home_dir");
        CHECK_INT(parse(gpst_parse_conf, "{ chip: c, step: 0, dir: 1, steps_per_deg: 1, stp: 3 }",
                        &c, err, sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "stp");
}

static void test_switch_map(void)
{
        struct gpsw_conf c;
        char err[256];

        CHECK_INT(parse(gpsw_parse_conf, "{ bus: io, chip: gpiochip0, line: 6, active_low: true }",
                        &c, err, sizeof(err)),
                  0);
        CHECK_STR(c.chip, "gpiochip0");
        CHECK_STR(c.line, "6");
        CHECK(c.active_low);
        CHECK_INT(parse(gpsw_parse_conf, "{ bus: io, chip: gpiochip0 }", &c, err, sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "key 'line'");
        CHECK_INT(parse(gpsw_parse_conf, "{ bus: io, chip: c, line: lamp, pin: 3 }", &c, err,
                        sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, "pin");
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"trapezoid", test_trapezoid},     {"triangle", test_triangle},
                {"no-ramp", test_no_ramp},         {"steps", test_steps},
                {"stepper-map", test_stepper_map}, {"switch-map", test_switch_map},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
