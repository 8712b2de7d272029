/* test-relit.c - fitted models (appearance/fit.h) of synthetic datasets (apscene.h) relit by
 * the renderer (appearance/render.h) at views and lights held out of the fit, against the
 * simulator's rendering of the same view and light (noise off): PSNR inside the object; and
 * gonioctl model render on a model written into its dataset, with bad input. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "appearance/fit.h"
#include "appearance/mesh.h"
#include "appearance/render.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds_png.h"
#include "drivers/registry.h"
#include "tests/appearance/apscene.h"
#include "tests/dataset/ds-util.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_renderer *, ap_renderer_free);

#define DEG        (M_PI / 180)
#define TT_ANGLES  12 /* views of the fit: turntable angles 30 degrees apart, one camera */
#define ARM_ANGLES 18

#define SEAM_TT_ANGLES 6   /* test_seams: views 60 degrees apart */
#define SEAM_RIM_PX    4   /* pixels this close to the object's outline are not compared */
#define SEAM_MAX_STEP  0.2 /* largest change of a view's share between pixel neighbours */

static void rm_rfp(char **dir)
{
        if (*dir)
                tu_rm_rf(*dir);
        free(*dir);
}

/* A fitted model (P = 6, K = 12) of a dataset written into it. */
struct fitted {
        struct apscene s;
        char *dir, ds[512];
        struct ap_model *m;
        struct ap_mesh mesh;
};

/* fit_scene with the images scale times the default size. */
static void fit_scene_scaled(struct fitted *f, enum aps_material mat, int tt_angles, int scale)
{
        struct aps_opts ao;
        char err[512], src[512];

        aps_opts_default(&ao, mat);
        ao.turntable_angles = tt_angles, ao.arm_angles = ARM_ANGLES;
        ao.width *= scale, ao.height *= scale;
        aps_open(&f->s, &ao);
        f->dir = tu_tmpdir();
        snprintf(f->ds, sizeof(f->ds), "%s/ds", f->dir);
        aps_fit_dataset(&f->s, f->ds, 4, &f->m);
        CHECK_INT(ap_mesh_for_dataset(f->ds, registry_backends, &f->mesh, src, sizeof(src), err,
                                      sizeof(err)),
                  0);
        CHECK_STR_CONTAINS(src, "scan");
}

static void fit_scene(struct fitted *f, enum aps_material mat, int tt_angles)
{
        fit_scene_scaled(f, mat, tt_angles, 1);
}

static void fitted_free(struct fitted *f)
{
        ap_mesh_free(&f->mesh);
        ap_model_free(f->m);
        aps_close(&f->s);
        rm_rfp(&f->dir);
}

/* The simulator's camera at turntable angle tt as seen from the object frame. */
static struct ap_camera object_camera(struct fitted *f, double tt)
{
        struct gn_pose pose = {{tt, 0, NAN}, 0, false};
        struct sim_cam_geom g;
        struct ap_camera cam;
        double a = tt * DEG;

        CHECK_INT(sim_camera_geom(f->s.t.s, &pose, 0, &g), 0);
        cam = (struct ap_camera){g.width, g.height, g.fx, g.fy, g.cx, g.cy};
        memcpy(cam.dist, g.dist, sizeof(cam.dist));
        memcpy(cam.t, g.t, sizeof(cam.t));
        for (int i = 0; i < 3; i++) { /* object to camera: R Rz(tt) */
                cam.R[3 * i] = g.R[3 * i] * cos(a) + g.R[3 * i + 1] * sin(a);
                cam.R[3 * i + 1] = -g.R[3 * i] * sin(a) + g.R[3 * i + 1] * cos(a);
                cam.R[3 * i + 2] = g.R[3 * i + 2];
        }
        return cam;
}

/* The PSNR of the model relit at turntable angle tt and world light position Pw against
 * the simulator, over the pixels both give (at least 1000 samples). */
static double relit_psnr(struct fitted *f, struct ap_renderer *r, double tt, const double Pw[3],
                         enum ap_view_mode mode)
{
        _cleanup_(sim_truth_free) struct sim_truth tr = {0};
        struct ap_camera cam = object_camera(f, tt);
        struct sim_cam_geom g = {.width = cam.width, .height = cam.height};
        double a = tt * DEG, sse = 0;
        struct ap_light l = {
                AP_LIGHT_POINT,
                {cos(a) * Pw[0] + sin(a) * Pw[1], -sin(a) * Pw[0] + cos(a) * Pw[1], Pw[2]},
                0,
                NULL};
        struct gn_frame fr;
        size_t n = 0;

        _cleanup_free_ float *rgb = malloc(3 * sizeof(float) * g.width * g.height);
        _cleanup_free_ uint8_t *mask = malloc((size_t)g.width * g.height);
        CHECK(rgb && mask);
        CHECK_INT(ap_render(r, &cam, &l, mode, 2, rgb, mask), 0);
        aps_render_light(&f->s, 0, tt, Pw, &fr, SIM_TRUTH_POINT, &tr);
        for (size_t p = 0; p < (size_t)g.width * g.height; p++) {
                if (!mask[p] || isnan(tr.point[3 * p]))
                        continue;
                for (int c = 0; c < 3; c++) {
                        double e = fmin(fmax(rgb[3 * p + c], 0), 1) -
                                   rt_px(&fr, (int)(p % g.width), (int)(p / g.width), c) / 65535;
                        sse += e * e;
                        n++;
                }
        }
        gn_frame_free_data(&fr);
        CHECK(n > 1000);
        return 10 * log10(n / sse);
}

/* Held-out views (half-way between fitted turntable angles) under held-out lights (between
 * the fitted light-arm angles and lamp elevations, as test-fit's): the mean PSNR of both view
 * modes. */
static void heldout(enum aps_material mat, double min_db)
{
        static const double tts[] = {15, 195};
        static const double elev[] = {-27, -2, 22, 47, 72};
        _cleanup_(ap_renderer_freep) struct ap_renderer *r = NULL;
        struct fitted f;
        double px = 0, obj = 0, worst = INFINITY;
        int n = 0;

        fit_scene(&f, mat, TT_ANGLES);
        CHECK_INT(ap_renderer_new(f.m, &f.mesh, &r), 0);
        for (size_t v = 0; v < ELEMENTSOF(tts); v++)
                for (size_t e = 0; e < ELEMENTSOF(elev); e++)
                        for (int i = 0; i < 4; i++, n++) {
                                double az = (15 + 90 * i + 7 * e) * DEG, el = elev[e] * DEG;
                                double Pw[3] = {500 * cos(el) * cos(az), 500 * cos(el) * sin(az),
                                                500 * sin(el)};
                                double a = relit_psnr(&f, r, tts[v], Pw, AP_VIEW_PIXEL);
                                px += a, worst = fmin(worst, a);
                                obj += relit_psnr(&f, r, tts[v], Pw, AP_VIEW_OBJECT);
                        }
        fprintf(stderr,
                "held-out views and lights: per pixel %.2f dB (worst %.2f), per object "
                "%.2f\n",
                px / n, worst, obj / n);
        CHECK(px / n >= min_db);
        CHECK(obj / n >= min_db - 1);
        ap_renderer_free(TAKE_PTR(r));
        fitted_free(&f);
}

/* Sets the first weight of every pixel of view v to value(v), the others to 0. */
static void set_weights(struct ap_model *m, float (*value)(size_t v))
{
        for (size_t v = 0; v < m->n_views; v++) {
                const struct ap_camera *c = &m->views[v].cam;
                for (size_t p = 0; p < (size_t)c->width * c->height; p++)
                        for (int k = 0; k < m->k; k++)
                                m->views[v].weights[p * m->k + k] = k ? 0 : value(v);
        }
}

static float weight_zero(size_t v)
{
        return 0;
}

static float weight_one(size_t v)
{
        return 1;
}

static float weight_odd(size_t v)
{
        return v % 2;
}

/* Green of a per-pixel render of f's model with the weights of value() and light l. */
static void render_weights(struct fitted *f, const struct ap_camera *cam, const struct ap_light *l,
                           float (*value)(size_t v), float *rgb, uint8_t *mask)
{
        _cleanup_(ap_renderer_freep) struct ap_renderer *r = NULL;

        set_weights(f->m, value);
        CHECK_INT(ap_renderer_new(f->m, &f->mesh, &r), 0);
        CHECK_INT(ap_render(r, cam, l, AP_VIEW_PIXEL, 2, rgb, mask), 0);
}

/* Whether the pixels within SEAM_RIM_PX of p (a square) are all in mask: p is away from the
 * object's outline, where a pixel spans much of the surface and the blend moves fast. */
static bool inside(const uint8_t *mask, size_t W, size_t H, size_t p)
{
        size_t x = p % W, y = p / W;

        if (x < SEAM_RIM_PX || y < SEAM_RIM_PX || x + SEAM_RIM_PX + 1 >= W ||
            y + SEAM_RIM_PX + 1 >= H)
                return false;
        for (size_t v = y - SEAM_RIM_PX; v <= y + SEAM_RIM_PX + 1; v++)
                for (size_t u = x - SEAM_RIM_PX; u <= x + SEAM_RIM_PX + 1; u++)
                        if (!mask[v * W + u])
                                return false;
        return true;
}

/* The largest change of the odd views' share of the blend between pixel neighbours inside the
 * object in the renders s (weights 0, 1, alternating; mask of the first). */
static double largest_step(float *const s[3], const uint8_t *mask, size_t W, size_t H)
{
        double worst = 0;

        for (size_t p = 0; p < W * H; p++) {
                double share[3];
                if (!inside(mask, W, H, p) || !(fabsf(s[1][3 * p + 1] - s[0][3 * p + 1]) > 1e-3f))
                        continue;
                for (int j = 0; j < 3; j++) { /* p, its right and lower neighbours */
                        size_t q = p + (j == 1) + (j == 2) * W;
                        share[j] = (s[2][3 * q + 1] - s[0][3 * q + 1]) /
                                   (s[1][3 * q + 1] - s[0][3 * q + 1]);
                }
                worst = fmax(worst, fmax(fabs(share[1] - share[0]), fabs(share[2] - share[0])));
        }
        return worst;
}

/* No seam where a view stops seeing the surface. With the views' first weight alternately 0
 * and 1 (the others 0), the odd views' share of each pixel's blend (from renders with all
 * weights 0 and all 1: the light term is affine in the weights) moves by at most
 * SEAM_MAX_STEP between neighbouring pixels inside the object. The views are 60 degrees apart
 * and the renders half-way between two: each of the two reaches its silhouette well inside
 * the picture. Measured 0.10; a view cut off there (seen, then not) made the share jump by 0.56. */
static void test_seams(void)
{
        struct ap_light l = {AP_LIGHT_DIRECTIONAL, {1, 0, 0.5}, 0, NULL};
        struct fitted f;
        double worst = 0;

        fit_scene_scaled(&f, APS_DIFFUSE, SEAM_TT_ANGLES, 2);
        for (double tt = 180.0 / SEAM_TT_ANGLES; tt < 360; tt += 90) {
                struct ap_camera cam = object_camera(&f, tt);
                size_t n = (size_t)cam.width * cam.height;
                _cleanup_free_ float *rgb = malloc(3 * 3 * n * sizeof(float));
                _cleanup_free_ uint8_t *mask = malloc(3 * n);
                float *s[3] = {rgb, rgb + 3 * n, rgb + 6 * n};
                CHECK(rgb && mask);
                render_weights(&f, &cam, &l, weight_zero, s[0], mask);
                render_weights(&f, &cam, &l, weight_one, s[1], mask + n);
                render_weights(&f, &cam, &l, weight_odd, s[2], mask + 2 * n);
                worst = fmax(worst, largest_step(s, mask, cam.width, cam.height));
        }
        fprintf(stderr, "largest step of the odd views' share between neighbours: %.3f\n", worst);
        CHECK(worst <= SEAM_MAX_STEP);
        fitted_free(&f);
}

static void test_diffuse(void)
{
        heldout(APS_DIFFUSE, 35);
}

static void test_glossy(void)
{
        heldout(APS_GLOSSY, 35);
}

/* The PNG at path against the simulator's camera 0 at turntable angle tt under the point
 * light Pw (world): PSNR over the pixels where both see the object. */
static double png_psnr(struct fitted *f, const char *path, double tt, const double Pw[3])
{
        _cleanup_(sim_truth_free) struct sim_truth tr = {0};
        _cleanup_free_ void *buf = NULL;
        struct gn_frame png = {0}, fr;
        double sse = 0;
        size_t len, n = 0;

        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 1 << 24, &buf, &len), 0);
        CHECK_INT(ds_png_decode(buf, len, &png), 0);
        aps_render_light(&f->s, 0, tt, Pw, &fr, SIM_TRUTH_POINT, &tr);
        CHECK_INT(png.width, fr.width);
        CHECK_INT(png.height, fr.height);
        CHECK_INT(png.bits, 8);
        for (int y = 0; y < fr.height; y++)
                for (int x = 0; x < fr.width; x++) {
                        const uint8_t *q = png.data + (size_t)y * png.stride + 3 * x;
                        if (isnan(tr.point[3 * ((size_t)y * fr.width + x)]) ||
                            q[0] + q[1] + q[2] == 0)
                                continue;
                        for (int c = 0; c < 3; c++) {
                                double e = q[c] / 255.0 - fmin(rt_px(&fr, x, y, c) / 65535, 1);
                                sse += e * e;
                                n++;
                        }
                }
        gn_frame_free_data(&png);
        gn_frame_free_data(&fr);
        CHECK(n > 1000);
        return 10 * log10(n / sse);
}

/* gonioctl model render at a held-out view (the camera at turntable angle 15 is at object
 * azimuth -15) and light, per pixel and per object; an environment map. */
static void test_gonioctl(void)
{
        struct fitted f;
        char args[2048], out[4096], png[600], env[600];
        double Pw[3] = {300, 250, 200}, a = 15 * DEG, db;
        FILE *pfm;

        fit_scene(&f, APS_DIFFUSE, TT_ANGLES);
        snprintf(png, sizeof(png), "%s/out.png", f.dir);
        for (int mode = 0; mode < 2; mode++) {
                snprintf(args, sizeof(args),
                         "model render %s/models/default --light %g,%g,%g --view -15,15 "
                         "--mode %s -o %s",
                         f.ds, cos(a) * Pw[0] + sin(a) * Pw[1], -sin(a) * Pw[0] + cos(a) * Pw[1],
                         Pw[2], mode ? "object" : "pixel", png);
                CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
                CHECK_STR_CONTAINS(out, "rendered");
                db = png_psnr(&f, png, 15, Pw);
                fprintf(stderr, "gonioctl model render --mode %s: %.2f dB\n",
                        mode ? "object" : "pixel", db);
                CHECK(db >= 33);
        }
        snprintf(env, sizeof(env), "%s/sky.pfm", f.dir);
        pfm = fopen(env, "wb");
        CHECK(pfm);
        fprintf(pfm, "PF\n8 4\n-1.0\n");
        for (int i = 0; i < 8 * 4 * 3; i++) {
                float v = i < 8 * 3 * 2 ? 0.05f : 0.01f; /* a brighter upper half */
                CHECK(fwrite(&v, sizeof(v), 1, pfm) == 1);
        }
        fclose(pfm);
        snprintf(args, sizeof(args),
                 "model render %s/models/default --envmap %s --view 40,30 --size 48x36 -o %s", f.ds,
                 env, png);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        fitted_free(&f);
}

/* The model's model.json cut in half, then from a newer gonio: gonioctl model render says
 * which, exit 6, no image written. */
static void check_bad_model_json(const struct fitted *f)
{
        _cleanup_free_ char *text = NULL;
        char path[600], args[2048], out[4096], *v;
        size_t len;

        snprintf(path, sizeof(path), "%s/models/default/model.json", f->ds);
        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 1 << 24, (void **)&text, &len), 0);
        snprintf(args, sizeof(args),
                 "model render %s/models/default --dir 0,0,1 --view 0,15 -o %s/y.png", f->ds,
                 f->dir);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, text, len / 2, NULL), 0);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "model.json: line ");
        CHECK_STR_CONTAINS(out, "(the file is cut short)");
        CHECK((v = strstr(text, "gonio-appearance 1")) != NULL);
        v[strlen("gonio-appearance ")] = '2';
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, text, len, NULL), 0);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "format 'gonio-appearance 2' is newer than this gonio reads");
        snprintf(path, sizeof(path), "%s/y.png", f->dir);
        CHECK(access(path, F_OK) < 0);
}

/* A missing model, a bad environment map, views out of range, bad command lines. */
static void test_gonioctl_bad(void)
{
        struct fitted f;
        char args[2048], out[4096], bad[600];

        fit_scene(&f, APS_DIFFUSE, 4);
        snprintf(args, sizeof(args),
                 "model render %s/models/nothing --dir 0,0,1 --view 0,15 -o %s/x.png", f.ds, f.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "nothing");
        snprintf(bad, sizeof(bad), "%s/bad.png", f.dir);
        CHECK_INT(gn_write_atomic(AT_FDCWD, bad, "not an image", 12, NULL), 0);
        snprintf(args, sizeof(args),
                 "model render %s/models/default --envmap %s --view 0,15 -o %s/x.png", f.ds, bad,
                 f.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "not a PNG or PFM");
        snprintf(args, sizeof(args),
                 "model render %s/models/default --dir 0,0,1 --view 0,-80 -o %s/x.png", f.ds,
                 f.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "away from the views the model covers");
        snprintf(args, sizeof(args),
                 "model render %s/models/default --dir 0,0,1 --view 0,95 -o %s/x.png", f.ds, f.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        CHECK_STR_CONTAINS(out, "elevation");
        snprintf(args, sizeof(args), "model render %s/models/default --view 0,15 -o %s/x.png", f.ds,
                 f.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        snprintf(args, sizeof(args),
                 "model render %s/models/default --dir 0,0 --view 0,15 -o %s/x.png", f.ds, f.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        check_bad_model_json(&f);
        fitted_free(&f);
}

/* The mesh of a dataset without a scan: the simulated rig's object (the 60 mm sphere on the
 * turntable, tessellated), and no mesh at all for a folder with neither. */
static void test_mesh(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        struct ap_mesh m;
        struct aps_opts o;
        struct apscene s;
        char path[512], src[600], err[512];
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};

        aps_opts_default(&o, APS_DIFFUSE);
        o.turntable_angles = o.arm_angles = o.n_lamps = 1, o.mesh = false;
        aps_open(&s, &o);
        snprintf(path, sizeof(path), "%s/ds", dir);
        ds_close(aps_make_dataset(&s, path));
        CHECK_INT(ap_mesh_for_dataset(path, registry_backends, &m, src, sizeof(src), err,
                                      sizeof(err)),
                  0);
        CHECK_STR_CONTAINS(src, "simulator");
        CHECK(m.nt > 1000);
        CHECK(m.front != 0); /* closed */
        for (size_t i = 0; i < m.nv; i++)
                for (int j = 0; j < 3; j++) {
                        lo[j] = fmin(lo[j], m.pos[3 * i + j]);
                        hi[j] = fmax(hi[j], m.pos[3 * i + j]);
                }
        for (int j = 0; j < 3; j++) {
                CHECK_NEAR(lo[j], j == 2 ? 0 : -APS_SIZE_MM / 2, 0.1);
                CHECK_NEAR(hi[j], j == 2 ? APS_SIZE_MM : APS_SIZE_MM / 2, 0.1);
        }
        ap_mesh_free(&m);
        CHECK_INT(
                ap_mesh_for_dataset(dir, registry_backends, &m, src, sizeof(src), err, sizeof(err)),
                -ENOENT);
        CHECK_STR_CONTAINS(err, "no shape to render on");
        aps_close(&s);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"diffuse", test_diffuse},   {"glossy", test_glossy},
                {"gonioctl", test_gonioctl}, {"gonioctl-bad", test_gonioctl_bad},
                {"mesh", test_mesh},         {"seams", test_seams},
        };

        /* the datasets' thousand fsyncs cost seconds on a disk: memory where there is one */
        if (!getenv("TMPDIR") && access("/dev/shm", W_OK) == 0)
                setenv("TMPDIR", "/dev/shm", 0);
        return TEST_RUN_CASES(cases, argc, argv);
}
