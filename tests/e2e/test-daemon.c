/* test-daemon.c - goniod end to end, as an operator drives it: gonio-sim emulates
 * the rig, goniod reaches it through its real drivers, and every command goes
 * through gonioctl (or a raw socket client for malformed input). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "common/frame.h"
#include "common/sha256.h"
#include "dataset/ds.h"
#include "harness.h"
#include "tests/test.h"

static double axis_pos(struct rigenv *e, const char *axis)
{
        json_t *st = ctl_ok(e, "status", NULL), *a;
        size_t i;
        double pos = NAN;

        json_array_foreach(json_object_get(st, "axes"), i,
                           a) if (strcmp(json_string_value(json_object_get(a, "name")), axis) == 0)
                pos = json_number_value(json_object_get(a, "position"));
        json_decref(st);
        return pos;
}

static void test_motion_and_switches(struct rigenv *e)
{
        json_t *r, *st;

        CHECK_INT(ctl(e, NULL, "move", "turntable", "90", NULL), 9); /* not homed yet */
        json_decref(ctl_ok(e, "home", NULL));
        st = ctl_ok(e, "status", NULL);
        CHECK(json_is_true(json_object_get(st, "homed")));
        CHECK(strcmp(json_string_value(json_object_get(st, "state")), "idle") == 0);
        json_decref(st);
        json_decref(ctl_ok(e, "move", "turntable", "90", NULL));
        CHECK_NEAR(axis_pos(e, "turntable"), 90, 0.01);
        json_decref(ctl_ok(e, "move", "turntable", "-30", "--relative", NULL));
        CHECK_NEAR(axis_pos(e, "turntable"), 60, 0.01);
        json_decref(ctl_ok(e, "move", "camera_arm", "-45", NULL));
        CHECK_NEAR(axis_pos(e, "camera_arm"), -45, 0.01);
        /* outside the soft limits: refused, nothing moves */
        CHECK_INT(ctl(e, &r, "move", "camera_arm", "200", NULL), 6);
        json_decref(r);
        CHECK_NEAR(axis_pos(e, "camera_arm"), -45, 0.01);
        json_decref(ctl_ok(e, "move", "camera_arm", "0", NULL));

        r = ctl_ok(e, "lamp", "lamp1", "on", NULL);
        CHECK(json_is_true(json_object_get(r, "on")));
        json_decref(r);
        json_decref(ctl_ok(e, "laser", "on", NULL));
        st = ctl_ok(e, "status", NULL);
        CHECK(json_is_true(json_object_get(json_array_get(json_object_get(st, "lamps"), 1), "on")));
        CHECK(json_is_true(json_object_get(json_object_get(st, "laser"), "on")));
        json_decref(st);
        json_decref(ctl_ok(e, "laser", "off", NULL));
        json_decref(ctl_ok(e, "lamp", "1", "off", NULL));
        CHECK_INT(ctl(e, NULL, "lamp", "lamp9", "on", NULL), 6);
}

/* Captures with camera cam and returns the stored frame read back from the dataset. */
static void capture_one(struct rigenv *e, const char *cam, struct ds *d, struct gn_frame *out)
{
        json_t *r = ctl_ok(e, "capture", "--camera", cam, NULL);
        json_t *c = json_array_get(json_object_get(r, "captures"), 0);
        char path[600], hex[65];

        CHECK(c);
        CHECK_INT(json_array_size(json_object_get(r, "captures")), 1);
        snprintf(path, sizeof(path), "%s/%s", ds_path(d),
                 json_string_value(json_object_get(c, "file")));
        CHECK_INT(gn_sha256_file_at(AT_FDCWD, path, hex), 0);
        CHECK(strcmp(hex, json_string_value(json_object_get(c, "sha256"))) == 0);
        CHECK_INT(ds_load_image(d, json_string_value(json_object_get(c, "file")), out), 0);
        json_decref(r);
}

static double mean(const struct gn_frame *f)
{
        double sum = 0;
        size_t n = (size_t)f->width * f->height * f->channels;

        for (size_t i = 0; i < n; i++)
                sum += f->bits == 8 ? f->data[i] : ((uint16_t *)f->data)[i] / 257.0;
        return sum / n;
}

static double mean_abs_diff(const struct gn_frame *a, const struct gn_frame *b)
{
        double sum = 0;
        size_t n = (size_t)a->width * a->height * a->channels;

        CHECK(a->width == b->width && a->height == b->height && a->bits == 8 && b->bits == 8);
        for (size_t i = 0; i < n; i++)
                sum += fabs((double)a->data[i] - b->data[i]);
        return sum / n;
}

/* The rendered frame shows the scene: it changes with the turntable angle, and
 * switching the lamp off darkens it. */
static void test_captures(struct rigenv *e)
{
        struct gn_frame lit0, lit90, dark;
        char path[400];
        struct ds *d = NULL;
        json_t *r;

        CHECK_INT(ctl(e, NULL, "capture", NULL), 9); /* no dataset open */
        r = ctl_ok(e, "dataset", "create", "e2e", NULL);
        json_decref(r);
        snprintf(path, sizeof(path), "%s/e2e", e->data);
        CHECK_INT(ds_open(path, &d), 0);

        json_decref(ctl_ok(e, "move", "turntable", "0", NULL));
        json_decref(ctl_ok(e, "lamp", "lamp0", "on", NULL));
        capture_one(e, "cam0", d, &lit0);
        json_decref(ctl_ok(e, "move", "turntable", "90", NULL));
        capture_one(e, "cam0", d, &lit90);
        json_decref(ctl_ok(e, "lamp", "lamp0", "off", NULL));
        capture_one(e, "cam0", d, &dark);
        fprintf(stderr, "mean lit %.2f, lit after 90 deg %.2f, dark %.2f, |diff| %.2f\n",
                mean(&lit0), mean(&lit90), mean(&dark), mean_abs_diff(&lit0, &lit90));
        CHECK(mean(&lit0) > 10);
        CHECK(mean(&dark) < 0.25 * mean(&lit90));
        CHECK(mean_abs_diff(&lit0, &lit90) > 1.0);

        /* all cameras at once: one row per camera, files match their checksums */
        r = ctl_ok(e, "capture", NULL);
        CHECK_INT(json_array_size(json_object_get(r, "captures")), 2);
        json_decref(r);
        CHECK_INT(ds_count(d), 5);
        CHECK_INT(ds_verify(d), 0);
        r = ctl_ok(e, "dataset", "info", NULL);
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 5);
        CHECK_INT(json_array_size(json_object_get(r, "captures")), 5);
        CHECK_STR(json_string_value(json_array_get(json_object_get(r, "cameras"), 0)), "cam0");
        CHECK_STR(json_string_value(json_array_get(json_object_get(r, "cameras"), 1)), "cam1");
        json_decref(r);
        r = ctl_ok(e, "dataset", "list", NULL);
        CHECK_INT(json_array_size(json_object_get(r, "datasets")), 1);
        CHECK_STR(json_string_value(json_object_get(
                          json_array_get(json_object_get(r, "datasets"), 0), "name")),
                  "e2e");
        json_decref(r);
        gn_frame_free_data(&lit0);
        gn_frame_free_data(&lit90);
        gn_frame_free_data(&dark);
        ds_close(d);
}

/* The config object describe gives device name, or fails. */
static json_t *device_config(json_t *desc, const char *name)
{
        json_t *d;
        size_t i;

        json_array_foreach(json_object_get(desc, "devices"), i,
                           d) if (strcmp(json_string_value(json_object_get(d, "name")), name) ==
                                  0) return json_object_get(d, "config");
        CHECK(!"no such device in describe");
        return NULL;
}

static double num(json_t *o, const char *key)
{
        CHECK(json_is_number(json_object_get(o, key)));
        return json_number_value(json_object_get(o, key));
}

/* describe holds what the rig file sets (harness.c's test rig), and the defaults of what it
 * does not: speeds, limits, motion semantics, lamp geometry and safety limits, camera
 * formats. */
static void test_describe(struct rigenv *e)
{
        json_t *d = ctl_ok(e, "describe", NULL), *c;

        c = device_config(d, "turntable");
        CHECK(json_is_true(json_object_get(c, "continuous")));
        CHECK(num(c, "max_speed") == 90 && num(c, "accel") == 180 && num(c, "settle_ms") == 20);
        CHECK_STR(json_string_value(json_object_get(c, "role")), "turntable");
        c = device_config(d, "camera_arm");
        CHECK(num(c, "min") == -170 && num(c, "max") == 170 && num(c, "max_speed") == 30);
        c = device_config(d, "lamp1");
        CHECK(num(c, "elevation") == 60 && num(c, "radius") == 450 && num(c, "max_on_s") == 3600);
        c = device_config(d, "laser");
        CHECK(num(c, "max_on_s") == 120 && json_is_false(json_object_get(c, "off_on_disconnect")));
        c = device_config(d, "cam1");
        CHECK(num(c, "bits") == 16 && num(c, "width") == 160 && num(c, "exposure_us") == 20000);
        json_decref(d);
}

/* The check of doctor's result (or error) named name. */
static json_t *doctor_check(json_t *r, const char *name)
{
        json_t *c, *list = json_object_get(r, "checks");
        size_t i;

        if (!list)
                list = json_object_get(json_object_get(r, "error"), "checks");
        json_array_foreach(list, i, c) if (!strcmp(json_string_value(json_object_get(c, "name")),
                                                   name)) return c;
        CHECK(!"doctor has no such check");
        return NULL;
}

/* gonioctl doctor on the homed, idle rig: every check ok, the room a session needs counted
 * from its plan and the cameras' frames; no socket: exit 3 with the hint to start goniod. */
static void test_doctor(struct rigenv *e)
{
        char file[400], sock[500];
        json_t *r = ctl_ok(e, "doctor", NULL);
        const char *detail;

        CHECK(json_is_true(json_object_get(r, "ok")));
        CHECK_STR(json_string_value(json_object_get(doctor_check(r, "camera_arm"), "status")),
                  "ok");
        CHECK_STR(json_string_value(json_object_get(doctor_check(r, "cam1"), "status")), "ok");
        json_decref(r);
        sess_write(e, "doctor.yaml", e2e_session_text, file, sizeof(file));
        r = ctl_ok(e, "doctor", file, NULL);
        detail = json_string_value(json_object_get(doctor_check(r, "storage"), "detail"));
        fprintf(stderr, "doctor: %s\n", detail);
        CHECK_STR_CONTAINS(detail, "captures need about");
        json_decref(r);
        snprintf(sock, sizeof(sock), "--socket=%s/none.sock", e->dir);
        CHECK_INT(ctl(e, &r, sock, "doctor", NULL), 3);
        CHECK_STR(json_string_value(json_object_get(doctor_check(r, "socket"), "status")), "fail");
        json_decref(r);
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 4);
        rigenv_start(&e, argv, 10);
        test_describe(&e);
        test_motion_and_switches(&e);
        test_doctor(&e);
        test_captures(&e);
        rigenv_stop(&e);
        return 0;
}
