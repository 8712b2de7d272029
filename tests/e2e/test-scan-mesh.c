/* test-scan-mesh.c - gonioctl scan end to end: a sphere on gonio-sim's turntable scanned
 * through goniod in continuous rotation and stop-and-go, its point cloud and mesh rebuilt from
 * the dataset, scored against the sphere the renderer drew; and gonioctl scan --from with a
 * calibration file: the true calibration written through calib/calfile gives the same
 * shape, a wrong laser plane a wrong one, a file without the laser an error naming it; a rig
 * with two lasers on either side of the camera scanned stop-and-go (each laser alone at every
 * angle) and in continuous rotation (one pass per laser): each laser's points on the sphere,
 * and the two surfaces in agreement. */
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/calfile.h"
#include "calib/scan.h"
#include "common/cleanup.h"
#include "common/riggeom.h"
#include "drivers/registry.h"
#include "harness.h"
#include "tests/scan/meshread.h"
#include "tests/test.h"

static char **args;

/* One camera, the turntable, a laser whose plane contains the axis 30 degrees from the camera,
 * a 60 mm sphere off the axis (centre SPHERE_C) */
static const char rig[] =
        "rig: scan-mesh\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\", timeout_ms: 300 "
        "}\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\", timeout_ms: 300 "
        "}\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "laser: { name: laser, modbus-coil: { bus: relays, unit: 10, coil: 7 }, azimuth: 30,\n"
        "         origin: [520, 300, 60], width: 0.8, power: 3.0e3, channel: red }\n"
        "cameras:\n"
        "  - { name: cam0, sim: { bus: frames }, elevation: 20, distance: 400, azimuth: 0,\n"
        "      target: [0, 0, 30], width: 320, height: 240, fx: 500, fy: 500,\n"
        "      exposure_us: 5000 }\n"
        "scene:\n"
        "  seed: 5\n"
        "  object: { shape: sphere, size: 60, pose: { translate: [20, 0, 0] },\n"
        "            material: { albedo: 0.7 } }\n"
        "  turntable: { radius: 0 }\n"
        "  sensor: { black_level: 0.02 }\n";

static const double SPHERE_C[3] = {20, 0, 30}, SPHERE_R = 30;

/* The RMS distance from the points to the true sphere must stay under this (mm): the
 * segmentation error (0.01-0.03 px, about 0.02 mm here at 0.8 mm a pixel) times the
 * triangulation's 2 and, in continuous mode, the interpolated angles (0.05 deg, 0.03 mm at
 * the sphere's far side) measure 0.06-0.07 mm; a frame stored with the angle of its
 * neighbour (0.45-1 deg) gives 0.3 mm and more. */
#define RMS_MM 0.1

/* The RMS distance of the points of dir/scan.ply from the sphere; their count into *n. */
static double sphere_rms(const char *dir, size_t *n)
{
        struct cal_mesh m = {0};
        char path[4096];
        double sum = 0;

        snprintf(path, sizeof(path), "%s/scan.ply", dir);
        mr_read_ply(AT_FDCWD, path, &m);
        for (size_t i = 0; i < m.n_v; i++) {
                double d[3];

                for (int k = 0; k < 3; k++)
                        d[k] = m.v[i].x[k] - SPHERE_C[k];
                sum += pow(sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) - SPHERE_R, 2);
        }
        *n = m.n_v;
        cal_mesh_free(&m);
        return *n ? sqrt(sum / (double)*n) : INFINITY;
}

/* The mesh the scan wrote: faces, and the sphere's points. */
static void expect_mesh(const char *dir, size_t min_triangles)
{
        struct cal_mesh m = {0};
        char path[4096];

        snprintf(path, sizeof(path), "%s/mesh.ply", dir);
        mr_read_ply(AT_FDCWD, path, &m);
        fprintf(stderr, "mesh: %zu vertices, %zu triangles\n", m.n_v, m.n_tri);
        CHECK(m.n_tri > min_triangles);
        mr_check_edges(m.tri, m.n_tri);
        cal_mesh_free(&m);
}

/* gonioctl scan NAME in mode with step, checked against the truth; the dataset's directory
 * into dir. (With --json, stop-and-go prints the session's events before the result: only the
 * exit code is read here, the files tell the rest.) */
static void scan_and_score(struct rigenv *e, const char *name, const char *mode, const char *step,
                           size_t min_points, char dir[static 4096])
{
        size_t n;
        double rms;

        CHECK_INT(ctl(e, NULL, "--timeout", "600", "scan", name, "--mode", mode, "--step", step,
                      NULL),
                  0);
        snprintf(dir, 4096, "%s/%s", e->data, name);
        rms = sphere_rms(dir, &n);
        fprintf(stderr, "%s scan: %zu points, RMS %.4f mm from the sphere (at most %.2f)\n", mode,
                n, rms, RMS_MM);
        CHECK(n >= min_points);
        CHECK(rms <= RMS_MM);
        expect_mesh(dir, min_points);
}

/* time_scale 1 for continuous scans (their angles come from timed read-backs), faster for
 * stop-and-go (the rig stands still at each exposure) */
static void start(struct rigenv *e, double time_scale)
{
        rigenv_start_rig(e, args, time_scale, rig);
        json_decref(ctl_ok(e, "home", "turntable", NULL));
}

static void test_continuous(void)
{
        struct rigenv e;
        char dir[4096];

        start(&e, 1);
        /* 360 frames, about 42 points each: rows at the line's ends and kinks are not vouched
         * for (sec_add_line), and a loaded machine drops a few frames */
        scan_and_score(&e, "c1", "continuous", "1", 12000, dir);
        rigenv_stop(&e);
}

static void test_stop(void)
{
        struct rigenv e;
        char dir[4096];

        start(&e, 8);
        scan_and_score(&e, "s1", "stop", "4", 4000, dir);
        rigenv_stop(&e);
}

/* The true calibration of the rig's camera and laser into the calibration file at path: the
 * camera and turntable sections from the rig file's camera, the laser's plane through the
 * axis at azimuth_deg (the rig's 30, or a wrong one). */
static void write_calibration(const char *path, const struct rig_config *rc, double azimuth_deg,
                              bool laser)
{
        const struct rig_camera_conf *cc = &rc->cameras[0];
        struct cal_camera c = {.width = cc->width, .height = cc->height, .rms = 0.05};
        struct cal_file_turntable t = {.tt = {.rms_px = 0.05, .n_views = 9, .n_used = 9}};
        struct cal_laser l = {.rms_mm = 0.01, .n_views = 4, .n_used = 4};
        double nw[3] = {-sin(azimuth_deg * M_PI / 180), cos(azimuth_deg * M_PI / 180), 0};
        char err[1024];

        snprintf(c.camera, sizeof(c.camera), "%s", cc->name);
        c.k = (struct cal_intrinsics){.fx = cc->fx, .fy = cc->fy, .cx = cc->cx, .cy = cc->cy};
        snprintf(t.camera, sizeof(t.camera), "%s", cc->name);
        riggeom_camera_pose(cc, 0, t.tt.R, t.tt.t);
        for (int k = 0; k < 3; k++) { /* the axis and the plane in the camera frame */
                t.tt.axis[k] = t.tt.R[3 * k + 2];
                t.tt.origin[k] = t.tt.t[k];
                l.plane.n[k] = t.tt.R[3 * k] * nw[0] + t.tt.R[3 * k + 1] * nw[1];
        }
        l.plane.d =
                -(l.plane.n[0] * t.tt.t[0] + l.plane.n[1] * t.tt.t[1] + l.plane.n[2] * t.tt.t[2]);
        CHECK_INT(cal_camera_write(path, &c, true, err, sizeof(err)), 0);
        CHECK_INT(cal_turntable_write(path, &t, true, err, sizeof(err)), 0);
        if (laser)
                CHECK_INT(cal_laser_write(path, rc->lasers[0].name, cc->name, &l, "", true, err,
                                          sizeof(err)),
                          0);
}

/* gonioctl scan --from DIR with the calibration file at file (NULL: the dataset's). */
static json_t *rebuild(struct rigenv *e, const char *dir, const char *file, int want)
{
        json_t *out = NULL;

        if (file)
                CHECK_INT(
                        ctl(e, &out, "scan", "--from", dir, "--force", "--calibration", file, NULL),
                        want);
        else
                CHECK_INT(ctl(e, &out, "scan", "--from", dir, "--force", NULL), want);
        return out;
}

static void test_calibration(void)
{
        struct rig_config *rc = NULL;
        struct rigenv e;
        char dir[4096], file[4200], other[4200], err[1024];
        size_t n;
        json_t *r;

        start(&e, 8);
        scan_and_score(&e, "k1", "stop", "6", 2500, dir);
        snprintf(file, sizeof(file), "%s/rig.yaml", dir);
        CHECK_INT(rigconf_load_stored(file, registry_backends, &rc, err, sizeof(err)), 0);
        snprintf(file, sizeof(file), "%s/calibration.yaml", dir);
        write_calibration(file, rc, 30, true); /* the truth: the same shape as nominal */
        r = rebuild(&e, dir, NULL, 0);
        CHECK_STR(json_string_value(json_object_get(r, "calibration")), "calibration.yaml");
        json_decref(r);
        CHECK(sphere_rms(dir, &n) <= RMS_MM);
        write_calibration(file, rc, 31, true); /* a laser plane 1 degree off: the file is used */
        json_decref(rebuild(&e, dir, NULL, 0));
        fprintf(stderr, "laser 1 deg off: RMS %.3f mm\n", sphere_rms(dir, &n));
        CHECK(sphere_rms(dir, &n) > 3 * RMS_MM);
        json_decref(rebuild(&e, dir, "nominal", 0)); /* the rig file's geometry on request */
        CHECK(sphere_rms(dir, &n) <= RMS_MM);
        snprintf(other, sizeof(other), "%s/other.yaml", dir);
        write_calibration(other, rc, 30, false); /* no laser section: an error naming it */
        json_decref(rebuild(&e, dir, other, 6));
        rigconf_free(rc);
        rigenv_stop(&e);
}

/* The rig above with a second laser, mirrored on the camera's other side (azimuth -30) on the
 * next coil: the two lines cross on the axis. */
static char *two_laser_rig(void)
{
        static const char one[] =
                "laser: { name: laser, modbus-coil: { bus: relays, unit: 10, coil: 7 }, azimuth: "
                "30,\n         origin: [520, 300, 60], width: 0.8, power: 3.0e3, channel: red }\n";
        static const char two[] =
                "lasers:\n"
                "  - { name: left, modbus-coil: { bus: relays, unit: 10, coil: 7 }, azimuth: 30,\n"
                "      origin: [520, 300, 60], width: 0.8, power: 3.0e3, channel: red }\n"
                "  - { name: right, modbus-coil: { bus: relays, unit: 10, coil: 8 }, azimuth: "
                "-30,\n"
                "      origin: [520, -300, 60], width: 0.8, power: 3.0e3, channel: red }\n";
        const char *at = strstr(rig, one);
        char *text = malloc(sizeof(rig) + sizeof(two));

        CHECK(at && text);
        snprintf(text, sizeof(rig) + sizeof(two), "%.*s%s%s", (int)(at - rig), rig, two,
                 at + strlen(one));
        return text;
}

/* Each laser's points of dataset dir (triangulated here, with the rig file's nominal
 * geometry, as gonioctl scan did): their RMS distance from the sphere, each at least
 * min_points; the agreement gonioctl reported (res) within RMS_MM. */
static void score_lasers(const char *dir, json_t *res, size_t min_points)
{
        _cleanup_(sec_free) struct sec_ctx c = {0};
        struct rig_config *rc = NULL;
        struct scan_result out;
        struct scan_opts o;
        struct ds *d = NULL;
        double sum[2] = {0, 0}, agree;
        size_t n[2] = {0, 0};
        char err[1024];

        CHECK_INT(ds_open(dir, &d), 0);
        CHECK_INT(scan_load_rig(d, registry_backends, &rc, err, sizeof(err)), 0);
        scan_opts_default(&o);
        CHECK_INT(scan_section(d, rc, &o, NULL, &c, &out, err, sizeof(err)), 0);
        for (size_t i = 0; i < c.n_pts; i++) {
                const struct sec_point *p = &c.pts[i];
                double r = sqrt(pow(p->x[0] - SPHERE_C[0], 2) + pow(p->x[1] - SPHERE_C[1], 2) +
                                pow(p->x[2] - SPHERE_C[2], 2));

                CHECK(p->laser < 2);
                sum[p->laser] += pow(r - SPHERE_R, 2);
                n[p->laser]++;
        }
        agree = json_number_value(json_object_get(json_object_get(res, "lasers"), "agree_rms_mm"));
        for (int l = 0; l < 2; l++) {
                fprintf(stderr, "laser %s: %zu points, RMS %.4f mm from the sphere\n",
                        rc->lasers[l].name, n[l], sqrt(sum[l] / (double)MAX(n[l], 1)));
                CHECK(n[l] >= min_points);
                CHECK(sqrt(sum[l] / (double)n[l]) <= RMS_MM);
        }
        fprintf(stderr, "the lasers agree within %.4f mm RMS (%lld points matched)\n", agree,
                (long long)json_integer_value(
                        json_object_get(json_object_get(res, "lasers"), "agree_pairs")));
        CHECK(json_is_number(json_object_get(json_object_get(res, "lasers"), "agree_rms_mm")));
        CHECK(agree <= RMS_MM);
        rigconf_free(rc);
        ds_close(d);
}

/* gonioctl scan NAME in mode with the args given, then scan --from for its JSON summary;
 * each laser's points scored. */
static void scan_two(struct rigenv *e, const char *name, const char *mode, const char *from,
                     const char *to, const char *step, size_t min_points)
{
        char dir[4096];
        json_t *res = NULL;

        CHECK_INT(ctl(e, NULL, "--timeout", "600", "scan", name, "--mode", mode, "--start", from,
                      "--end", to, "--step", step, "--no-mesh", NULL),
                  0);
        snprintf(dir, sizeof(dir), "%s/%s", e->data, name);
        CHECK_INT(ctl(e, &res, "scan", "--from", dir, NULL), 0);
        score_lasers(dir, res, min_points);
        json_decref(res);
}

/* The two-laser rig at time scale ts, homed, scanned in mode over [from, to] by step. */
static void two_lasers(double ts, const char *mode, const char *from, const char *to,
                       const char *step, size_t min_points)
{
        _cleanup_free_ char *text = two_laser_rig();
        struct rigenv e;

        rigenv_start_rig(&e, args, ts, text);
        json_decref(ctl_ok(&e, "home", "turntable", NULL));
        scan_two(&e, "two", mode, from, to, step, min_points);
        rigenv_stop(&e);
}

/* Stop-and-go over a full turn, sped up (the rig stands still at each exposure). */
static void test_two_lasers(void)
{
        two_lasers(12, "stop", "0", "359", "12", 1000);
}

/* Continuous, one pass per laser, over most of a turn, so that the return to the second
 * pass goes on round, not back (rig time: angles from read-backs). The right laser sees the
 * sphere's edge only: about 510 points. */
static void test_two_lasers_continuous(void)
{
        two_lasers(1, "continuous", "0", "120", "3", 400);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"continuous", test_continuous},
                {"stop", test_stop},
                {"calibration", test_calibration},
                {"two-lasers", test_two_lasers},
                {"two-lasers-continuous", test_two_lasers_continuous},
        };

        CHECK(argc >= 4);
        args = argv;
        return TEST_RUN_CASES(cases, argc - 3, argv + 3);
}
