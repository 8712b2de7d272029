/* test-turntable.c - the turntable axis and the camera's pose in the turntable frame
 * (calib/turntable.h) against the simulator's ground truth: a chessboard lying on the
 * turntable is rendered in-process (noise on) at several turntable angles and the solved axis
 * is compared with the true one (the world z axis) in the camera frame; a turntable that did
 * not turn and a board that is not there are refused with a reason. */
#include <math.h>

#include "calib/turntable.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"
#include "tests/dataset/ds-util.h"
#include "tests/render/rtest.h"

#define N_ANGLES 9
static const struct cal_intrinsics K = {
        1200, 1192, 642.6, 477.4, {-0.12, 0.08, 0.0011, -0.0007, -0.02}};
static const struct cal_board BOARD = {CAL_BOARD_CHESSBOARD, 9, 6, 16, 0};

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 45, "
        "radius: 800, azimuth: 10, intensity: 2.0e6 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 40, distance: 420, azimuth: 0,\n"
        "      target: [0, 0, 0], width: 1280, height: 960, fx: 1200, fy: 1192, cx: 642.6,\n"
        "      cy: 477.4, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 "
        "}\n";
/* printed side up, its corner 40 mm from the axis */
static const char board_scene[] = "scene:\n  seed: 5\n  targets:\n"
                                  "    - { type: chessboard, squares: [9, 6], square: 16,\n"
                                  "        pose: { translate: [-40, 60, 0.5], rotate_x: 180 } }\n"
                                  "  turntable: { radius: 200, albedo: [0.2, 0.2, 0.2] }\n";
static const char empty_scene[] = "scene:\n  seed: 5\n  turntable: { radius: 200 }\n";

struct views {
        struct rtest t;
        struct gn_frame f[N_ANGLES];
        struct cal_tt_view v[N_ANGLES];
        struct sim_cam_geom g;
};

/* Renders the scene at n turntable angles from first, step apart. */
static void render(struct views *w, const char *scene, int n, double first, double step)
{
        rt_open(&w->t, lamps, "", cams, scene);
        for (int i = 0; i < n; i++) {
                struct gn_pose st = {{first + i * step, 0, 0}, 1, false};
                struct gn_frame *f = &w->f[i];
                char name[32];

                rt_render(&w->t, &st, NULL, i + 1, f, 0, NULL);
                snprintf(name, sizeof(name), "turntable-%02d", i);
                rt_dump(f, name);
                w->v[i] = (struct cal_tt_view){
                        {f->data, f->width, f->height, f->channels, f->bits, f->stride}, st.deg[0]};
        }
        CHECK_INT(sim_camera_geom(w->t.s, &(struct gn_pose){{0, 0, 0}, 1, false}, 0, &w->g), 0);
}

static void release(struct views *w, int n)
{
        for (int i = 0; i < n; i++)
                gn_frame_free_data(&w->f[i]);
        rt_close(&w->t);
}

static int solve(struct views *w, int n, struct cal_turntable *tt, char *err, size_t len)
{
        struct cal_tt_opts o = {.board = BOARD, .k = K};
        int r = cal_turntable_solve(w->v, n, &o, tt, err, len);

        fprintf(stderr, "solve: %d %s\n", r, r < 0 ? err : "");
        return r;
}

/* The axis within 0.05 deg and 0.1 mm of the truth; the origin on it in the board's plane. */
static void test_axis(void)
{
        struct views w;
        struct cal_turntable tt;
        char err[512];
        double z[3], o[3], d[3], dist, ang, top[3] = {0, 0, 0.5}, otrue[3];

        render(&w, board_scene, N_ANGLES, -40, 10);
        CHECK_INT(solve(&w, N_ANGLES, &tt, err, sizeof(err)), 0);
        for (int i = 0; i < 3; i++) {
                z[i] = w.g.R[i * 3 + 2]; /* the world z axis, in the camera frame */
                o[i] = w.g.t[i];         /* the world origin, in the camera frame */
        }
        ang = acos(fmin(cal_dot(z, tt.axis), 1)) * 180 / M_PI;
        for (int i = 0; i < 3; i++)
                d[i] = o[i] - tt.origin[i];
        double along = cal_dot(d, tt.axis);
        for (int i = 0; i < 3; i++)
                d[i] -= along * tt.axis[i];
        dist = sqrt(cal_dot(d, d));
        cal_mat_vec(w.g.R, top, otrue);
        for (int i = 0; i < 3; i++)
                otrue[i] += w.g.t[i] - tt.origin[i];
        fprintf(stderr,
                "axis: %.4f deg, %.4f mm from the truth; origin %.3f mm from (0, 0, 0.5); rms %.3f "
                "px, circle rms %.4f mm, tilt %.4f deg, span %.0f deg, %d of %d views\n",
                ang, dist, sqrt(cal_dot(otrue, otrue)), tt.rms_px, tt.circle_rms_mm, tt.tilt_deg,
                tt.span_deg, tt.n_used, tt.n_views);
        CHECK(ang < 0.05);
        CHECK(dist < 0.1);
        CHECK(sqrt(cal_dot(otrue, otrue)) < 0.2);
        CHECK(tt.rms_px < 0.08); /* the joint fit: 0.05 px; the circle fit alone: 0.1 */
        CHECK(tt.circle_rms_mm < 0.2);
        CHECK(tt.tilt_deg < 0.1);
        CHECK_NEAR(tt.span_deg, 80, 1e-9);
        release(&w, N_ANGLES);
}

/* Views at one angle (the turntable did not turn), and views without the board. */
static void test_bad(void)
{
        struct views w;
        struct cal_turntable tt;
        char err[512];

        render(&w, board_scene, 4, 20, 2);
        CHECK_INT(solve(&w, 4, &tt, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "the turntable did not turn");
        CHECK_STR_CONTAINS(err, "span 6.0 deg");
        CHECK_INT(tt.n_used, 4);
        release(&w, 4);
        render(&w, empty_scene, 3, 0, 30);
        CHECK_INT(solve(&w, 3, &tt, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "found in only 0 of 3 views");
        release(&w, 3);
        /* a symmetric chessboard */
        struct cal_tt_opts o = {.board = {CAL_BOARD_CHESSBOARD, 9, 7, 16, 0}, .k = K};
        CHECK_INT(cal_turntable_solve(w.v, 0, &o, &tt, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, "looks the same turned by 180 deg");
}

/* Through a dataset: the views stored as captures of c0 with their turntable angles (and a
 * laser-on view, not used) give the same axis; an unknown camera is refused. */
static void test_dataset(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct views w;
        struct cal_turntable a, b;
        struct cal_tt_opts o = {.board = BOARD, .k = K};
        char path[512], err[512];
        struct ds *d;

        snprintf(path, sizeof(path), "%s/ds", tmp);
        CHECK_INT(ds_create(path, "turntable", "rig: test\n", &d), 0);
        render(&w, board_scene, N_ANGLES, -40, 10);
        for (int i = 0; i < N_ANGLES; i++) {
                struct ds_capture c = {.pose = {{w.v[i].angle_deg, 0, 0}, 1, i == 4},
                                       .camera = "c0",
                                       .lamps = "l0",
                                       .exposure_us = 20000};
                CHECK_INT(ds_store(d, &w.f[i], &c), 0);
        }
        CHECK_INT(solve(&w, N_ANGLES, &a, err, sizeof(err)), 0);
        CHECK_INT(cal_turntable_solve_ds(d, "c0", &o, &b, err, sizeof(err)), 0);
        CHECK_INT(b.n_views, N_ANGLES - 1);
        CHECK(acos(fmin(cal_dot(a.axis, b.axis), 1)) * 180 / M_PI < 0.05);
        CHECK_NEAR(b.span_deg, 80, 1e-9);
        CHECK_INT(cal_turntable_solve_ds(d, "c9", &o, &b, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, "no images of camera c9");
        release(&w, N_ANGLES);
        ds_close(d);
        tu_rm_rf(tmp);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"axis", test_axis}, {"bad", test_bad}, {"dataset", test_dataset}};

        return TEST_RUN_CASES(cases, argc, argv);
}
