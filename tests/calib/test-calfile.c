/* test-calfile.c - the calibration file (calib/calfile.h): each section written and read back
 * (cameras, turntables, lasers in the turntable frame, lamps), the other sections kept,
 * a worse result kept out unless forced, a laser without its camera's turntable section,
 * and malformed files refused with where; gonioctl calibrate turntable|laser|lamps --from
 * end to end (the lamps on test-lamps' mirror-sphere scene, lampscene.h), and calibrate lamps
 * --nominal. */
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <sys/wait.h>

#include "calib/calfile.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/riggeom.h"
#include "tests/calib/lampscene.h"
#include "tests/dataset/ds-util.h"
#include "tests/render/rtest.h"

struct fixture {
        char *tmp;
        char path[512];
        char err[1024];
        struct cal_file *f;
};

static void fx_open(struct fixture *fx)
{
        fx->tmp = tu_tmpdir();
        snprintf(fx->path, sizeof(fx->path), "%s/calibration.yaml", fx->tmp);
        fx->f = malloc(sizeof(*fx->f));
        CHECK(fx->f);
}

static void fx_close(struct fixture *fx)
{
        tu_rm_rf(fx->tmp);
        free(fx->tmp);
        free(fx->f);
}

static void write_text(const char *path, const char *text)
{
        FILE *f = fopen(path, "w");

        CHECK(f);
        fputs(text, f);
        CHECK(fclose(f) == 0);
}

/* A camera c0 looking down 30 deg at the turntable from 400 mm (a proper rotation). */
static struct cal_file_turntable turntable(double rms)
{
        const double c = cos(M_PI / 3), s = sin(M_PI / 3);
        struct cal_file_turntable t = {.camera = "c0",
                                       .dataset = "/data/tt",
                                       .board = {CAL_BOARD_CHESSBOARD, 9, 6, 16, 0},
                                       .tt = {.R = {1, 0, 0, 0, -c, -s, 0, s, -c},
                                              .t = {2, 30, 400},
                                              .rms_px = rms,
                                              .circle_rms_mm = 0.015,
                                              .tilt_deg = 0.02,
                                              .span_deg = 80,
                                              .n_views = 9,
                                              .n_used = 8}};

        /* the axis is R's third column, the origin t */
        for (int i = 0; i < 3; i++) {
                t.tt.axis[i] = t.tt.R[3 * i + 2];
                t.tt.origin[i] = t.tt.t[i];
        }
        return t;
}

/* The plane x_tt = 0 (contains the axis) in c0's frame of turntable(). */
static struct cal_laser laser(const struct cal_file_turntable *t, double rms)
{
        struct cal_laser l = {.rms_mm = rms,
                              .spread_mm = 40,
                              .points = 900,
                              .inliers = 880,
                              .n_views = 5,
                              .n_used = 4};

        for (int i = 0; i < 3; i++)
                l.plane.n[i] = t->tt.R[3 * i]; /* R e_x */
        l.plane.d = -(l.plane.n[0] * t->tt.t[0] + l.plane.n[1] * t->tt.t[1] +
                      l.plane.n[2] * t->tt.t[2]);
        return l;
}

static void read_ok(struct fixture *fx)
{
        int r = cal_file_read(fx->path, fx->f, fx->err, sizeof(fx->err));

        if (r < 0)
                fprintf(stderr, "%s\n", fx->err);
        CHECK_INT(r, 0);
}

/* Every section written, read back, the others kept. */
static void test_sections(void)
{
        struct fixture fx;
        struct cal_file_turntable t = turntable(0.05);
        struct cal_laser l = laser(&t, 0.03);
        struct cal_lamp_pos lamp = {"l0", {300, -20, 500}, 0.4, 6, 1.5};
        const struct cal_file_turntable *tb;
        const struct cal_file_laser *lb;
        const struct cal_lamp_pos *pb;

        fx_open(&fx);
        write_text(fx.path, "format: gonio-calibration 1\nnotes: { by: hand }\n");
        CHECK_INT(cal_turntable_write(fx.path, &t, false, fx.err, sizeof(fx.err)), 0);
        CHECK_INT(cal_laser_write(fx.path, "laser", "c0", &l, "/data/lp", false, fx.err,
                                  sizeof(fx.err)),
                  0);
        CHECK_INT(cal_lamp_write(fx.path, &lamp, false, fx.err, sizeof(fx.err)), 0);
        read_ok(&fx);
        CHECK_INT(fx.f->n_turntables, 1);
        CHECK_INT(fx.f->n_lasers, 1);
        CHECK_INT(fx.f->n_lamps, 1);
        CHECK_INT(fx.f->n_cameras, 0);
        tb = cal_file_turntable(fx.f, "c0");
        CHECK(tb && !cal_file_turntable(fx.f, "c1"));
        for (int i = 0; i < 9; i++)
                CHECK_NEAR(tb->tt.R[i], t.tt.R[i], 1e-9);
        CHECK_NEAR(tb->tt.t[2], 400, 1e-9);
        CHECK_NEAR(tb->tt.axis[1], t.tt.axis[1], 1e-9);
        CHECK_NEAR(tb->tt.rms_px, 0.05, 1e-9);
        CHECK_NEAR(tb->tt.span_deg, 80, 1e-9);
        CHECK_INT(tb->tt.n_used, 8);
        CHECK_INT(tb->tt.n_views, 9);
        CHECK_INT(tb->board.squares_y, 6);
        CHECK_STR(tb->dataset, "/data/tt");
        CHECK(strlen(tb->solved) == 20);
        /* the laser in the turntable frame: x = 0, on the axis */
        lb = cal_file_laser(fx.f, "laser");
        CHECK(lb);
        CHECK_STR(lb->camera, "c0");
        CHECK_NEAR(fabs(lb->plane.n[0]), 1, 1e-9);
        CHECK_NEAR(lb->plane.d, 0, 1e-9);
        CHECK_NEAR(lb->axis_angle_deg, 0, 1e-6);
        CHECK_NEAR(lb->axis_dist_mm, 0, 1e-6);
        CHECK_NEAR(lb->rms_mm, 0.03, 1e-9);
        CHECK_INT(lb->inliers, 880);
        CHECK_INT(lb->n_used, 4);
        pb = cal_file_lamp(fx.f, "l0");
        CHECK(pb && !cal_file_lamp(fx.f, "l1"));
        CHECK_NEAR(pb->pos[2], 500, 1e-9);
        CHECK_INT(pb->n_obs, 6);
        CHECK_NEAR(pb->nominal_dist_mm, 1.5, 1e-9);
        /* the section nobody knows is still there */
        struct yconf yc;
        CHECK_INT(cal_file_open(&yc, fx.path, false, fx.err, sizeof(fx.err)), 0);
        CHECK(yconf_get(yconf_get(yconf_root(&yc), "notes"), "by"));
        yconf_close(&yc);
        fx_close(&fx);
}

/* A worse result is kept out unless forced, for each kind. */
static void test_never_worse(void)
{
        struct fixture fx;
        struct cal_file_turntable t = turntable(0.05), worse = turntable(0.5);
        struct cal_laser l = laser(&t, 0.03), lworse = laser(&t, 0.3);
        struct cal_lamp_pos lamp = {"l0", {300, -20, 500}, 0.4, 6, 1.5}, lamp2 = lamp;

        fx_open(&fx);
        CHECK_INT(cal_turntable_write(fx.path, &t, false, fx.err, sizeof(fx.err)), 0);
        CHECK_INT(cal_turntable_write(fx.path, &worse, false, fx.err, sizeof(fx.err)), -EEXIST);
        CHECK_STR_CONTAINS(fx.err, "kept the calibration of the turntable seen by camera c0");
        CHECK_STR_CONTAINS(fx.err, "(RMS 0.050 px from 8 views)");
        CHECK_INT(cal_laser_write(fx.path, "laser", "c0", &l, "", false, fx.err, sizeof(fx.err)),
                  0);
        CHECK_INT(
                cal_laser_write(fx.path, "laser", "c0", &lworse, "", false, fx.err, sizeof(fx.err)),
                -EEXIST);
        CHECK_STR_CONTAINS(fx.err, "RMS 0.300 mm from 4 views");
        lamp2.rms_mm = 2;
        CHECK_INT(cal_lamp_write(fx.path, &lamp, false, fx.err, sizeof(fx.err)), 0);
        CHECK_INT(cal_lamp_write(fx.path, &lamp2, false, fx.err, sizeof(fx.err)), -EEXIST);
        read_ok(&fx);
        CHECK_NEAR(cal_file_turntable(fx.f, "c0")->tt.rms_px, 0.05, 1e-9);
        CHECK_NEAR(cal_file_laser(fx.f, "laser")->rms_mm, 0.03, 1e-9);
        CHECK_NEAR(cal_file_lamp(fx.f, "l0")->rms_mm, 0.4, 1e-9);
        /* forced */
        CHECK_INT(cal_turntable_write(fx.path, &worse, true, fx.err, sizeof(fx.err)), 0);
        CHECK_INT(
                cal_laser_write(fx.path, "laser", "c0", &lworse, "", true, fx.err, sizeof(fx.err)),
                0);
        CHECK_INT(cal_lamp_write(fx.path, &lamp2, true, fx.err, sizeof(fx.err)), 0);
        read_ok(&fx);
        CHECK_NEAR(cal_file_turntable(fx.f, "c0")->tt.rms_px, 0.5, 1e-9);
        CHECK_NEAR(cal_file_laser(fx.f, "laser")->rms_mm, 0.3, 1e-9);
        CHECK_NEAR(cal_file_lamp(fx.f, "l0")->rms_mm, 2, 1e-9);
        fx_close(&fx);
}

/* A laser needs its camera's turntable section; the file is not touched without it. */
static void test_laser_first(void)
{
        struct fixture fx;
        struct cal_file_turntable t = turntable(0.05);
        struct cal_laser l = laser(&t, 0.03);

        fx_open(&fx);
        CHECK_INT(cal_laser_write(fx.path, "laser", "c0", &l, "", false, fx.err, sizeof(fx.err)),
                  -ENOENT);
        CHECK_STR_CONTAINS(fx.err, "no turntable calibration of camera c0");
        CHECK_STR_CONTAINS(fx.err, "calibrate the turntable first");
        CHECK(access(fx.path, F_OK) < 0);
        CHECK_INT(cal_turntable_write(fx.path, &t, false, fx.err, sizeof(fx.err)), 0);
        CHECK_INT(cal_laser_write(fx.path, "laser", "c1", &l, "", false, fx.err, sizeof(fx.err)),
                  -ENOENT);
        CHECK_STR_CONTAINS(fx.err, "camera c1");
        read_ok(&fx);
        CHECK_INT(fx.f->n_lasers, 0);
        fx_close(&fx);
}

/* Malformed files: -EBADMSG with file, line and key; never overwritten. */
static void test_malformed(void)
{
        static const struct {
                const char *text, *where;
        } bad[] = {
                {"cameras: {}\n", "key 'format': not a calibration file"},
                {"format: gonio-calibration 2\n", ":1: key 'format'"},
                {"format: gonio-calibration 1\nturntables: [1, 2]\n", ":2: key 'turntables'"},
                {"format: gonio-calibration 1\nlasers:\n  laser:\n    camera: c0\n    n: [1, 0]\n",
                 ":5: key 'n'"},
                {"format: gonio-calibration 1\nlamps:\n  l0: { position_mm: [1, 2, 3] }\n",
                 "key 'rms_mm': missing"},
                {"format: gonio-calibration 1\ncameras:\n  c0: { fx: [1] }\n", "key 'board'"},
                {"format: gonio-calibration 1\ncameras: { c0: {\n", "YAML syntax error"},
        };
        struct fixture fx;
        struct cal_lamp_pos lamp = {"l0", {300, -20, 500}, 0.4, 6, 1.5};

        fx_open(&fx);
        CHECK_INT(cal_file_read(fx.path, fx.f, fx.err, sizeof(fx.err)), -ENOENT);
        for (size_t i = 0; i < ELEMENTSOF(bad); i++) {
                _cleanup_free_ void *before = NULL, *after = NULL;
                size_t n1, n2;

                write_text(fx.path, bad[i].text);
                CHECK_INT(cal_file_read(fx.path, fx.f, fx.err, sizeof(fx.err)), -EBADMSG);
                fprintf(stderr, "%s\n", fx.err);
                CHECK_STR_CONTAINS(fx.err, fx.path);
                CHECK_STR_CONTAINS(fx.err, bad[i].where);
                /* a write refuses a file that is not a calibration file, and leaves it */
                if (i >= 3 && i < ELEMENTSOF(bad) - 1)
                        continue;
                CHECK_INT(gn_read_file_at(AT_FDCWD, fx.path, 1 << 20, &before, &n1), 0);
                CHECK_INT(cal_lamp_write(fx.path, &lamp, false, fx.err, sizeof(fx.err)), -EBADMSG);
                CHECK_INT(gn_read_file_at(AT_FDCWD, fx.path, 1 << 20, &after, &n2), 0);
                CHECK(n1 == n2 && memcmp(before, after, n1) == 0);
        }
        fx_close(&fx);
}

/* ---- gonioctl calibrate turntable|laser --from, on views rendered here ---- */

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 35, "
        "radius: 800, azimuth: 20, intensity: 1.5e6 }\n";
static const char laser_yaml[] =
        "laser: { name: line, modbus-coil: { bus: relays, coil: 7 }, azimuth: 0,\n"
        "         origin: [600, 0, 70], width: 0.5, power: 2.0e3, channel: red }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 20, distance: 420, azimuth: 40,\n"
        "      target: [0, 0, 70], width: 1280, height: 960, fx: 1200, fy: 1192, cx: 642.6,\n"
        "      cy: 477.4, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 "
        "}\n";

/* Renders the 9x6 board (16 mm squares) at translate x, y, z, turned rotate_x (-90: standing,
 * facing +x; -135: tilted 45 deg up) at turntable angle tt, the laser on or off, into dataset
 * d as lit by the lasers of bit set `as` (the rendered laser's frame stored as another
 * laser's: two lasers of one plane); the world z axis in the camera frame into axis (may be
 * NULL). */
static void store_view(struct ds *d, const double pose[4], double tt, bool laser, uint32_t as,
                       double axis[3])
{
        struct gn_pose st = {{tt, 0, 0}, 1, laser};
        struct ds_capture c = {.pose = st, .camera = "c0", .lamps = "l0", .exposure_us = 20000};
        struct sim_cam_geom g;
        struct gn_frame f;
        struct rtest t;
        char scene[512];

        snprintf(scene, sizeof(scene),
                 "scene:\n  seed: 9\n  targets:\n"
                 "    - { type: chessboard, squares: [9, 6], square: 16,\n"
                 "        pose: { translate: [%g, %g, %g], rotate_x: %g, rotate_z: 90 } }\n"
                 "  turntable: { radius: 0 }\n  sensor: { black_level: 0.02 }\n",
                 pose[0], pose[1], pose[2], pose[3]);
        rt_open(&t, lamps, laser_yaml, cams, scene);
        rt_render(&t, &st, NULL, 1, &f, 0, NULL);
        c.pose.lasers = laser ? as : 0;
        CHECK_INT(ds_store(d, &f, &c), 0);
        CHECK_INT(sim_camera_geom(t.s, &(struct gn_pose){{0, 0, 0}, 1, false}, 0, &g), 0);
        for (int i = 0; axis && i < 3; i++)
                axis[i] = g.R[i * 3 + 2];
        gn_frame_free_data(&f);
        rt_close(&t);
}

/* test_run_gonioctl with its arguments formatted from fmt. */
static int gonioctl(char *out, size_t len, const char *fmt, ...)
{
        char args[2048];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(args, sizeof(args), fmt, ap);
        va_end(ap);
        return test_run_gonioctl(args, out, len);
}

/* A dataset at dir/name made of views of the tilted board at 9 turntable angles 7.5 deg
 * apart (all at angle 0 when still), or of the standing board at 5 poses, laser off, laser
 * `line` on and laser `line2` on (the rig of the dataset has two lasers of one plane). */
static void make_dataset(const char *dir, const char *name, char kind, double axis[3])
{
        static const double standing[5][4] = {{20, -72, 120, -90},
                                              {-10, -72, 120, -75},
                                              {50, -72, 120, -105},
                                              {-40, -72, 120, -70},
                                              {60, -72, 120, -80}};
        static const double tilted[4] = {10, -72, 110, -135};
        static const double tt[5] = {0, 15, -10, 0, 30};
        char path[600], rig[2048];
        struct ds *d;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        snprintf(rig, sizeof(rig),
                 "rig: test\nbuses:\n  - { name: relays, type: modbus-rtu, port: /dev/null }\n"
                 "  - { name: frames, type: sim, port: /tmp/f.sock }\n%slasers:\n"
                 "  - { name: line, channel: red, modbus-coil: { bus: relays, coil: 7 } }\n"
                 "  - { name: line2, channel: red, modbus-coil: { bus: relays, coil: 8 } }\n",
                 cams);
        CHECK_INT(ds_create(path, name, rig, &d), 0);
        for (int i = 0; kind != 'l' && i < 9; i++)
                store_view(d, tilted, kind == 's' ? 0 : -30 + 7.5 * i, false, 0, axis);
        for (int i = 0; kind == 'l' && i < 5; i++)
                for (int on = 0; on < 3; on++)
                        store_view(d, standing[i], tt[i], on > 0, on, NULL);
        ds_close(d);
}

/* The turntable, then the laser, solved by gonioctl from datasets and written into the
 * file (two lasers of one plane: both solved from their own rows and refined jointly); the
 * errors of a missing camera section, a turntable that did not turn. */
static void test_gonioctl(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir(), *before = NULL, *after = NULL;
        struct cal_file *f = malloc(sizeof(*f));
        char out[8192], file[600], err[1024];
        const struct cal_file_turntable *t;
        const struct cal_file_laser *l;
        size_t n1, n2;
        double axis[3];

        if (!getenv("GONIOCTL")) {
                fprintf(stderr, "GONIOCTL not set: skipped\n");
                exit(TEST_SKIP);
        }
        make_dataset(tmp, "tt", 't', axis);
        make_dataset(tmp, "lp", 'l', NULL);
        make_dataset(tmp, "still", 's', NULL);
        snprintf(file, sizeof(file), "%s/tt/calibration.yaml", tmp);
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate turntable --from %s/tt --board "
                           "chessboard:9x6:16",
                           tmp),
                  6);
        CHECK_STR_CONTAINS(out, "no intrinsics of camera c0");
        CHECK_STR_CONTAINS(out, "run gonioctl calibrate camera first");
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate camera --from %s/tt --board "
                           "chessboard:9x6:16",
                           tmp),
                  0);
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate laser --from %s/lp --board "
                           "chessboard:9x6:16 --calibration %s",
                           tmp, file),
                  6);
        CHECK_STR_CONTAINS(out, "calibrate the turntable first");
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate turntable --from %s/tt --board "
                           "chessboard:9x6:16",
                           tmp),
                  0);
        CHECK_STR_CONTAINS(out, "turntable seen by camera c0: board found in 9 of 9 views over "
                                "60.0 deg");
        CHECK_STR_CONTAINS(out, "written to ");
        CHECK_INT(gonioctl(out, sizeof(out),
                           "--json calibrate laser --from %s/lp --board "
                           "chessboard:9x6:16 --calibration %s",
                           tmp, file),
                  0);
        CHECK_STR_CONTAINS(out, "\"laser\":\"line\"");
        CHECK_STR_CONTAINS(out, "\"axis_dist_mm\":");
        /* both lasers solved from their own rows, the joint refinement reported */
        CHECK_STR_CONTAINS(out, "\"laser\":\"line2\"");
        CHECK_STR_CONTAINS(out, "\"joint\":{\"refined\":true"); /* the clouds overlap */
        CHECK_INT(cal_file_read(file, f, err, sizeof(err)), 0);
        t = cal_file_turntable(f, "c0");
        l = cal_file_laser(f, "line");
        CHECK(t && l && cal_file_camera(f, "c0"));
        CHECK(cal_file_laser(f, "line2"));
        CHECK_NEAR(cal_file_laser(f, "line2")->plane.n[0], l->plane.n[0], 1e-6); /* one plane */
        CHECK_NEAR(cal_file_laser(f, "line2")->plane.d, l->plane.d, 1e-6);
        fprintf(stderr, "axis %.4f deg from the truth; laser %.4f deg, %.4f mm from the axis\n",
                acos(fmin(cal_dot(axis, t->tt.axis), 1)) * 180 / M_PI, l->axis_angle_deg,
                l->axis_dist_mm);
        CHECK(acos(fmin(cal_dot(axis, t->tt.axis), 1)) * 180 / M_PI < 0.2);
        CHECK(fabs(l->axis_angle_deg) < 0.2 && fabs(l->axis_dist_mm) < 0.5);
        CHECK_NEAR(fabs(l->plane.n[2]), 0, 0.005); /* contains the axis: vertical */
        /* the turntable that did not turn: said, and the file kept as it was */
        CHECK_INT(gn_read_file_at(AT_FDCWD, file, 1 << 20, (void **)&before, &n1), 0);
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate turntable --from %s/still --board "
                           "chessboard:9x6:16 --calibration %s --force",
                           tmp, file),
                  6);
        CHECK_STR_CONTAINS(out, "the turntable did not turn");
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate turntable --from %s/tt --board "
                           "chessboard:6x5:16 --calibration %s --force",
                           tmp, file),
                  6);
        CHECK_INT(gn_read_file_at(AT_FDCWD, file, 1 << 20, (void **)&after, &n2), 0);
        CHECK(n1 == n2 && memcmp(before, after, n1) == 0);
        free(f);
        tu_rm_rf(tmp);
}

/* ---- gonioctl calibrate lamps, on test-lamps' mirror-sphere scene ---- */

/* The cameras' true calibration of fx written as their camera and turntable sections of the
 * file at path; c1's turntable section left out when !c1_pose. */
static void write_true_cameras(const struct ls_fixture *fx, const char *path, bool c1_pose)
{
        char err[512];

        for (int i = 0; i < 2; i++) {
                const struct sec_camera *s = &fx->cams[i].cal;
                struct cal_camera c = {.board = {CAL_BOARD_CHESSBOARD, 9, 6, 16, 0},
                                       .width = s->width,
                                       .height = s->height,
                                       .k = s->k,
                                       .rms = 0.1};
                struct cal_file_turntable tt = {.board = c.board, .tt = {.rms_px = 0.1}};
                snprintf(c.camera, sizeof(c.camera), "%s", fx->cams[i].name);
                snprintf(tt.camera, sizeof(tt.camera), "%s", fx->cams[i].name);
                memcpy(tt.tt.R, s->R, sizeof(s->R));
                memcpy(tt.tt.t, s->t, sizeof(s->t));
                CHECK_INT(cal_camera_write(path, &c, true, err, sizeof(err)), 0);
                if (i == 0 || c1_pose)
                        CHECK_INT(cal_turntable_write(path, &tt, true, err, sizeof(err)), 0);
        }
}

/* Every lamp of the file within LS_TOL_MM of the truth, measured (n_obs > 0). */
static void check_file_lamps(const struct ls_fixture *fx, const char *path)
{
        _cleanup_free_ struct cal_file *f = malloc(sizeof(*f));
        char err[512];

        CHECK(f);
        CHECK_INT(cal_file_read(path, f, err, sizeof(err)), 0);
        for (size_t i = 0; i < fx->t.rc->n_lamps; i++) {
                const struct cal_lamp_pos *l = cal_file_lamp(f, fx->t.rc->lamps[i].name);
                CHECK(l);
                double e = ls_lamp_error(fx, (int)i, l->pos);
                fprintf(stderr, "lamp %s: %.3f mm from the truth, %d rays\n", l->name, e, l->n_obs);
                CHECK(e <= LS_TOL_MM);
                CHECK(l->n_obs >= 2 * LS_ANGLES * 3 / 4);
        }
}

/* The lamps solved by gonioctl from a dataset of the sphere and written into the file; the
 * errors of no calibration file, a camera without its pose, no sphere, a lamp never lit. */
static void test_gonioctl_lamps(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct ls_fixture fx, empty;
        char out[8192], ds[600], file[700];

        if (!getenv("GONIOCTL")) {
                fprintf(stderr, "GONIOCTL not set: skipped\n");
                exit(TEST_SKIP);
        }
        ls_open(&fx, ls_scene_sphere, 30);
        snprintf(ds, sizeof(ds), "%s/sphere", tmp);
        snprintf(file, sizeof(file), "%s/calibration.yaml", ds);
        ds_close(ls_make_dataset(&fx, ds, LS_ANGLES, 3, -1));
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --from %s --sphere 100", ds), 6);
        CHECK_STR_CONTAINS(out, "no calibration file");
        CHECK_STR_CONTAINS(out, "run gonioctl calibrate camera and turntable");
        write_true_cameras(&fx, file, false);
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --from %s --sphere 100", ds), 6);
        CHECK_STR_CONTAINS(out, "no section turntables.c1");
        CHECK_STR_CONTAINS(out, "run gonioctl calibrate turntable");
        write_true_cameras(&fx, file, true);
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --from %s", ds), 2);
        CHECK_STR_CONTAINS(out, "needs --sphere DIAMETER");
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate lamps --from %s --sphere 100 --lamp-radius 30", ds),
                  0);
        CHECK_STR_CONTAINS(out, "of 96 views used");
        CHECK_STR_CONTAINS(out, "mirror sphere: centre [70.0");
        CHECK_STR_CONTAINS(out, "l2 (measured): position [");
        CHECK_STR_CONTAINS(out, "mm from nominal");
        check_file_lamps(&fx, file);
        /* the same again, --json: not worse, written */
        CHECK_INT(gonioctl(out, sizeof(out),
                           "--json calibrate lamps --from %s --sphere 100 --lamp-radius 30", ds),
                  0);
        CHECK_STR_CONTAINS(out, "\"lamp\":\"l0\"");
        CHECK_STR_CONTAINS(out, "\"source\":\"measured\"");
        CHECK_STR_CONTAINS(out, "\"failed\":[]");
        /* nominal over measured: kept unless --force */
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --nominal --from %s", ds), 0);
        CHECK_STR_CONTAINS(out, "l1 (measured)");
        check_file_lamps(&fx, file);
        /* no sphere, then a lamp never lit: the others solved and written, then exit 6 */
        ls_open(&empty, ls_scene_empty, 30);
        snprintf(ds, sizeof(ds), "%s/empty", tmp);
        ds_close(ls_make_dataset(&empty, ds, 2, 3, -1));
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate lamps --from %s --sphere 100 --calibration %s", ds, file),
                  6);
        CHECK_STR_CONTAINS(out, "found in none of the 12 views");
        CHECK_STR_CONTAINS(out, "bright even background");
        CHECK_STR_CONTAINS(out, "50 to 150 mm off its axis");
        snprintf(ds, sizeof(ds), "%s/two", tmp);
        ds_close(ls_make_dataset(&fx, ds, LS_ANGLES / 2, 2, -1));
        CHECK_INT(gonioctl(out, sizeof(out),
                           "calibrate lamps --from %s --sphere 100 --calibration %s --force", ds,
                           file),
                  6);
        CHECK_STR_CONTAINS(out, "l0 (measured)");
        CHECK_STR_CONTAINS(out, "l2: failed: never lit alone in the dataset");
        CHECK_STR_CONTAINS(out, "capture each lamp alone");
        ls_close(&empty);
        ls_close(&fx);
        tu_rm_rf(tmp);
}

/* --nominal from a rig file: each lamp's rig-file position with no observations, over
 * nominal ones but not over a measured one unless --force. */
static void test_nominal(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct ls_fixture fx;
        struct cal_file *f = malloc(sizeof(*f));
        struct cal_lamp_pos m = {.name = "l1", .pos = {1, 2, 3}, .rms_mm = 0.2, .n_obs = 30};
        char out[8192], file[600], err[512];
        double nom[3];

        if (!getenv("GONIOCTL")) {
                fprintf(stderr, "GONIOCTL not set: skipped\n");
                exit(TEST_SKIP);
        }
        ls_open(&fx, ls_scene_sphere, 30);
        snprintf(file, sizeof(file), "%s/cal.yaml", tmp);
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --nominal %s", fx.t.path), 6);
        CHECK_STR_CONTAINS(out, "names no calibration file");
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --nominal"), 2);
        CHECK_INT(cal_lamp_write(file, &m, false, err, sizeof(err)), 0);
        CHECK_INT(gonioctl(out, sizeof(out), "calibrate lamps --nominal %s --calibration %s",
                           fx.t.path, file),
                  0);
        CHECK_STR_CONTAINS(out, "l0 (nominal, from the rig file)");
        CHECK_STR_CONTAINS(out, "l1 (measured)");
        CHECK_INT(cal_file_read(file, f, err, sizeof(err)), 0);
        CHECK_INT(cal_file_lamp(f, "l1")->n_obs, 30);
        riggeom_lamp_position(&fx.t.rc->lamps[2], 0, nom);
        CHECK_INT(cal_file_lamp(f, "l2")->n_obs, 0);
        CHECK_NEAR(cal_file_lamp(f, "l2")->rms_mm, 0, 1e-9);
        for (int k = 0; k < 3; k++)
                CHECK_NEAR(cal_file_lamp(f, "l2")->pos[k], nom[k], 1e-3);
        CHECK_INT(gonioctl(out, sizeof(out),
                           "--json calibrate lamps --nominal %s --calibration %s --force",
                           fx.t.path, file),
                  0);
        CHECK_STR_CONTAINS(out, "{\"lamp\":\"l1\",\"source\":\"nominal\"");
        CHECK_INT(cal_file_read(file, f, err, sizeof(err)), 0);
        CHECK_INT(cal_file_lamp(f, "l1")->n_obs, 0);
        free(f);
        ls_close(&fx);
        tu_rm_rf(tmp);
}

/* The rig file's key calibration: relative to the rig file's directory, absolute as is,
 * ${VAR} expanded; an empty path refused with file, line and key. */
static void test_rigkey(void)
{
        static const struct {
                const char *value, *want;
        } cases[] = {
                {"cal/rig.yaml", "/tmp/cal/rig.yaml"},
                {"/var/lib/gonio/c.yaml", "/var/lib/gonio/c.yaml"},
                {"${CALFILE_TEST_DIR}/c.yaml", "/tmp/d/c.yaml"},
                {"", NULL},
        };
        struct rtest t;
        char scene[256], err[512];

        setenv("CALFILE_TEST_DIR", "d", 1);
        for (size_t i = 0; i < ELEMENTSOF(cases); i++) {
                snprintf(scene, sizeof(scene), "calibration: \"%s\"\n", cases[i].value);
                int r = rt_try_open(&t, lamps, "", cams, scene, err, sizeof(err));

                if (cases[i].want) {
                        CHECK_INT(r, 0);
                        CHECK_STR(t.rc->calibration, cases[i].want);
                } else {
                        CHECK_INT(r, -EINVAL);
                        CHECK_STR_CONTAINS(err, ".yaml:14: key 'calibration': empty path");
                }
                rt_close(&t);
        }
        /* no key: none */
        rt_open(&t, lamps, "", cams, "");
        CHECK_STR(t.rc->calibration, "");
        rt_close(&t);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"sections", test_sections},
                {"never-worse", test_never_worse},
                {"laser-first", test_laser_first},
                {"malformed", test_malformed},
                {"gonioctl", test_gonioctl},
                {"rigkey", test_rigkey},
                {"gonioctl-lamps", test_gonioctl_lamps},
                {"nominal", test_nominal},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
