/* test-calibrate.c - the rig's calibration file end to end (gonio-sim, goniod and gonioctl
 * as separate processes): the rig file's `calibration` key, its state in describe (missing
 * at start is a warning, not a failure), its copy into each dataset goniod creates or begins
 * a session on; and `gonioctl calibrate camera|turntable|laser` run on the rig as sessions,
 * solved and written into the rig's calibration file; `gonioctl calibrate lamps` on a rig
 * with a mirror sphere (lamps_rig_text), refused before anything moves without the cameras'
 * sections, then captured, solved against the truth and written. */
#include <fcntl.h>
#include <math.h>
#include <sys/stat.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/riggeom.h"
#include "common/sha256.h"
#include "harness.h"
#include "tests/test.h"

/* One camera looking at a 9x6 chessboard (16 mm squares) fixed on the turntable, tilted 45
 * deg up towards +x: seen at turntable angles from about -45 to 120 deg. */
static const char rig_text[] =
        "rig: calib\n"
        "calibration: cal/rig-calibration.yaml\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\", timeout_ms: "
        "300 }\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\", timeout_ms: "
        "300 }\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3 }, limits: [-170, 170],\n"
        "      max_speed: 30, accel: 60, settle_ms: 20 }\n"
        "lamps:\n"
        "  - { name: l0, modbus-coil: { bus: relays, unit: 10, coil: 0 }, elevation: 35,\n"
        "      radius: 800, azimuth: 20, intensity: 1.5e6 }\n"
        "laser: { name: line, modbus-coil: { bus: relays, unit: 10, coil: 7 }, azimuth: 0,\n"
        "         origin: [600, 0, 70], width: 0.5, power: 2.0e3, channel: red }\n"
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 20, distance: 420, azimuth: 40,\n"
        "      target: [0, 0, 70], width: 640, height: 480, fx: 600, fy: 596, cx: 321.3,\n"
        "      cy: 238.7, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02],\n"
        "      exposure_us: 20000 }\n"
        "scene:\n"
        "  seed: 9\n"
        "  targets:\n"
        "    - { type: chessboard, squares: [9, 6], square: 16,\n"
        "        pose: { translate: [10, -72, 110], rotate_x: -135, rotate_z: 90 } }\n"
        "  turntable: { radius: 0 }\n"
        "  sensor: { black_level: 0.02 }\n";

/* Two cameras and three lamps around a 100 mm mirror sphere 70 mm off the axis of a white
 * turntable (test-lamps' scene without distortion). */
static const char lamps_rig_text[] =
        "rig: lamps\n"
        "calibration: cal/rig-calibration.yaml\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\", timeout_ms: "
        "300 }\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\", timeout_ms: "
        "300 }\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "lamps:\n"
        "  - { name: l0, modbus-coil: { bus: relays, unit: 10, coil: 0 }, elevation: 30,\n"
        "      radius: 500, azimuth: 20, intensity: 3.0e5 }\n"
        "  - { name: l1, modbus-coil: { bus: relays, unit: 10, coil: 1 }, elevation: 55,\n"
        "      radius: 500, azimuth: 140, intensity: 3.0e5 }\n"
        "  - { name: l2, modbus-coil: { bus: relays, unit: 10, coil: 2 }, elevation: 40,\n"
        "      radius: 420, azimuth: 250, intensity: 3.0e5 }\n"
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 30, distance: 450, azimuth: 0,\n"
        "      target: [0, 0, 30], width: 1024, height: 768, fx: 1600, fy: 1600,\n"
        "      exposure_us: 20000 }\n"
        "  - { name: c1, sim: { bus: frames }, elevation: 40, distance: 480, azimuth: 70,\n"
        "      target: [0, 0, 30], width: 1024, height: 768, fx: 1500, fy: 1500,\n"
        "      exposure_us: 20000 }\n"
        "scene:\n"
        "  seed: 3\n"
        "  targets:\n"
        "    - { type: mirror_sphere, size: 100, reflectance: 0.6, pose: { translate: [70, 0, 0] "
        "} }\n"
        "  turntable: { radius: 400, albedo: 0.8 }\n"
        "  lamps: { radius: 30 }\n"
        "  sensor: { black_level: 0.02 }\n";

#define CAL_TEXT "format: gonio-calibration 1\nnotes: { by: e2e }\n"

/* The calibration member of describe. */
static json_t *calibration_state(struct rigenv *e)
{
        json_t *d = ctl_ok(e, "describe", NULL),
               *c = json_incref(json_object_get(d, "calibration"));

        print_json("calibration", c);
        json_decref(d);
        CHECK(c);
        return c;
}

static void check_state(struct rigenv *e, const char *want, const char *message)
{
        json_t *c = calibration_state(e);

        CHECK_STR(json_string_value(json_object_get(c, "state")), want);
        if (message)
                CHECK_STR_CONTAINS(json_string_value(json_object_get(c, "message")), message);
        else
                CHECK(!json_object_get(c, "message"));
        json_decref(c);
}

/* The dataset's calibration.yaml holds text (NULL: there is none). */
static void check_copy(struct rigenv *e, const char *dataset, const char *text)
{
        _cleanup_free_ void *got = NULL;
        char path[600];
        size_t len = 0;
        int r;

        snprintf(path, sizeof(path), "%s/%s/calibration.yaml", e->data, dataset);
        r = gn_read_file_at(AT_FDCWD, path, 1 << 20, &got, &len);
        if (!text) {
                CHECK_INT(r, -ENOENT);
                return;
        }
        CHECK_INT(r, 0);
        CHECK_STR((const char *)got, text);
}

/* The file missing at start, then written; copied at dataset create and session begin. */
static void test_copy(struct rigenv *e)
{
        char cal[400], dir[400], file[400], hex[GN_SHA256_HEX];
        json_t *r;

        snprintf(dir, sizeof(dir), "%s/cal", e->dir);
        snprintf(cal, sizeof(cal), "%s/rig-calibration.yaml", dir);
        check_state(e, "missing", "does not exist");
        r = calibration_state(e);
        CHECK_STR(json_string_value(json_object_get(r, "path")), cal);
        json_decref(r);
        json_decref(ctl_ok(e, "dataset", "create", "d0", NULL));
        check_copy(e, "d0", NULL);
        CHECK(mkdir(dir, 0755) == 0);
        CHECK(mkdir(cal, 0755) == 0); /* a directory where the file should be */
        check_state(e, "unreadable", "cannot read");
        json_decref(ctl_ok(e, "dataset", "create", "d2", NULL));
        check_copy(e, "d2", NULL);
        CHECK(rmdir(cal) == 0);
        write_file(cal, "cameras: {}\n");
        check_state(e, "invalid", "not a calibration file");
        write_file(cal, CAL_TEXT);
        check_state(e, "ok", NULL);
        json_decref(ctl_ok(e, "dataset", "create", "d1", NULL));
        check_copy(e, "d1", CAL_TEXT);
        /* describe's sha256 is the copy's */
        snprintf(file, sizeof(file), "%s/d1/calibration.yaml", e->data);
        CHECK_INT(gn_sha256_file_at(AT_FDCWD, file, hex), 0);
        r = calibration_state(e);
        CHECK_STR(json_string_value(json_object_get(r, "sha256")), hex);
        json_decref(r);
        /* a session begun on an existing dataset carries the file as it is then */
        write_file(cal, CAL_TEXT "# changed\n");
        sess_write(e, "s.yaml", "name: s\ndataset: d1\nsweep: { turntable: [0] }\nlamps: [l0]\n",
                   file, sizeof(file));
        CHECK_INT(ctl(e, NULL, "session", "run", file, NULL), 0);
        check_copy(e, "d1", CAL_TEXT "# changed\n");
        check_copy(e, "d0", NULL);
}

/* Runs gonioctl calibrate KIND on the rig; returns its exit code, the summary into *out. */
static int calibrate(struct rigenv *e, const char *kind, json_t **out)
{
        int r = ctl(e, out, "calibrate", kind, "--board", "chessboard:9x6:16", NULL);

        print_json(kind, *out);
        return r;
}

static double num(json_t *o, const char *key)
{
        return json_number_value(json_object_get(o, key));
}

/* The only dataset whose name starts with prefix holds a calibration.yaml with sub. */
static void check_dataset_copy(struct rigenv *e, const char *prefix, const char *sub)
{
        json_t *list = ctl_ok(e, "dataset", "list", NULL), *d;
        _cleanup_free_ void *text = NULL;
        char path[600] = "";
        size_t i, len;

        json_array_foreach(json_object_get(list, "datasets"), i,
                           d) if (strncmp(json_string_value(json_object_get(d, "name")), prefix,
                                          strlen(prefix)) == 0)
                snprintf(path, sizeof(path), "%s/calibration.yaml",
                         json_string_value(json_object_get(d, "path")));
        json_decref(list);
        CHECK(path[0]);
        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 1 << 20, &text, &len), 0);
        CHECK_STR_CONTAINS((const char *)text, sub);
}

/* The calibration sessions on the rig: camera, then turntable, solved into the rig's file;
 * the turntable before the camera refused before anything moves; the laser's session (its
 * laser frames, lamps off, used alone with the board from the lit frames of their angles:
 * calib-laserplane-dataset) refused with what each view showed, since this board lies where
 * the laser crosses it in one view only, and the file kept. */
static void test_rig(struct rigenv *e)
{
        _cleanup_free_ void *before = NULL, *after = NULL;
        json_t *res = NULL, *list;
        char cal[400];
        size_t n1, n2;

        snprintf(cal, sizeof(cal), "%s/cal", e->dir);
        CHECK(mkdir(cal, 0755) == 0);
        snprintf(cal, sizeof(cal), "%s/cal/rig-calibration.yaml", e->dir);
        CHECK_INT(calibrate(e, "turntable", &res), 6);
        json_decref(res); /* each failure's error object */
        CHECK_INT(ctl(e, &res, "calibrate", "laser", "--board", "chessboard:9x6:16", "--laser",
                      "nosuch", NULL),
                  6);
        json_decref(res);
        CHECK_INT(ctl(e, &res, "calibrate", "camera", "--board", "chessboard:9x6:16", "--camera",
                      "c9", NULL),
                  6);
        json_decref(res);
        list = ctl_ok(e, "dataset", "list", NULL);
        CHECK_INT(json_array_size(json_object_get(list, "datasets")), 0); /* nothing captured */
        json_decref(list);
        CHECK_INT(calibrate(e, "camera", &res), 0);
        CHECK_STR(json_string_value(json_object_get(res, "file")), cal);
        CHECK_NEAR(num(res, "fx"), 600, 6);
        CHECK_NEAR(num(res, "cy"), 238.7, 5);
        CHECK(num(res, "rms_px") < 0.3);
        json_decref(res);
        CHECK_INT(calibrate(e, "turntable", &res), 0);
        CHECK(num(res, "views_used") >= 4 && num(res, "span_deg") >= 60);
        CHECK(num(res, "rms_px") < 0.3);
        CHECK_NEAR(num(res, "tilt_deg"), 45, 1);
        json_decref(res);
        /* the turntable's dataset carries the calibration its capture began with */
        check_dataset_copy(e, "calib-turntable-", "cameras:");
        CHECK_INT(gn_read_file_at(AT_FDCWD, cal, 1 << 20, &before, &n1), 0);
        CHECK_STR_CONTAINS((const char *)before, "turntables:");
        CHECK_INT(calibrate(e, "laser", &res), 6);
        json_decref(res);
        CHECK_INT(gn_read_file_at(AT_FDCWD, cal, 1 << 20, &after, &n2), 0);
        CHECK(n1 == n2 && memcmp(before, after, n1) == 0);
}

/* The cameras of lamps_rig_text: name, elevation, distance, azimuth, fx (= fy). */
static const struct {
        const char *name;
        double elevation, distance, azimuth, f;
} lamp_cams[] = {{"c0", 30, 450, 0, 1600}, {"c1", 40, 480, 70, 1500}};

/* The cameras' true intrinsics and poses as calibration file sections, into path. */
static void write_true_cameras(const char *path)
{
        FILE *f = fopen(path, "w");

        CHECK(f);
        fprintf(f, "format: gonio-calibration 1\ncameras:\n");
        for (size_t i = 0; i < ELEMENTSOF(lamp_cams); i++)
                fprintf(f,
                        "  %s: { solved: x, dataset: x, board: { type: chessboard, squares: [9, "
                        "6], square_mm: 16 }, width: 1024, height: 768, fx: %g, fy: %g, cx: "
                        "511.5, cy: 383.5, dist: [0, 0, 0, 0, 0], std_px: [0, 0, 0, 0], rms_px: "
                        "0.1, views_used: 10, views_rejected: 0 }\n",
                        lamp_cams[i].name, lamp_cams[i].f, lamp_cams[i].f);
        fprintf(f, "turntables:\n");
        for (size_t i = 0; i < ELEMENTSOF(lamp_cams); i++) {
                struct rig_camera_conf c = {.elevation_deg = lamp_cams[i].elevation,
                                            .distance_mm = lamp_cams[i].distance,
                                            .azimuth_deg = lamp_cams[i].azimuth,
                                            .target = {0, 0, 30}};
                double R[9], tv[3];
                riggeom_camera_pose(&c, 0, R, tv);
                fprintf(f,
                        "  %s: { solved: x, dataset: x, board: { type: chessboard, squares: [9, "
                        "6], square_mm: 16 }, R: [%.12g, %.12g, %.12g, %.12g, %.12g, %.12g, "
                        "%.12g, %.12g, %.12g], t: [%.12g, %.12g, %.12g], axis: [%.12g, %.12g, "
                        "%.12g], origin: [%.12g, %.12g, %.12g], rms_px: 0.1, circle_rms_mm: 0.01, "
                        "tilt_deg: 45, span_deg: 90, views_used: 9, views_given: 9 }\n",
                        lamp_cams[i].name, R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8],
                        tv[0], tv[1], tv[2], R[2], R[5], R[8], tv[0], tv[1], tv[2]);
        }
        CHECK(fclose(f) == 0);
}

/* Lamp position against the truth on the rig: 0.2, 1.4 and 0.1 mm. l1's 1.4 mm is a bias along
 * its direction from the highlight model, not the rig: test-lamps' in-process frames give the
 * same without their camera c0's distortion (docs/calibration.md, "Not done yet (lamps)"). */
#define LAMPS_RIG_TOL_MM 2.0

/* The lamps on the rig: refused before anything moves without the calibration file or the
 * cameras' sections, then the session (2 cameras x 3 lamps x 16 angles), solved, written,
 * each lamp within LAMPS_RIG_TOL_MM of the truth. */
static void test_lamps(struct rigenv *e)
{
        static const double truth_rea[3][3] = {{500, 30, 20}, {500, 55, 140}, {420, 40, 250}};
        json_t *res = NULL, *list, *l;
        char cal[400];
        size_t i;

        snprintf(cal, sizeof(cal), "%s/cal", e->dir);
        CHECK(mkdir(cal, 0755) == 0);
        snprintf(cal, sizeof(cal), "%s/cal/rig-calibration.yaml", e->dir);
        CHECK_INT(ctl(e, &res, "calibrate", "lamps", "--sphere", "100", NULL), 6);
        json_decref(res);
        write_file(cal, "format: gonio-calibration 1\n");
        CHECK_INT(ctl(e, &res, "calibrate", "lamps", "--sphere", "100", NULL), 6);
        json_decref(res);
        list = ctl_ok(e, "dataset", "list", NULL);
        CHECK_INT(json_array_size(json_object_get(list, "datasets")), 0); /* nothing captured */
        json_decref(list);
        write_true_cameras(cal);
        CHECK_INT(
                ctl(e, &res, "calibrate", "lamps", "--sphere", "100", "--lamp-radius", "30", NULL),
                0);
        print_json("lamps", res);
        CHECK_STR(json_string_value(json_object_get(res, "file")), cal);
        CHECK_INT(num(res, "views"), 96);
        CHECK_INT(json_array_size(json_object_get(res, "failed")), 0);
        CHECK_INT(json_array_size(json_object_get(res, "lamps")), 3);
        json_array_foreach(json_object_get(res, "lamps"), i, l)
        {
                const double *t = truth_rea[i], r = t[0], el = t[1] * M_PI / 180,
                             az = t[2] * M_PI / 180;
                double want[3] = {r * cos(el) * cos(az), r * cos(el) * sin(az), r * sin(el)},
                       e2 = 0;
                for (int k = 0; k < 3; k++)
                        e2 += pow(json_number_value(
                                          json_array_get(json_object_get(l, "position_mm"), k)) -
                                          want[k],
                                  2);
                fprintf(stderr, "lamp %zu: %.3f mm from the truth\n", i, sqrt(e2));
                CHECK(sqrt(e2) <= LAMPS_RIG_TOL_MM);
        }
        json_decref(res);
        check_dataset_copy(e, "calib-lamps-", "turntables:");
}

int main(int argc, char **argv)
{
        static const char *const cases[] = {"copy", "rig", "lamps"};
        struct rigenv e;
        const char *c = argc == 5 ? argv[4] : "";

        CHECK(argc == 5);
        if (strcmp(c, cases[0]) != 0 && strcmp(c, cases[1]) != 0 && strcmp(c, cases[2]) != 0)
                return 1;
        rigenv_start_rig(&e, argv, 20, strcmp(c, cases[2]) == 0 ? lamps_rig_text : rig_text);
        if (strcmp(c, cases[0]) == 0)
                test_copy(&e);
        else if (strcmp(c, cases[1]) == 0)
                test_rig(&e);
        else
                test_lamps(&e);
        rigenv_stop(&e);
        return 0;
}
