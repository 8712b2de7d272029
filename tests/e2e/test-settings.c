/* test-settings.c - gonioctl get/set of device settings through goniod on gonio-sim (issue 13,
 * docs/goniod.md "Settings"): get shows each value and its limit; an axis's speed reaches its
 * drive, whose emulator then takes longer over the same move; a camera's default exposure
 * reaches the renderer, whose stored image is darker; every client hears of a change
 * (setting.changed); out of range refused naming the limit, unknown devices and settings
 * refused, settings refused while a session runs. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "common/frame.h"
#include "dataset/ds.h"
#include "harness.h"
#include "tests/test.h"

#define TIME_SCALE 10.0

/* The value of DEVICE.SETTING as gonioctl get gives it. */
static double get_value(struct rigenv *e, const char *what)
{
        json_t *r = ctl_ok(e, "get", what, NULL);
        double v = json_number_value(json_object_get(r, "value"));

        json_decref(r);
        return v;
}

/* Member key of setting name of device d (a device of get or describe: {..., settings}). */
static double setting_of(json_t *d, const char *name, const char *key)
{
        json_t *s = json_object_get(json_object_get(d, "settings"), name);

        return json_number_value(json_object_get(s, key));
}

/* gonioctl fails with exit code want and a message holding text. */
static void refused(struct rigenv *e, int want, const char *text, const char *a, const char *b)
{
        json_t *r = NULL;

        CHECK_INT(ctl(e, &r, "set", a, b, NULL), want);
        print_json("refused", r);
        CHECK_STR_CONTAINS(
                json_string_value(json_object_get(json_object_get(r, "error"), "message")) ?: "",
                text);
        json_decref(r);
}

/* Wall seconds of a move of the turntable from 0 to 180 deg and back to 0 (timed by the test,
 * the motion by gonio-sim's drive model at its speed register). */
static double move_time(struct rigenv *e)
{
        double t0 = now_s(), t;

        json_decref(ctl_ok(e, "move", "turntable", "180", NULL));
        t = now_s() - t0;
        json_decref(ctl_ok(e, "move", "turntable", "0", NULL));
        return t;
}

/* get shows the rig file's values and limits; unknown names and values out of range are
 * refused, naming what is wrong. */
static void test_get_and_refusals(struct rigenv *e)
{
        json_t *r = ctl_ok(e, "get", NULL), *d = json_array_get(json_object_get(r, "devices"), 0);

        CHECK_STR(json_string_value(json_object_get(d, "device")), "turntable");
        CHECK_NEAR(setting_of(d, "speed", "max"), 90, 1e-9);
        json_decref(r);
        r = ctl_ok(e, "get", "turntable.speed", NULL);
        CHECK_NEAR(json_number_value(json_object_get(r, "value")), 90, 1e-9);
        CHECK_STR(json_string_value(json_object_get(r, "limit")), "max_speed");
        json_decref(r);
        CHECK_NEAR(get_value(e, "turntable.accel"), 180, 1e-9);
        CHECK_NEAR(get_value(e, "cam0.exposure_us"), 20000, 1e-9);
        refused(e, 6, "outside [0.1, 90] (max from max_speed)", "turntable.speed", "200");
        refused(e, 6, "outside [0.1, 180] (max from max_accel)", "turntable.accel", "500");
        refused(e, 6, "exposure_us 0 us outside", "cam0.exposure_us", "0");
        refused(e, 6, "no axis or camera named 'nosuch'", "nosuch.speed", "1");
        refused(e, 6, "axis 'turntable' has no setting 'bogus'", "turntable.bogus", "1");
        CHECK_INT(ctl(e, NULL, "get", "lamp0", NULL), 6);
        CHECK_NEAR(get_value(e, "turntable.speed"), 90, 1e-9); /* unchanged by the refusals */
}

/* The turntable at 30 deg/s instead of 90: the same half turn takes 180/30 + 30/180 instead
 * of 180/90 + 90/180 s of rig time longer, on gonio-sim's clock (TIME_SCALE). */
static void test_axis_speed(struct rigenv *e)
{
        double fast, slow,
                want = (180.0 / 30 + 30.0 / 180 - (180.0 / 90 + 90.0 / 180)) / TIME_SCALE;
        json_t *r;
        int fd;

        json_decref(ctl_ok(e, "home", "turntable", NULL));
        fast = move_time(e);
        fd = raw_connect(e); /* another client: it hears of the change */
        r = ctl_ok(e, "set", "turntable.speed", "30", NULL);
        CHECK_NEAR(json_number_value(json_object_get(r, "value")), 30, 1e-9);
        json_decref(r);
        r = raw_wait_note(fd, "setting.changed", NULL, 5);
        CHECK_STR(json_string_value(json_object_get(r, "device")), "turntable");
        CHECK_STR(json_string_value(json_object_get(r, "setting")), "speed");
        CHECK_NEAR(json_number_value(json_object_get(r, "value")), 30, 1e-9);
        json_decref(r);
        close(fd);
        CHECK_NEAR(get_value(e, "turntable.speed"), 30, 1e-9);
        r = ctl_ok(e, "describe", NULL); /* describe shows the settings too */
        CHECK_NEAR(setting_of(json_array_get(json_object_get(r, "devices"), 0), "speed", "value"),
                   30, 1e-9);
        json_decref(r);
        slow = move_time(e);
        fprintf(stderr,
                "half turn at 90 deg/s: %.3f s, at 30 deg/s: %.3f s; %.3f s longer, the "
                "model %.3f s\n",
                fast, slow, slow - fast, want);
        CHECK(fabs(slow - fast - want) < 0.2);
        json_decref(ctl_ok(e, "set", "turntable.speed", "90", NULL));
}

/* Captures cam0 (the default exposure) and returns the stored frame's mean. */
static double capture_mean(struct rigenv *e, struct ds *d)
{
        json_t *r = ctl_ok(e, "capture", "--camera", "cam0", NULL);
        json_t *c = json_array_get(json_object_get(r, "captures"), 0);
        struct gn_frame f = {0};
        double sum = 0;
        size_t n;

        CHECK_INT(ds_load_image(d, json_string_value(json_object_get(c, "file")), &f), 0);
        n = (size_t)f.width * f.height * f.channels;
        for (size_t i = 0; i < n; i++)
                sum += f.data[i];
        gn_frame_free_data(&f);
        json_decref(r);
        return sum / n;
}

/* A quarter of the exposure: the stored image is about a quarter as bright. */
static void test_camera_exposure(struct rigenv *e)
{
        struct ds *d = NULL;
        char path[400];
        double full, quarter;

        json_decref(ctl_ok(e, "dataset", "create", "settings", NULL));
        snprintf(path, sizeof(path), "%s/settings", e->data);
        CHECK_INT(ds_open(path, &d), 0);
        json_decref(ctl_ok(e, "lamp", "lamp0", "on", NULL));
        full = capture_mean(e, d);
        json_decref(ctl_ok(e, "set", "cam0.exposure_us", "5000", NULL));
        quarter = capture_mean(e, d);
        fprintf(stderr, "mean at 20000 us %.2f, at 5000 us %.2f\n", full, quarter);
        CHECK(full > 10);
        CHECK(quarter < 0.4 * full && quarter > 0.1 * full);
        CHECK_NEAR(get_value(e, "cam0.exposure_us"), 5000, 1e-9);
        ds_close(d);
}

/* A session owns the rig: settings are refused until it ends. */
static void test_session_refuses(struct rigenv *e)
{
        int fd = sess_start_default(e, NULL);

        refused(e, 9, "session", "turntable.speed", "45");
        json_decref(ctl_ok(e, "session", "abort", NULL));
        close(fd);
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 4);
        rigenv_start(&e, argv, TIME_SCALE);
        test_get_and_refusals(&e);
        test_axis_speed(&e);
        test_camera_exposure(&e);
        test_session_refuses(&e);
        rigenv_stop(&e);
        return 0;
}
