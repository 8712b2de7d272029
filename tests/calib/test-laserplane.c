/* test-laserplane.c - laser planes (calib/laserplane.h) against the simulator's ground
 * truth: a chessboard standing on the turntable at several poses is rendered in-process
 * (noise on) with the lamp, and with the lamp and the laser; the solved plane is compared
 * with the rig's true laser plane in the camera frame. Two lasers (two rigs, the lasers
 * at azimuths 0 and 20) are compared with each other and with the axis; a laser that is off
 * or misses the board is refused with what each view showed. */
#include <math.h>

#include "calib/laserplane.h"
#include "calib/turntable_geom.h"
#include "common/cleanup.h"
#include "tests/dataset/ds-util.h"
#include "tests/render/rtest.h"

#define N_POSES 5
static const struct cal_intrinsics K = {
        1200, 1192, 642.6, 477.4, {-0.12, 0.08, 0.0011, -0.0007, -0.02}};
static const struct cal_board BOARD = {CAL_BOARD_CHESSBOARD, 9, 6, 16, 0};

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 35, "
        "radius: 800, azimuth: 20, intensity: 1.5e6 }\n";
static const char laser_fmt[] =
        "laser: { name: laser, modbus-coil: { bus: relays, coil: 7 }, azimuth: %g,\n"
        "         origin: [%g, %g, 70], width: 0.5, power: 2.0e3, channel: red }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 20, distance: 420, azimuth: 40,\n"
        "      target: [0, 0, 70], width: 1280, height: 960, fx: 1200, fy: 1192, cx: 642.6,\n"
        "      cy: 477.4, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 "
        "}\n";

/* A board standing on the turntable facing +x: its distance from the axis (mm), its left
 * edge along y (mm), its pitch and the turntable angle (deg). */
struct pose {
        double x, y, pitch, tt;
};

static const struct pose poses[N_POSES] = {
        {20, -72, 0, 0},   {-10, -72, 15, 15}, {50, -72, -15, -10},
        {-40, -72, 20, 0}, {60, -72, 10, 30},
};
/* the laser misses the board: it stands beside the laser plane */
static const struct pose beside[3] = {{20, 40, 0, 0}, {0, 40, 10, 0}, {30, 40, -10, 0}};

struct views {
        struct gn_frame off[N_POSES], on[N_POSES];
        struct gn_frame dark[N_POSES]; /* the laser on, the lamp off (a session's laser frame) */
        struct cal_lp_view v[N_POSES];
        struct cal_plane truth;    /* in the camera frame */
        struct cal_turntable axis; /* the true axis, in the camera frame */
        struct sim_cam_geom g;
};

/* The true laser plane and axis in the camera's frame. */
static void truth(struct rtest *t, struct views *w)
{
        struct sim_cam_geom g;
        double n[3], d;

        CHECK_INT(sim_camera_geom(t->s, &(struct gn_pose){{0, 0, 0}, 1, false}, 0, &g), 0);
        w->g = g;
        CHECK_INT(sim_laser_plane(t->s, 0, n, &d), 0);
        cal_mat_vec(g.R, n, w->truth.n);
        w->truth.d = d - cal_dot(w->truth.n, g.t);
        for (int i = 0; i < 3; i++) {
                w->axis.axis[i] = g.R[i * 3 + 2];
                w->axis.origin[i] = g.t[i];
        }
}

/* Renders the board at pose p off and on (the laser at azimuth az; lit when laser). */
static void render_pose(struct views *w, int i, const struct pose *p, double az, bool laser)
{
        struct rtest t;
        char scene[512], las[512], name[32];
        struct gn_pose off = {{p->tt, 0, 0}, 1, false}, on = {{p->tt, 0, 0}, 1, laser};

        snprintf(scene, sizeof(scene),
                 "scene:\n  seed: 9\n  targets:\n"
                 "    - { type: chessboard, squares: [9, 6], square: 16,\n"
                 "        pose: { translate: [%g, %g, 120], rotate_x: %g, rotate_z: 90 } }\n"
                 "  turntable: { radius: 0 }\n  sensor: { black_level: 0.02 }\n",
                 p->x, p->y, p->pitch - 90);
        snprintf(las, sizeof(las), laser_fmt, az, 600 * cos(az * M_PI / 180),
                 600 * sin(az * M_PI / 180));
        rt_open(&t, lamps, las, cams, scene);
        rt_render(&t, &off, NULL, 2 * i + 1, &w->off[i], 0, NULL);
        rt_render(&t, &on, NULL, 2 * i + 2, &w->on[i], 0, NULL);
        on.lamps = 0;
        rt_render(&t, &on, NULL, 2 * i + 2, &w->dark[i], 0, NULL);
        snprintf(name, sizeof(name), "laser-%02d", i);
        rt_dump(&w->on[i], name);
        w->v[i] = (struct cal_lp_view){&w->off[i], &w->on[i]};
        if (i == 0)
                truth(&t, w);
        rt_close(&t);
}

static void release(struct views *w, int n)
{
        for (int i = 0; i < n; i++) {
                gn_frame_free_data(&w->off[i]);
                gn_frame_free_data(&w->on[i]);
                gn_frame_free_data(&w->dark[i]);
        }
}

static int solve(struct views *w, int n, struct cal_laser *l, char *err, size_t len)
{
        struct cal_lp_opts o = {.board = BOARD, .k = K, .channel = 0};
        int r = cal_laser_solve(w->v, n, &o, l, err, len);

        fprintf(stderr, "solve: %d %s; views not used: %s\n", r, r < 0 ? err : "", l->unused);
        return r;
}

/* Fits the laser at azimuth az from the five poses; checks it against the truth within
 * 0.05 deg and 0.1 mm (at a point of the true plane where the boards stood). */
static void fit_checked(struct views *w, double az, struct cal_laser *l)
{
        char err[1024];
        double ang, p[3] = {30, 30 * tan(az * M_PI / 180), 70}, c[3], dist;

        for (int i = 0; i < N_POSES; i++)
                render_pose(w, i, &poses[i], az, true);
        CHECK_INT(solve(w, N_POSES, l, err, sizeof(err)), 0);
        ang = acos(fmin(fabs(cal_dot(l->plane.n, w->truth.n)), 1)) * 180 / M_PI;
        cal_mat_vec(w->g.R, p, c);
        for (int i = 0; i < 3; i++)
                c[i] += w->g.t[i];
        dist = fabs(cal_dot(l->plane.n, c) + l->plane.d);
        fprintf(stderr,
                "laser %g: %.4f deg, %.4f mm from the truth; rms %.3f mm, %zu of %zu points, "
                "spread %.1f mm, %d of %d views\n",
                az, ang, dist, l->rms_mm, l->inliers, l->points, l->spread_mm, l->n_used,
                l->n_views);
        CHECK(fabs(cal_dot(w->truth.n, c) + w->truth.d) < 1e-9);
        CHECK(ang < 0.05);
        CHECK(dist < 0.1);
        CHECK(l->rms_mm < 0.1);
        CHECK(l->plane.d <= 0);
        CHECK(l->n_used >= 3); /* a view whose line runs along a square's edge is dropped */
        release(w, N_POSES);
}

static void test_plane(void)
{
        struct views w;
        struct cal_laser l;

        fit_checked(&w, 0, &l);
        CHECK_INT(l.n_used, N_POSES);
        CHECK_STR(l.unused, "");
}

/* Two lasers, 20 deg apart, both containing the axis: they agree on it. */
static void test_two(void)
{
        struct views w;
        struct cal_laser a, b;
        double ang, dist;

        fit_checked(&w, 0, &a);
        fit_checked(&w, 20, &b);
        cal_laser_agreement(&a.plane, &b.plane, &w.axis, &ang, &dist);
        fprintf(stderr, "agreement: %.4f deg apart, common line %.4f mm from the axis\n", ang,
                dist);
        CHECK_NEAR(ang, 20, 0.05);
        CHECK(dist < 0.1);
        cal_laser_vs_axis(&a.plane, &w.axis, &ang, &dist);
        fprintf(stderr, "laser 0 vs axis: %.4f deg, %.4f mm\n", ang, dist);
        CHECK(ang < 0.05 && dist < 0.1);
}

/* The laser off, then the laser beside the board: what each view showed. */
static void test_bad(void)
{
        struct views w;
        struct cal_laser l;
        char err[1024];

        for (int i = 0; i < 3; i++)
                render_pose(&w, i, &poses[i], 0, false);
        CHECK_INT(solve(&w, 3, &l, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "no laser line found on the board in 3 of 3 views: view 0 (");
        CHECK_STR_CONTAINS(err, "is the laser on");
        release(&w, 3);
        for (int i = 0; i < 3; i++)
                render_pose(&w, i, &beside[i], 0, true);
        CHECK_INT(solve(&w, 3, &l, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "in 3 of 3 views");
        release(&w, 3);
        /* one pose seen three times: the points lie on one line */
        for (int i = 0; i < 3; i++)
                render_pose(&w, i, &poses[0], 0, true);
        CHECK_INT(solve(&w, 3, &l, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "lie on one line");
        release(&w, 3);
}

/* Through a dataset: each pose stored laser off then on, all at turntable angle 0 but the
 * board moved between them: the same plane; without laser-off rows, a reason. */
static void test_dataset(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct views w;
        struct cal_laser a, b;
        struct cal_lp_opts o = {.board = BOARD, .k = K};
        char path[512], err[1024];
        struct ds *d;

        snprintf(path, sizeof(path), "%s/ds", tmp);
        CHECK_INT(ds_create(path, "laser", "rig: test\n", &d), 0);
        for (int i = 0; i < 3; i++) {
                struct pose p = poses[i];
                p.tt = 0;
                render_pose(&w, i, &p, 0, true);
                for (int on = 0; on < 2; on++) {
                        struct ds_capture c = {.pose = {{0, 0, 0}, 1, on},
                                               .camera = "c0",
                                               .lamps = "l0",
                                               .exposure_us = 20000};
                        CHECK_INT(ds_store(d, on ? &w.on[i] : &w.off[i], &c), 0);
                }
        }
        CHECK_INT(solve(&w, 3, &a, err, sizeof(err)), 0);
        CHECK_INT(cal_laser_solve_ds(d, "c0", &o, &b, err, sizeof(err)), 0);
        CHECK_INT(b.n_used, 3);
        CHECK(acos(fmin(fabs(cal_dot(a.plane.n, b.plane.n)), 1)) * 180 / M_PI < 1e-5);
        ds_close(d);
        /* laser-on rows only */
        snprintf(path, sizeof(path), "%s/ds2", tmp);
        CHECK_INT(ds_create(path, "laser", "rig: test\n", &d), 0);
        for (int i = 0; i < 3; i++) {
                struct ds_capture c = {.pose = {{0, 0, 0}, 1, true},
                                       .camera = "c0",
                                       .lamps = "l0",
                                       .exposure_us = 20000};
                CHECK_INT(ds_store(d, &w.on[i], &c), 0);
        }
        CHECK_INT(cal_laser_solve_ds(d, "c0", &o, &b, err, sizeof(err)), -ENODATA);
        fprintf(stderr, "%s\n", err);
        CHECK_STR_CONTAINS(err, "none of the 3 images of camera c0 has the laser on with a "
                                "laser-off image of the same pose (3 with the laser on)");
        ds_close(d);
        /* a session's frames: the board lit (image), the laser with the lamp off (kind laser,
         * no bracket): the laser frame alone, the board from the lit one */
        snprintf(path, sizeof(path), "%s/ds3", tmp);
        CHECK_INT(ds_create(path, "laser", "rig: test\n", &d), 0);
        for (int i = 0; i < 3; i++)
                for (int on = 0; on < 2; on++) {
                        struct ds_capture c = {.pose = {{0, 0, 0}, on ? 0 : 1, on},
                                               .camera = "c0",
                                               .bracket = on ? -1 : 0,
                                               .exposure_us = 20000};
                        snprintf(c.lamps, sizeof(c.lamps), "%s", on ? "" : "l0");
                        snprintf(c.kind, sizeof(c.kind), "%s", on ? "laser" : "image");
                        CHECK_INT(ds_store(d, on ? &w.dark[i] : &w.off[i], &c), 0);
                }
        CHECK_INT(cal_laser_solve_ds(d, "c0", &o, &b, err, sizeof(err)), 0);
        CHECK_INT(b.n_used, 3);
        fprintf(stderr, "lamp-off laser frames: %.4f deg from the on-minus-off plane\n",
                acos(fmin(fabs(cal_dot(a.plane.n, b.plane.n)), 1)) * 180 / M_PI);
        CHECK(acos(fmin(fabs(cal_dot(a.plane.n, b.plane.n)), 1)) * 180 / M_PI < 0.02);
        ds_close(d);
        release(&w, 3);
        tu_rm_rf(tmp);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {{"plane", test_plane},
                                                 {"two", test_two},
                                                 {"bad", test_bad},
                                                 {"dataset", test_dataset}};

        return TEST_RUN_CASES(cases, argc, argv);
}
