/* test-lamps.c - lamp positions from a mirror sphere (calib/lamps.h) against the simulator's
 * ground truth: a 100 mm mirror sphere 70 mm off the axis of a white turntable, three lamps
 * 420-500 mm away lit one at a time, two cameras, sixteen turntable angles, noise on,
 * rendered in-process (the scene: lampscene.h), stored in a dataset and solved through the dataset
 * library with the true calibration of the rig file (intrinsics and distortion,
 * riggeom_camera_pose). Every lamp must come within LS_TOL_MM of its true position
 * (sim_lamp_position), the sphere within LS_SPHERE_TOL_MM. Also: the same through the in-memory API
 * with the light arm turned, the sphere and highlight finders against the true geometry, a moved
 * sphere and a mislabelled frame rejected, the nominal geometry (truth against an independent
 * formula, and a rig file whose nominal lamp is off by a known amount), and bad input: no sphere in
 * view, a lamp that stays off, a single view, bad arguments. */
#include <math.h>

#include "common/cleanup.h"
#include "common/riggeom.h"
#include "tests/calib/lampscene.h"
#include "tests/dataset/ds-util.h"

#define DEG (M_PI / 180)

static void print_result(int r, const struct cal_lamps *l, const char *err)
{
        fprintf(stderr, "solve: %d %s\n", r, r < 0 ? err : "");
        fprintf(stderr, "  sphere %.3f %.3f %.3f rms %.3f mm diameter %.2f mm, %zu of %zu views\n",
                l->sphere[0], l->sphere[1], l->sphere[2], l->sphere_rms_mm, l->sphere_diam_mm,
                l->n_used, l->n_views);
        for (size_t i = 0; l->views && i < l->n_views; i++) {
                const struct cal_lamp_view *v = &l->views[i];
                fprintf(stderr,
                        "  view %zu: cam %d lamp %d tt %.0f circle %.2f %.2f %.2f (%d edges, %.3f "
                        "px) highlight %.2f %.2f miss %.3f %s\n",
                        i, v->camera, v->lamp, v->turntable_deg, v->sphere.u, v->sphere.v,
                        v->sphere.r, v->sphere.n_edges, v->sphere.rms_px, v->highlight[0],
                        v->highlight[1], v->miss_mm, v->reason);
        }
        for (size_t i = 0; i < l->n_lamps; i++)
                fprintf(stderr, "  %s: %.2f %.2f %.2f rms %.3f mm, %d rays, %.2f mm from nominal\n",
                        l->lamps[i].name, l->lamps[i].pos[0], l->lamps[i].pos[1],
                        l->lamps[i].pos[2], l->lamps[i].rms_mm, l->lamps[i].n_obs,
                        l->lamps[i].nominal_dist_mm);
}

/* Distance of lamp k of l from its true position (light arm at 0). */
static double lamp_error(const struct ls_fixture *fx, const struct cal_lamps *l, size_t k)
{
        return ls_lamp_error(fx, l->index[k], l->lamps[k].pos);
}

static void check_sphere(const struct cal_lamps *l)
{
        double e = hypot(hypot(l->sphere[0] - LS_SPHERE_TRUE[0], l->sphere[1] - LS_SPHERE_TRUE[1]),
                         l->sphere[2] - LS_SPHERE_TRUE[2]);

        fprintf(stderr, "sphere centre: %.3f mm from the truth\n", e);
        CHECK(e <= LS_SPHERE_TOL_MM);
}

/* Every lamp of the rig within LS_TOL_MM of the truth. */
static void check_lamps(const struct ls_fixture *fx, const struct cal_lamps *l)
{
        CHECK_INT(l->n_lamps, fx->t.rc->n_lamps);
        for (size_t k = 0; k < l->n_lamps; k++) {
                double e = lamp_error(fx, l, k);
                fprintf(stderr, "lamp %s: %.3f mm from the truth\n", l->lamps[k].name, e);
                CHECK(e <= LS_TOL_MM);
                CHECK(l->lamps[k].rms_mm < LS_TOL_MM);
                CHECK(l->lamps[k].n_obs >= 2 * LS_ANGLES * 3 / 4);
        }
}

static void test_dataset(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct ls_fixture fx;
        struct cal_lamps l;
        char path[512], err[512];
        struct ds *d;
        int r;

        ls_open(&fx, ls_scene_sphere, 30);
        snprintf(path, sizeof(path), "%s/ds", tmp);
        d = ls_make_dataset(&fx, path, LS_ANGLES, 3, -1);
        r = cal_lamps_solve_ds(d, &fx.o, &l, err, sizeof(err));
        print_result(r, &l, err);
        CHECK_INT(r, 0);
        CHECK_INT(l.n_views, 2 * LS_ANGLES * 3);
        for (size_t i = 0; i < l.n_views; i++) { /* the rows, without their images */
                CHECK_INT(l.views[i].row_id, (int64_t)i + 1);
                CHECK(!l.views[i].im.data);
                CHECK(l.views[i].used == !l.views[i].reason[0]);
        }
        check_sphere(&l);
        CHECK_NEAR(l.sphere_diam_mm, LS_SPHERE_MM, 1.0);
        check_lamps(&fx, &l);
        cal_lamps_clear(&l);
        ds_close(d);
        tu_rm_rf(tmp);
        ls_close(&fx);
}

/* Views for the in-memory API: camera cam, angles, light arm at arm for every other angle. */
static size_t add_views(struct ls_fixture *fx, struct cal_lamp_view *v, struct gn_frame *f, int cam,
                        int n_angles, double arm)
{
        size_t n = 0;

        for (int a = 0; a < n_angles; a++)
                for (int lamp = 0; lamp < (int)fx->t.rc->n_lamps; lamp++) {
                        double tt = 360.0 * a / n_angles, la = a % 2 ? arm : 0;
                        ls_render(fx, cam, tt, la, 1u << lamp, &f[n]);
                        v[n] = (struct cal_lamp_view){{f[n].data, f[n].width, f[n].height,
                                                       f[n].channels, f[n].bits, f[n].stride},
                                                      cam,
                                                      lamp,
                                                      tt,
                                                      la};
                        n++;
                }
        return n;
}

/* The in-memory API with the light arm turned by 35 degrees in half of the views. */
static void test_light_arm(void)
{
        struct ls_fixture fx;
        struct cal_lamp_view v[2 * LS_ANGLES * 3];
        struct gn_frame f[2 * LS_ANGLES * 3];
        struct cal_lamps l;
        char err[512];
        size_t n;
        int r;

        ls_open(&fx, ls_scene_sphere, 30);
        n = add_views(&fx, v, f, 0, LS_ANGLES, 35);
        n += add_views(&fx, v + n, f + n, 1, LS_ANGLES, 35);
        r = cal_lamps_solve(v, n, &fx.o, &l, err, sizeof(err));
        l.views = v;
        print_result(r, &l, err);
        l.views = NULL;
        CHECK_INT(r, 0);
        check_sphere(&l);
        check_lamps(&fx, &l);
        for (size_t i = 0; i < n; i++)
                gn_frame_free_data(&f[i]);
        ls_close(&fx);
}

/* The specular point q of the lamp at l on the true sphere (world centre s) seen from c: the
 * normal bisects the directions to c and l. */
static void true_specular(const double s[3], const double c[3], const double l[3], double q[3])
{
        double n[3] = {0, 0, 1};

        for (int it = 0; it < 100; it++) {
                double a[3], b[3], la, lb, ln;
                for (int k = 0; k < 3; k++) {
                        q[k] = s[k] + LS_SPHERE_MM / 2 * n[k];
                        a[k] = c[k] - q[k];
                        b[k] = l[k] - q[k];
                }
                la = hypot(hypot(a[0], a[1]), a[2]);
                lb = hypot(hypot(b[0], b[1]), b[2]);
                for (int k = 0; k < 3; k++)
                        n[k] = a[k] / la + b[k] / lb;
                ln = hypot(hypot(n[0], n[1]), n[2]);
                for (int k = 0; k < 3; k++)
                        n[k] /= ln;
        }
}

/* One view of the finders against the truth: the silhouette's axis through the sphere's true
 * centre (0.5 px), the highlight at the true specular point of its lamp (0.3 px). */
static void check_image(struct ls_fixture *fx, int cam, double tt)
{
        struct gn_pose st = {{tt, 0, NAN}, 1, false};
        struct sim_cam_geom g;
        struct cal_sphere_image si;
        struct gn_frame f;
        double s[3], l[3], c[3], q[3], x[3], uv[2], hl[2], len;

        ls_render(fx, cam, tt, 0, 1, &f);
        CHECK_INT(sim_camera_geom(fx->t.s, &st, cam, &g), 0);
        CHECK_INT(sim_lamp_position(fx->t.s, &st, 0, l), 0);
        s[0] = LS_SPHERE_TRUE[0] * cos(tt * DEG);
        s[1] = LS_SPHERE_TRUE[0] * sin(tt * DEG);
        s[2] = LS_SPHERE_TRUE[2];
        for (int k = 0; k < 3; k++) {
                c[k] = -(g.R[k] * g.t[0] + g.R[3 + k] * g.t[1] + g.R[6 + k] * g.t[2]);
                x[k] = g.R[3 * k] * s[0] + g.R[3 * k + 1] * s[1] + g.R[3 * k + 2] * s[2] + g.t[k];
        }
        true_specular(s, c, l, q);
        CHECK_INT(sim_cam_project(&g, q, uv), 0);
        struct cal_image im = {f.data, f.width, f.height, f.channels, f.bits, f.stride};
        CHECK_INT(cal_lamps_find_sphere(&im, &fx->cams[cam].cal, LS_SPHERE_MM, 0, &si), 0);
        CHECK_INT(cal_lamps_find_highlight(&im, &si, hl), 1);
        len = hypot(hypot(x[0], x[1]), x[2]);
        double axis_px =
                g.fx *
                acos(fmin(1, (si.axis[0] * x[0] + si.axis[1] * x[1] + si.axis[2] * x[2]) / len));
        fprintf(stderr, "cam %d tt %3.0f: axis %.3f px off, highlight %.3f px off\n", cam, tt,
                axis_px, hypot(hl[0] - uv[0], hl[1] - uv[1]));
        CHECK(axis_px <= 0.5);
        CHECK(hypot(hl[0] - uv[0], hl[1] - uv[1]) <= 0.3);
        gn_frame_free_data(&f);
}

/* The finders against the truth, and two lamps lit at once: two highlights. */
static void test_image(void)
{
        struct ls_fixture fx;
        struct cal_sphere_image si;
        struct gn_frame f;
        double hl[2];

        ls_open(&fx, ls_scene_sphere, 30);
        for (int cam = 0; cam < 2; cam++)
                for (int a = 0; a < 4; a++)
                        check_image(&fx, cam, 90.0 * a);
        ls_render(&fx, 0, 0, 0, 3, &f);
        struct cal_image im = {f.data, f.width, f.height, f.channels, f.bits, f.stride};
        CHECK_INT(cal_lamps_find_sphere(&im, &fx.cams[0].cal, LS_SPHERE_MM, 0, &si), 0);
        CHECK_INT(cal_lamps_find_highlight(&im, &si, hl), 2);
        gn_frame_free_data(&f);
        ls_close(&fx);
}

/* A view of the sphere moved by 8 mm and a view filed under the wrong lamp among good ones:
 * the first's silhouette and the second's ray are rejected with their reasons, the lamps
 * still found. */
static void test_outliers(void)
{
        static const char moved[] = "translate: [78, 0, ";
        struct ls_fixture fx, mv;
        struct cal_lamp_view v[2 * (LS_ANGLES / 2) * 3 + 3]; /* + the moved view's three */
        struct gn_frame f[ELEMENTSOF(v)];
        struct cal_lamps l;
        char scene[1024], err[512];
        size_t n;

        snprintf(scene, sizeof(scene), "%s", ls_scene_sphere);
        memcpy(strstr(scene, "translate: [70, 0, "), moved, strlen(moved));
        ls_open(&fx, ls_scene_sphere, 30);
        ls_open(&mv, scene, 30);
        n = add_views(&fx, v, f, 0, LS_ANGLES / 2, 0);
        n += add_views(&fx, v + n, f + n, 1, LS_ANGLES / 2, 0);
        add_views(&mv, v + n, f + n, 0, 1, 0); /* its lamp 0 view only */
        gn_frame_free_data(&f[n + 1]);
        gn_frame_free_data(&f[n + 2]);
        ls_render(&fx, 1, 45, 0, 1u << 1, &f[n + 1]); /* lamp 1 lit, filed as lamp 0 */
        v[n + 1] = (struct cal_lamp_view){{f[n + 1].data, f[n + 1].width, f[n + 1].height,
                                           f[n + 1].channels, f[n + 1].bits, f[n + 1].stride},
                                          1,
                                          0,
                                          45,
                                          0};
        n += 2;
        CHECK_INT(cal_lamps_solve(v, n, &fx.o, &l, err, sizeof(err)), 0);
        l.views = v;
        l.n_views = n;
        print_result(0, &l, err);
        l.views = NULL;
        CHECK(!v[n - 2].sphere_used);
        CHECK_STR_CONTAINS(v[n - 2].reason, "silhouette points");
        CHECK(!v[n - 1].used);
        CHECK_STR_CONTAINS(v[n - 1].reason, "outlier");
        for (size_t k = 0; k < l.n_lamps; k++)
                fprintf(stderr, "lamp %s: %.3f mm from the truth\n", l.lamps[k].name,
                        lamp_error(&fx, &l, k));
        for (size_t k = 0; k < l.n_lamps; k++)
                CHECK(lamp_error(&fx, &l, k) <= LS_TOL_MM);
        for (size_t i = 0; i < n; i++)
                gn_frame_free_data(&f[i]);
        ls_close(&mv);
        ls_close(&fx);
}

/* No sphere in view: -ENODATA saying so. */
static void test_no_sphere(void)
{
        struct ls_fixture fx;
        struct cal_lamp_view v[2 * 3];
        struct gn_frame f[2 * 3];
        struct cal_lamps l;
        char err[512];
        size_t n;

        ls_open(&fx, ls_scene_empty, 30);
        n = add_views(&fx, v, f, 0, 2, 0);
        CHECK_INT(cal_lamps_solve(v, n, &fx.o, &l, err, sizeof(err)), -ENODATA);
        fprintf(stderr, "%s\n", err);
        CHECK_STR_CONTAINS(err, "found in none of the 6 views");
        for (size_t i = 0; i < n; i++) {
                CHECK_STR(v[i].reason, "mirror sphere not found");
                gn_frame_free_data(&f[i]);
        }
        ls_close(&fx);
}

/* A lamp recorded as lit but off: -ENODATA naming it and what to check; the others solved. */
static void test_lamp_off(void)
{
        _cleanup_free_ char *tmp = tu_tmpdir();
        struct ls_fixture fx;
        struct cal_lamps l;
        char path[512], err[512], want[128];
        struct ds *d;
        int r;

        ls_open(&fx, ls_scene_sphere, 30);
        snprintf(path, sizeof(path), "%s/ds", tmp);
        d = ls_make_dataset(&fx, path, LS_ANGLES, 3, 2);
        r = cal_lamps_solve_ds(d, &fx.o, &l, err, sizeof(err));
        print_result(r, &l, err);
        CHECK_INT(r, -ENODATA);
        snprintf(want, sizeof(want), "lamp 'l2' gave a reflected ray in 0 of the %d views",
                 2 * LS_ANGLES);
        CHECK_STR_CONTAINS(err, want);
        CHECK_STR_CONTAINS(err, "is the lamp off?");
        CHECK_STR_CONTAINS(err, "check that the lamp lights");
        CHECK_INT(l.n_lamps, 3);
        CHECK(isnan(l.lamps[2].pos[0]));
        CHECK_INT(l.lamps[2].n_obs, 0);
        for (size_t k = 0; k < 2; k++)
                CHECK(lamp_error(&fx, &l, k) <= LS_TOL_MM);
        cal_lamps_clear(&l);
        ds_close(d);
        tu_rm_rf(tmp);
        ls_close(&fx);
}

/* A single view: the sphere from its diameter, each lamp one ray: -ENODATA asking for more
 * turntable angles or another camera. */
static void test_single_view(void)
{
        struct ls_fixture fx;
        struct cal_lamp_view v[3];
        struct gn_frame f[3];
        struct cal_lamps l;
        char err[512];

        ls_open(&fx, ls_scene_sphere, 30);
        add_views(&fx, v, f, 0, 1, 0);
        CHECK_INT(cal_lamps_solve(v, 1, &fx.o, &l, err, sizeof(err)), -ENODATA);
        fprintf(stderr, "%s\n", err);
        CHECK_STR_CONTAINS(err, "lamp 'l0' gave a reflected ray in 1 of the 1 views that light "
                                "it, 3 needed");
        CHECK_STR_CONTAINS(err, "more turntable angles or add a camera");
        CHECK(hypot(l.sphere[0] - LS_SPHERE_TRUE[0], l.sphere[1] - LS_SPHERE_TRUE[1]) < 5);
        for (size_t i = 0; i < 3; i++)
                gn_frame_free_data(&f[i]);
        ls_close(&fx);
}

/* The truth agrees with an independent formula and with the nominal geometry, and a nominal
 * lamp moved in the rig file shows in nominal_dist_mm. */
static void test_nominal(void)
{
        struct ls_fixture fx, moved;
        struct cal_lamp_view v[2 * LS_ANGLES * 3];
        struct gn_frame f[2 * LS_ANGLES * 3];
        struct gn_pose st = {{0, 0, NAN}, 0, false};
        struct cal_lamps l;
        double truth[3], nom[3], want, e = 30 * DEG, a = 20 * DEG;
        char err[512];
        size_t n;

        ls_open(&fx, ls_scene_sphere, 30);
        ls_open(&moved, ls_scene_sphere, 32); /* lamp l0 2 degrees higher in the rig file */
        CHECK_INT(sim_lamp_position(fx.t.s, &st, 0, truth), 0);
        CHECK_NEAR(truth[0], 500 * cos(e) * cos(a), 1e-9);
        CHECK_NEAR(truth[1], 500 * cos(e) * sin(a), 1e-9);
        CHECK_NEAR(truth[2], 500 * sin(e), 1e-9);
        riggeom_lamp_position(&fx.t.rc->lamps[0], 0, nom);
        CHECK_NEAR(hypot(hypot(nom[0] - truth[0], nom[1] - truth[1]), nom[2] - truth[2]), 0, 1e-9);
        riggeom_lamp_position(&moved.t.rc->lamps[0], 0, nom);
        want = hypot(hypot(nom[0] - truth[0], nom[1] - truth[1]), nom[2] - truth[2]);
        n = add_views(&fx, v, f, 0, LS_ANGLES, 0);
        n += add_views(&fx, v + n, f + n, 1, LS_ANGLES, 0);
        fx.o.rc = moved.t.rc;
        CHECK_INT(cal_lamps_solve(v, n, &fx.o, &l, err, sizeof(err)), 0);
        fprintf(stderr, "l0: %.2f mm from the moved nominal (%.2f mm moved), l1 %.2f mm\n",
                l.lamps[0].nominal_dist_mm, want, l.lamps[1].nominal_dist_mm);
        CHECK_NEAR(l.lamps[0].nominal_dist_mm, want, LS_TOL_MM);
        CHECK(l.lamps[1].nominal_dist_mm <= LS_TOL_MM);
        for (size_t i = 0; i < n; i++)
                gn_frame_free_data(&f[i]);
        ls_close(&moved);
        ls_close(&fx);
}

/* Bad arguments: -EINVAL with a sentence. */
static void test_args(void)
{
        struct ls_fixture fx;
        struct cal_lamp_view v = {.camera = 2};
        struct cal_lamps l;
        struct cal_lamps_opts o;
        char err[512];

        ls_open(&fx, ls_scene_sphere, 30);
        o = fx.o;
        o.sphere_mm = 0;
        CHECK_INT(cal_lamps_solve(&v, 1, &o, &l, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, "diameter");
        CHECK_INT(cal_lamps_solve(&v, 1, &fx.o, &l, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, "view 0 names camera 2");
        CHECK_INT(cal_lamps_solve_ds(NULL, &fx.o, &l, err, sizeof(err)), -EINVAL);
        ls_close(&fx);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"dataset", test_dataset},
                {"light-arm", test_light_arm},
                {"no-sphere", test_no_sphere},
                {"lamp-off", test_lamp_off},
                {"single-view", test_single_view},
                {"nominal", test_nominal},
                {"args", test_args},
                {"image", test_image},
                {"outliers", test_outliers},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
