/* test-pose.c - the pose type: role names both ways, poses compared across 0/360 and with
 * missing axes (NAN), lamp lists and their -ENOBUFS. */
#include <errno.h>
#include <math.h>

#include "common/pose.h"
#include "tests/test.h"

static void test_roles(void)
{
        static const char *const names[] = {"turntable", "light_arm", "camera_arm"};

        CHECK_INT(GN_ROLE_COUNT, 3);
        for (int i = 0; i < GN_ROLE_COUNT; i++) {
                CHECK_STR(gn_role_name(i), names[i]);
                CHECK_INT(gn_role_from_name(names[i]), i);
        }
        CHECK(gn_role_name(GN_ROLE_COUNT) == NULL);
        CHECK(gn_role_name(-1) == NULL);
        CHECK_INT(gn_role_from_name("Turntable"), -ENOENT);
        CHECK_INT(gn_role_from_name("turntable "), -ENOENT);
        CHECK_INT(gn_role_from_name("none"), -ENOENT);
        CHECK_INT(gn_role_from_name(""), -ENOENT);
        CHECK_INT(gn_role_from_name(NULL), -ENOENT);
}

/* A pose with only a turntable at deg. */
static struct gn_pose turntable_at(double deg)
{
        struct gn_pose p = gn_pose_none();

        p.deg[GN_ROLE_TURNTABLE] = deg;
        return p;
}

static void check_equal(double a, double b, double tol, bool want)
{
        struct gn_pose pa = turntable_at(a), pb = turntable_at(b);

        if (gn_pose_equal(&pa, &pb, tol) != want || gn_pose_equal(&pb, &pa, tol) != want) {
                fprintf(stderr, "gn_pose_equal(%g, %g, tol %g) != %d\n", a, b, tol, want);
                CHECK(!"gn_pose_equal");
        }
}

static void test_equal_angles(void)
{
        check_equal(359.99, 0.01, 0.05, true); /* 0.02 apart across zero */
        check_equal(359.99, 0.01, 0.01, false);
        check_equal(-0.01, 359.99, 1e-9, true);
        check_equal(0, 720, 1e-9, true);
        check_equal(0, 370, 1, false); /* 10 apart, also a full turn away */
        check_equal(5, -365, 10, true);
        check_equal(180, -180, 1e-9, true);
        check_equal(10, 190, 1, false); /* opposite sides: 180 apart, not 0 */
        check_equal(10, 10.5, 0.5, true);
        check_equal(10, 10.51, 0.5, false);
        check_equal(0, 0, 0, true);
}

static void test_equal_nan(void)
{
        struct gn_pose none = gn_pose_none(), a = gn_pose_none(), b;

        for (int i = 0; i < GN_ROLE_COUNT; i++) {
                CHECK(isnan(none.deg[i]));
                CHECK(!gn_pose_has(&none, i));
        }
        CHECK(!gn_pose_has(&none, GN_ROLE_COUNT));
        CHECK(!none.lasers && none.lamps == 0);
        CHECK(gn_pose_equal(&none, &a, 0)); /* no axis equals no axis */
        a.deg[GN_ROLE_CAMERA_ARM] = 0;
        CHECK(gn_pose_has(&a, GN_ROLE_CAMERA_ARM));
        CHECK(!gn_pose_equal(&none, &a, 360)); /* a missing axis is not at any angle */
        CHECK(!gn_pose_equal(&a, &none, 360));
        b = a;
        b.deg[GN_ROLE_TURNTABLE] = 5;
        CHECK(!gn_pose_equal(&a, &b, 360));
        a.deg[GN_ROLE_TURNTABLE] = 5;
        CHECK(gn_pose_equal(&a, &b, 0));
}

static void test_equal_switches(void)
{
        struct gn_pose a = turntable_at(1), b = turntable_at(1);

        a.lamps = 1u << 3;
        CHECK(!gn_pose_equal(&a, &b, 1));
        b.lamps = 1u << 3;
        CHECK(gn_pose_equal(&a, &b, 1));
        b.lasers = 1;
        CHECK(!gn_pose_equal(&a, &b, 1));
        a.lasers = 1u << 1; /* another laser: a bit set by rig-file index, not a flag */
        CHECK(!gn_pose_equal(&a, &b, 1));
        a.lasers = b.lasers = (1u << 1) | (1u << 7);
        CHECK(gn_pose_equal(&a, &b, 1));
        b.lasers = 1u << 7;
        CHECK(!gn_pose_equal(&a, &b, 1));
}

static void test_name_list(void)
{
        static const char *const names[] = {"left", "right", "top"};
        char buf[32];

        CHECK_INT(gn_name_list((1u << 0) | (1u << 2), names, 3, buf, sizeof(buf)), 8);
        CHECK_STR(buf, "left,top");
        CHECK_INT(gn_name_list(1u << 1, names, 3, buf, sizeof(buf)), 5);
        CHECK_STR(buf, "right");
        CHECK_INT(gn_name_list(0, names, 3, buf, sizeof(buf)), 0);
}

static void test_lamp_list(void)
{
        static const char *const names[] = {"lamp0", "lamp1", "lamp2", "lamp3"};
        struct gn_pose p = gn_pose_none();
        char buf[64], small[12];

        CHECK_INT(gn_pose_lamp_list(&p, names, 4, buf, sizeof(buf)), 0);
        CHECK_STR(buf, "");
        p.lamps = (1u << 0) | (1u << 2) | (1u << 9); /* bit 9: beyond the rig's 4 lamps */
        CHECK_INT(gn_pose_lamp_list(&p, names, 4, buf, sizeof(buf)), 11);
        CHECK_STR(buf, "lamp0,lamp2");
        CHECK_INT(gn_pose_lamp_list(&p, names, 4, small, 12), 11); /* exact fit */
        CHECK_STR(small, "lamp0,lamp2");
        CHECK_INT(gn_pose_lamp_list(&p, names, 4, small, 11), -ENOBUFS);
        CHECK_INT(gn_pose_lamp_list(&p, names, 4, small, 3), -ENOBUFS);
        CHECK_INT(gn_pose_lamp_list(&p, names, 4, small, 0), -ENOBUFS);
        p.lamps = 1u << 3;
        CHECK_INT(gn_pose_lamp_list(&p, names, 4, buf, sizeof(buf)), 5);
        CHECK_STR(buf, "lamp3");
}

int main(void)
{
        test_roles();
        test_equal_angles();
        test_equal_nan();
        test_equal_switches();
        test_lamp_list();
        test_name_list();
        return 0;
}
