/* test-camera.c - camera intrinsics (calib/camera.h) against the simulator's ground truth:
 * views of a chessboard and of a ChArUco board at several poses are rendered in-process
 * (noise on), stored in a dataset, solved through the dataset library and compared with
 * the rig's true intrinsics; the shim's corners are checked against the exact board
 * geometry; bad input (board missing, too few views, a view of another camera) is rejected
 * with a reason; the calibration file keeps a better result unless forced. */
#include <math.h>
#include <sys/wait.h>

#include "calib/camera.h"
#include "common/cleanup.h"
#include "common/yconf.h"
#include "tests/dataset/ds-util.h"
#include "tests/render/rtest.h"

#define W 1280
#define H 960
static const double TRUTH[9] = {1200, 1192, 642.6, 477.4, -0.12, 0.08, 0.0011, -0.0007, -0.02};

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 35, "
        "radius: 800, azimuth: 10, intensity: 2.0e6 }\n";
static const char cam_fmt[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 25, distance: 420, azimuth: 0,\n"
        "      target: [0, 0, 60], width: 1280, height: 960, fx: 1200, fy: 1192, cx: 642.6,\n"
        "      cy: 477.4, distortion: [%g, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 "
        "}\n";

/* A board pose: left edge along the board's rows (mm), height of its top edge (mm), pitch
 * (about the board's rows), roll (in its plane) and the turntable angle (yaw), degrees. The
 * twelve poses cover the image in a 3x3 grid plus three steep ones. */
struct view {
        double dy, z, pitch, roll, tt;
};

static const struct view poses[] = {
        {-88, 132, 0, 0, 0},     {-208, 205, 20, 10, -30}, {-88, 185, -25, -15, 25},
        {32, 205, 20, 15, 35},   {-208, 132, -20, 0, 35},  {32, 132, 25, -10, -35},
        {-208, 60, -25, 15, 20}, {-88, 60, 25, 10, -20},   {32, 60, -20, -20, 30},
        {-88, 150, 35, 0, 10},   {-88, 110, -35, 5, -10},  {-150, 170, 0, 20, 40},
};

struct fixture {
        char *tmp;
        char path[512];
        struct ds *d;
        struct cal_board board;
};

static const char *board_yaml(const struct cal_board *b, char *buf, size_t len,
                              const struct view *v)
{
        snprintf(buf, len,
                 "scene:\n  seed: 7\n  targets:\n"
                 "    - { type: %s, squares: [%d, %d], square: %g, marker: %g,\n"
                 "        pose: { translate: [20, %g, %g], rotate_x: %g, rotate_y: %g, "
                 "rotate_z: 90 } }\n  turntable: { radius: 0 }\n",
                 b->type == CAL_BOARD_CHARUCO ? "charuco" : "chessboard", b->squares_x,
                 b->squares_y, b->square_mm, b->type == CAL_BOARD_CHARUCO ? b->marker_mm : 1.0,
                 v->dy, v->z, v->pitch - 90, v->roll);
        return buf;
}

static void fx_open(struct fixture *fx, const struct cal_board *b)
{
        memset(fx, 0, sizeof(*fx));
        fx->tmp = tu_tmpdir();
        fx->board = *b;
        snprintf(fx->path, sizeof(fx->path), "%s/ds", fx->tmp);
        CHECK_INT(ds_create(fx->path, "calib", "rig: test\n", &fx->d), 0);
}

static void fx_close(struct fixture *fx)
{
        ds_close(fx->d);
        tu_rm_rf(fx->tmp);
        free(fx->tmp);
}

/* Renders the board at v (scene instead when given) with a camera of radial distortion k1,
 * stores it as a capture of camera c0. */
static void add_view(struct fixture *fx, const struct view *v, const char *scene, double k1,
                     uint64_t seq)
{
        struct rtest t;
        struct gn_pose st = {{v->tt, 0, 0}, 1, false};
        struct gn_frame f;
        struct ds_capture c = {.pose = st, .camera = "c0", .lamps = "l0", .exposure_us = 20000};
        char cams[512], sc[512];

        snprintf(cams, sizeof(cams), cam_fmt, k1);
        rt_open(&t, lamps, "", cams, scene ? scene : board_yaml(&fx->board, sc, sizeof(sc), v));
        rt_render(&t, &st, NULL, seq, &f, 0, NULL);
        snprintf(sc, sizeof(sc), "view-%03d", (int)seq);
        rt_dump(&f, sc); /* RTEST_DUMP=dir keeps the views */
        CHECK_INT(ds_store(fx->d, &f, &c), 0);
        gn_frame_free_data(&f);
        rt_close(&t);
}

static void add_poses(struct fixture *fx, size_t n)
{
        for (size_t i = 0; i < n; i++)
                add_view(fx, &poses[i % ELEMENTSOF(poses)], NULL, TRUTH[4], i + 1);
}

static int solve(struct fixture *fx, struct cal_camera *out, char *err, size_t len)
{
        struct cal_camera_opts o = {.board = fx->board, .camera = "c0"};
        int r = cal_camera_solve(fx->d, &o, out, err, len);

        fprintf(stderr, "solve: %d %s\n", r, r < 0 ? err : "");
        for (size_t i = 0; i < out->n_views; i++)
                fprintf(stderr, "  view %zu: %d corners, rms %.3f px %s\n", i,
                        out->views[i].corners, out->views[i].rms, out->views[i].reason);
        if (r == 0)
                fprintf(stderr,
                        "  fx %.3f fy %.3f cx %.3f cy %.3f dist %.4f %.4f %.5f %.5f %.4f rms %.3f "
                        "(%zu of %zu views)\n",
                        out->k.fx, out->k.fy, out->k.cx, out->k.cy, out->k.dist[0], out->k.dist[1],
                        out->k.dist[2], out->k.dist[3], out->k.dist[4], out->rms, out->n_used,
                        out->n_views);
        return r;
}

/* Displacement (px, at the true focal lengths) of normalised point (x, y) by the
 * distortion k1 k2 p1 p2 k3 of d (OpenCV's model). */
static void distortion_px(const double d[5], double x, double y, double uv[2])
{
        double r2 = x * x + y * y, rad = d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;

        uv[0] = TRUTH[0] * (x * rad + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x));
        uv[1] = TRUTH[1] * (y * rad + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y);
}

/* The solved camera against the truth: RMS, intrinsics within 0.2%, and the distortion
 * within 0.5 px of the true one over the central 80% of the image. */
static void check_truth(const struct cal_camera *c)
{
        const double got[4] = {c->k.fx, c->k.fy, c->k.cx, c->k.cy};
        double worst = 0, a[2], b[2];

        CHECK(c->rms <= 0.3);
        for (int i = 0; i < 4; i++)
                CHECK_NEAR(got[i], TRUTH[i], 0.002 * TRUTH[i]);
        for (double u = 0.1 * W; u <= 0.9 * W; u += W / 32.0)
                for (double v = 0.1 * H; v <= 0.9 * H; v += H / 32.0) {
                        double x = (u - TRUTH[2]) / TRUTH[0], y = (v - TRUTH[3]) / TRUTH[1];
                        distortion_px(TRUTH + 4, x, y, a);
                        distortion_px(c->k.dist, x, y, b);
                        worst = fmax(worst, hypot(a[0] - b[0], a[1] - b[1]));
                }
        fprintf(stderr, "distortion: worst %.3f px over the central 80%%\n", worst);
        CHECK(worst < 0.5);
}

static void test_chessboard(void)
{
        struct fixture fx;
        struct cal_camera c;
        char err[512];

        fx_open(&fx, &(struct cal_board){CAL_BOARD_CHESSBOARD, 9, 7, 16, 0});
        add_poses(&fx, 12);
        CHECK_INT(solve(&fx, &c, err, sizeof(err)), 0);
        CHECK_INT(c.n_used, 12);
        check_truth(&c);
        cal_camera_clear(&c);
        fx_close(&fx);
}

static const char no_board[] = "scene:\n  seed: 7\n  object: { shape: sphere, size: 60 }\n";

/* Partial ChArUco views are used; a view without the board is rejected with its reason. */
static void test_charuco(void)
{
        static const struct view partial[] = {{-270, 132, 0, 10, 10}, {100, 110, 10, -10, -10}};
        struct fixture fx;
        struct cal_camera c;
        char err[512];
        int full = 7 * 5, n_partial = 0;

        fx_open(&fx, &(struct cal_board){CAL_BOARD_CHARUCO, 8, 6, 20, 15});
        add_poses(&fx, 10);
        for (size_t i = 0; i < ELEMENTSOF(partial); i++)
                add_view(&fx, &partial[i], NULL, TRUTH[4], 20 + i);
        add_view(&fx, &poses[0], no_board, TRUTH[4], 30);
        CHECK_INT(solve(&fx, &c, err, sizeof(err)), 0);
        CHECK_INT(c.n_views, 13);
        for (size_t i = 10; i < 12; i++) {
                CHECK(c.views[i].used);
                n_partial += c.views[i].corners < full;
        }
        CHECK_INT(n_partial, 2);
        CHECK(!c.views[12].used);
        CHECK_STR(c.views[12].reason, "board not found");
        CHECK_INT(c.n_used, 12);
        check_truth(&c);
        cal_camera_clear(&c);
        fx_close(&fx);
}

/* A view of a camera with other distortion, filed under c0, is rejected as an outlier. */
static void test_outlier(void)
{
        struct fixture fx;
        struct cal_camera c;
        char err[512];

        fx_open(&fx, &(struct cal_board){CAL_BOARD_CHESSBOARD, 9, 7, 16, 0});
        add_poses(&fx, 8);
        add_view(&fx, &poses[3], NULL, 0.3, 40);
        CHECK_INT(solve(&fx, &c, err, sizeof(err)), 0);
        CHECK_INT(c.n_used, 8);
        CHECK(!c.views[8].used);
        CHECK_STR_CONTAINS(c.views[8].reason, "reprojection RMS");
        CHECK_STR_CONTAINS(c.views[8].reason, "the median");
        CHECK(c.views[8].rms > 1.0); /* against the calibration of the other views */
        check_truth(&c);
        cal_camera_clear(&c);
        fx_close(&fx);
}

/* Too few views, and a board never found: -ENODATA with what was seen and what to do. */
static void test_too_few(void)
{
        struct fixture fx;
        struct cal_camera c;
        char err[512];

        fx_open(&fx, &(struct cal_board){CAL_BOARD_CHESSBOARD, 9, 7, 16, 0});
        add_poses(&fx, 2);
        add_view(&fx, &poses[0], no_board, TRUTH[4], 50);
        CHECK_INT(solve(&fx, &c, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "only 2 of 3 views of camera c0");
        CHECK_STR_CONTAINS(err, "need at least 3");
        CHECK_STR(c.views[2].reason, "board not found");
        cal_camera_clear(&c);
        fx_close(&fx);
}

static void test_not_found(void)
{
        struct fixture fx;
        struct cal_camera c;
        char err[512];

        fx_open(&fx, &(struct cal_board){CAL_BOARD_CHESSBOARD, 5, 4, 20, 0});
        for (int i = 0; i < 3; i++)
                add_view(&fx, &poses[i], no_board, TRUTH[4], 60 + i);
        CHECK_INT(solve(&fx, &c, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "board not found in any of 3 views of camera c0");
        CHECK_STR_CONTAINS(err, "5x4 squares, chessboard");
        cal_camera_clear(&c);
        /* an unknown camera, and a board that cannot exist */
        struct cal_camera_opts o = {.board = fx.board, .camera = "c9"};
        CHECK_INT(cal_camera_solve(fx.d, &o, &c, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, "no captures of camera c9");
        o = (struct cal_camera_opts){.board = {CAL_BOARD_CHARUCO, 12, 10, 20, 15}};
        CHECK_INT(cal_camera_solve(fx.d, &o, &c, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, "bad board");
        fx_close(&fx);
}

/* Pixel of board point (x, y) in the rendered view: target pose and camera model. */
static void truth_px(struct rtest *t, const struct gn_pose *st, double x, double y, double uv[2])
{
        struct sim_cam_geom g;
        double R[9], tt[3], w[3];

        CHECK_INT(sim_target_pose(t->s, st, 0, R, tt), 0);
        CHECK_INT(sim_camera_geom(t->s, st, 0, &g), 0);
        for (int i = 0; i < 3; i++)
                w[i] = R[i * 3] * x + R[i * 3 + 1] * y + tt[i];
        CHECK_INT(sim_cam_project(&g, w, uv), 0);
}

/* The shim's corners against the board geometry: ChArUco corners by id (the +0.5 px of
 * OpenCV 4.6 corrected), chessboard corners against the nearest true corner. */
static void check_corners(const struct cal_board *b)
{
        struct rtest t;
        struct gn_pose st = {{15, 0, 0}, 1, false};
        struct gn_frame f;
        char cams[512], sc[512];
        double uv[2 * 64], xy[2], p[2], worst = 0;
        int ids[64], n;
        const struct view v = {-88, 132, 15, 20, 0};

        snprintf(cams, sizeof(cams), cam_fmt, TRUTH[4]);
        rt_open(&t, lamps, "", cams, board_yaml(b, sc, sizeof(sc), &v));
        rt_render(&t, &st, NULL, 1, &f, 0, NULL);
        rt_dump(&f, b->type == CAL_BOARD_CHARUCO ? "corners-charuco" : "corners-chessboard");
        struct cal_image im = {f.data, f.width, f.height, f.channels, f.bits, f.stride};
        n = cal_cv_find_corners(b, &im, uv, ids, 64);
        CHECK_INT(n, cal_board_corners(b));
        for (int k = 0; k < n; k++) {
                double best = 1e9;
                for (int id = 0; id < n; id++) {
                        if (b->type == CAL_BOARD_CHARUCO && id != ids[k])
                                continue;
                        cal_board_corner_xy(b, id, xy);
                        truth_px(&t, &st, xy[0], xy[1], p);
                        best = fmin(best, hypot(uv[2 * k] - p[0], uv[2 * k + 1] - p[1]));
                }
                worst = fmax(worst, best);
        }
        fprintf(stderr, "%s: %d corners, worst %.3f px\n",
                b->type == CAL_BOARD_CHARUCO ? "charuco" : "chessboard", n, worst);
        CHECK(worst < 0.15);
        gn_frame_free_data(&f);
        rt_close(&t);
}

static void test_corners(void)
{
        check_corners(&(struct cal_board){CAL_BOARD_CHESSBOARD, 9, 7, 16, 0});
        check_corners(&(struct cal_board){CAL_BOARD_CHARUCO, 8, 6, 20, 15});
}

/* A solved-looking camera of RMS rms. */
static void fake(struct cal_camera *c, double rms, struct cal_view *views)
{
        memset(c, 0, sizeof(*c));
        snprintf(c->camera, sizeof(c->camera), "c0");
        snprintf(c->solved, sizeof(c->solved), "2026-11-30T00:00:00Z");
        snprintf(c->dataset, sizeof(c->dataset), "/data/\"odd\" name");
        c->board = (struct cal_board){CAL_BOARD_CHARUCO, 8, 6, 20, 15};
        c->width = W;
        c->height = H;
        c->k = (struct cal_intrinsics){1200.5, 1192.25, 642, 477, {-0.1, 0.05, 0, 0, 0.01}};
        c->rms = rms;
        c->n_views = 2;
        c->n_used = 1;
        views[0] = (struct cal_view){.row_id = 1, .file = "images/a.png", .used = true};
        views[1] =
                (struct cal_view){.row_id = 2, .file = "images/b.png", .reason = "board not found"};
        c->views = views;
}

/* The calibration file: other sections kept, read back, a worse result refused unless forced. */
static void test_file(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct cal_view views[2];
        struct cal_camera c, back;
        char path[512], err[512];
        FILE *f;

        snprintf(path, sizeof(path), "%s/calibration.yaml", tmp);
        f = fopen(path, "w");
        CHECK(f);
        fprintf(f, "format: gonio-calibration 1\nturntable: { axis: [0, 0, 1] }\ncameras: {}\n");
        fclose(f);
        fake(&c, 0.12, views);
        CHECK_INT(cal_camera_write(path, &c, false, err, sizeof(err)), 0);
        CHECK_INT(cal_camera_read(path, "c0", &back, err, sizeof(err)), 0);
        CHECK_NEAR(back.k.fx, 1200.5, 1e-9);
        CHECK_NEAR(back.k.dist[4], 0.01, 1e-12);
        CHECK_NEAR(back.rms, 0.12, 1e-9);
        CHECK_INT(back.n_used, 1);
        CHECK_INT(back.n_views, 2);
        CHECK_INT(back.board.type, CAL_BOARD_CHARUCO);
        CHECK_STR(back.dataset, "/data/\"odd\" name");
        /* worse: kept, unless forced; a comparable one replaces it */
        fake(&c, 0.5, views);
        CHECK_INT(cal_camera_write(path, &c, false, err, sizeof(err)), -EEXIST);
        CHECK_STR_CONTAINS(err, "kept the calibration of camera c0");
        CHECK_INT(cal_camera_read(path, "c0", &back, err, sizeof(err)), 0);
        CHECK_NEAR(back.rms, 0.12, 1e-9);
        fake(&c, 0.13, views);
        CHECK_INT(cal_camera_write(path, &c, false, err, sizeof(err)), 0);
        fake(&c, 0.5, views);
        CHECK_INT(cal_camera_write(path, &c, true, err, sizeof(err)), 0);
        CHECK_INT(cal_camera_read(path, "c0", &back, err, sizeof(err)), 0);
        CHECK_NEAR(back.rms, 0.5, 1e-9);
        CHECK_INT(cal_camera_read(path, "c1", &back, err, sizeof(err)), -ENOENT);
        /* the other section is still there */
        struct yconf yc;
        CHECK_INT(yconf_open(&yc, path, err, sizeof(err)), 0);
        CHECK(yconf_get(yconf_get(yconf_root(&yc), "turntable"), "axis"));
        yconf_close(&yc);
        tu_rm_rf(tmp);
}

/* gonioctl calibrate camera --from DATASET: the summary, the file, the errors. */
static void test_gonioctl(void)
{
        struct fixture fx;
        struct cal_camera back;
        char args[1024], out[8192], file[600], err[512];

        if (!getenv("GONIOCTL")) {
                fprintf(stderr, "GONIOCTL not set: skipped\n");
                exit(TEST_SKIP);
        }
        fx_open(&fx, &(struct cal_board){CAL_BOARD_CHESSBOARD, 9, 7, 16, 0});
        add_poses(&fx, 8);
        add_view(&fx, &poses[0], no_board, TRUTH[4], 70);
        fx.d = ds_close(fx.d);
        snprintf(args, sizeof(args), "calibrate camera --from %s --board chessboard:9x7:16",
                 fx.path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "camera c0: 1280x960, 8 views used, 1 rejected");
        CHECK_STR_CONTAINS(out, "board not found");
        CHECK_STR_CONTAINS(out, "reprojection RMS 0.0");
        snprintf(file, sizeof(file), "%s/calibration.yaml", fx.path);
        CHECK_INT(cal_camera_read(file, "c0", &back, err, sizeof(err)), 0);
        CHECK_NEAR(back.k.fx, TRUTH[0], 0.002 * TRUTH[0]);
        CHECK_INT(back.n_used, 8);
        /* --json, a board that is not there, a bad board, an unknown camera */
        snprintf(args, sizeof(args), "--json calibrate camera --from %s --board chessboard:9x7:16",
                 fx.path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "\"rms_px\":");
        snprintf(args, sizeof(args), "calibrate camera --from %s --board chessboard:6x5:16",
                 fx.path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "board not found in any of 9 views of camera c0");
        snprintf(args, sizeof(args), "calibrate camera --from %s --board chessboard:9x7", fx.path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        snprintf(args, sizeof(args),
                 "calibrate camera --from %s --board chessboard:9x7:16 --camera c7", fx.path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "no captures of camera c7");
        fx_close(&fx);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"corners", test_corners}, {"chessboard", test_chessboard},
                {"charuco", test_charuco}, {"outlier", test_outlier},
                {"too-few", test_too_few}, {"not-found", test_not_found},
                {"file", test_file},       {"gonioctl", test_gonioctl},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
