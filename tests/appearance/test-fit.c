/* test-fit.c - the appearance fit (appearance/fit.h) on synthetic datasets (apscene.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "appearance/fit.h"
#include "appearance/sh.h"
#ifdef AP_CALFILE
#include "calib/calfile.h"
#endif
#include "common/cleanup.h"
#include "drivers/registry.h"
#include "tests/appearance/apscene.h"
#include "tests/dataset/ds-util.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);

#define DEG (M_PI / 180)

static void rm_rfp(char **dir)
{
        if (*dir)
                tu_rm_rf(*dir);
        free(*dir);
}

static double now_s(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* The scene's dataset: every view under every light, well exposed, the probe light where
 * a lamp is giving the lamp's image. */
static void test_scene(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        struct aps_opts o;
        struct apscene s;
        struct gn_frame a, b;
        char path[512];
        double t0 = now_s(), hi = 0, p[3];

        aps_opts_default(&o, APS_SHARP);
        aps_open(&s, &o);
        snprintf(path, sizeof(path), "%s/ds", dir);
        {
                _cleanup_(ds_closep) struct ds *d = aps_make_dataset(&s, path);
                CHECK_INT(ds_count(d), 2 * 18 * 6);
        }
        fprintf(stderr, "dataset of %d captures in %.2f s\n", 2 * 18 * 6, now_s() - t0);
        aps_render_lamp(&s, 0, 30, 60, 2, &a, 0, NULL);
        aps_lamp_position(&s, 2, 60, p);
        aps_render_light(&s, 0, 30, p, &b, 0, NULL);
        CHECK(tu_frames_equal(&a, &b));
        gn_frame_free_data(&b);
        aps_render_view(&s, 0, 15, 30, p, &b, 0, NULL); /* the camera's own elevation */
        CHECK(tu_frames_equal(&a, &b));
        gn_frame_free_data(&b);
        aps_render_view(&s, 0, 25, 30, p, &b, 0, NULL);
        CHECK(!tu_frames_equal(&a, &b));
        CHECK(s.t.rc->cameras[0].elevation_deg == 15);
        for (int l = 0; l < o.n_lamps; l++) {
                gn_frame_free_data(&a);
                aps_render_lamp(&s, 0, 0, 0, l, &a, 0, NULL);
                for (int y = 0; y < a.height; y++)
                        for (int x = 0; x < a.width; x++)
                                for (int c = 0; c < 3; c++)
                                        hi = fmax(hi, rt_px(&a, x, y, c) / 65535);
        }
        fprintf(stderr, "brightest sample %.3f of full scale\n", hi);
        CHECK(hi > 0.4 && hi < 0.98);
        gn_frame_free_data(&a);
        gn_frame_free_data(&b);
        aps_close(&s);
}

/* The model's radiance T of channel ch at pixel p of view v for a light from direction d. */
static double model_radiance(const struct ap_model *m, const struct ap_view *v, size_t p,
                             const double d[3], int ch)
{
        double y[AP_ORDER_MAX * AP_ORDER_MAX], sum = 0;
        int D = 3 * m->n_coef;

        ap_sh_eval(m->order, d, y);
        for (int j = 0; j < m->n_coef; j++) {
                double c = m->mean[j * 3 + ch];
                for (int k = 0; k < m->k; k++)
                        c += v->weights[p * m->k + k] * m->basis[k * D + j * 3 + ch];
                sum += y[j] * c;
        }
        return sum;
}

/* The model's value of channel ch at pixel p of view v for a point light of the rig's
 * intensity at P (object frame) seen from surface point X: the reference evaluation. */
static double model_value(const struct ap_model *m, const struct ap_view *v, size_t p,
                          const double P[3], const float X[3], int ch)
{
        double d[3] = {P[0] - X[0], P[1] - X[1], P[2] - X[2]};
        double r = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);

        for (int k = 0; k < 3; k++)
                d[k] /= r;
        return model_radiance(m, v, p, d, ch) * m->light_distance_mm * m->light_distance_mm /
               (r * r);
}

/* PSNR (peak: full scale) inside the model's mask of view vi relit by a light at world
 * position Pw (the light arm at 0), against the simulator's image. */
static double heldout_psnr(struct apscene *s, const struct ap_model *m, size_t vi,
                           const double Pw[3])
{
        const struct ap_view *v = &m->views[vi];
        _cleanup_(sim_truth_free) struct sim_truth tr = {0};
        double P[3], a = -v->turntable_deg * DEG, sse = 0;
        struct gn_frame f;
        size_t n = 0;

        P[0] = cos(a) * Pw[0] - sin(a) * Pw[1];
        P[1] = sin(a) * Pw[0] + cos(a) * Pw[1];
        P[2] = Pw[2];
        aps_render_light(s, 0, v->turntable_deg, Pw, &f, SIM_TRUTH_POINT, &tr);
        for (size_t p = 0; p < (size_t)f.width * f.height; p++) {
                if (!v->mask[p] || isnan(tr.point[3 * p]))
                        continue;
                for (int ch = 0; ch < 3; ch++) {
                        double e = fmin(fmax(model_value(m, v, p, P, &tr.point[3 * p], ch), 0), 1) -
                                   rt_px(&f, (int)(p % f.width), (int)(p / f.width), ch) / 65535;
                        sse += e * e;
                        n++;
                }
        }
        gn_frame_free_data(&f);
        CHECK(n > 1000);
        return 10 * log10(n / sse);
}

/* Held-out PSNR figures. */
struct psnr {
        double worst, mean;
};

/* Fits the scene of material mat at order P with K components and returns the PSNR of
 * held-out lights between the fitted ones (light-arm angles and lamp elevations half-way),
 * in every view. */
static struct psnr heldout(enum aps_material mat, int P, int K)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        static const double elev[] = {-27, -2, 22, 47, 72};
        struct psnr q = {INFINITY, 0};
        struct ap_fit_opts o;
        struct aps_opts ao;
        struct apscene s;
        char path[512], err[512];
        double t0;
        int n = 0;

        aps_opts_default(&ao, mat);
        aps_open(&s, &ao);
        snprintf(path, sizeof(path), "%s/ds", dir);
        _cleanup_(ds_closep) struct ds *d = aps_make_dataset(&s, path);
        ap_fit_opts_default(&o);
        o.backends = registry_backends;
        o.order = P, o.k = K, o.tile = 2;
        t0 = now_s();
        CHECK_INT(ap_fit(d, &o, &m, err, sizeof(err)), 0);
        fprintf(stderr, "fit in %.3f s: rms sh %.5f pca %.5f; notes: %s\n", now_s() - t0, m->rms_sh,
                m->rms_pca, m->notes);
        for (size_t v = 0; v < m->n_views; v++)
                for (size_t e = 0; e < ELEMENTSOF(elev); e++)
                        for (int a = 0; a < 4; a++, n++) {
                                double az = (15 + 90 * a + 7 * e) * DEG, el = elev[e] * DEG;
                                double Pw[3] = {500 * cos(el) * cos(az), 500 * cos(el) * sin(az),
                                                500 * sin(el)};
                                double x = heldout_psnr(&s, m, v, Pw);
                                q.worst = fmin(q.worst, x);
                                q.mean += x / (2 * ELEMENTSOF(elev) * 4);
                        }
        aps_close(&s);
        return q;
}

/* Diffuse and moderately glossy (Beckmann alpha 0.3) at P = 6, K = 12: held-out lights at
 * 35 dB or better on average; the worst (a light behind the object, lighting a grazing rim)
 * above a floor. docs/appearance.md, "Fidelity". */
static void test_heldout(void)
{
        struct psnr diffuse = heldout(APS_DIFFUSE, 6, 12), glossy = heldout(APS_GLOSSY, 6, 12);

        fprintf(stderr, "held-out lights: diffuse mean %.2f dB (worst %.2f), glossy %.2f (%.2f)\n",
                diffuse.mean, diffuse.worst, glossy.mean, glossy.worst);
        CHECK(diffuse.mean >= 35 && diffuse.worst >= 32);
        CHECK(glossy.mean >= 35 && glossy.worst >= 24);
}

/* A fit of the dataset at path with the defaults but order P, K components and tiles of 4; *m
 * the model (ap_fit's return). */
static int fit_at(const char *path, int P, int K, struct ap_model **m, char *err, size_t errlen)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct ap_fit_opts o;

        CHECK_INT(ds_open(path, &d), 0);
        ap_fit_opts_default(&o);
        o.backends = registry_backends;
        o.order = P, o.k = K, o.tile = 4;
        *m = NULL;
        return ap_fit(d, &o, m, err, errlen);
}

/* A dataset of the scene of o at dir/name; returns its path (static buffer). */
static const char *make(const char *dir, const char *name, const struct aps_opts *o,
                        struct apscene *s)
{
        static char path[512];

        aps_open(s, o);
        snprintf(path, sizeof(path), "%s/%s", dir, name);
        ds_close(aps_make_dataset(s, path));
        return path;
}

/* Stores an image of camera 0 at turntable angle tt with no lamp lit. */
static void store_unlit(struct apscene *s, const char *path, double tt)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct ds_capture c = {.pose = {{tt, 0, NAN}, 0, false}, .exposure_us = 20000};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct gn_frame f;

        CHECK_INT(ds_open(path, &d), 0);
        snprintf(c.camera, sizeof(c.camera), "c0");
        CHECK_INT(sim_render(s->t.s, &c.pose, 0, &ex, 99, &f, 0, NULL), 0);
        CHECK_INT(ds_store(d, &f, &c), 0);
        gn_frame_free_data(&f);
}

/* Too few lights for the order: the highest order they support, stated. A view without a
 * lamp-lit capture: skipped, stated. No calibration: nominal geometry, stated; a calibration
 * file given that is not there: an error naming it. */
static void test_few_lights(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        struct aps_opts o;
        struct apscene s;
        char err[512];
        const char *path;

        aps_opts_default(&o, APS_DIFFUSE);
        o.n_lamps = 3, o.arm_angles = 5; /* 15 lights: order 3 */
        path = make(dir, "few", &o, &s);
        store_unlit(&s, path, 90);
        CHECK_INT(fit_at(path, 6, 12, &m, err, sizeof(err)), 0);
        fprintf(stderr, "notes: %s\n", m->notes);
        CHECK_INT(m->order, 3);
        CHECK_INT(m->n_views, 2);
        CHECK_STR_CONTAINS(m->notes, "order 6 needs 36 lights per view, a view has 15: order 3");
        CHECK_STR_CONTAINS(m->notes, "1 views without a lamp-lit capture skipped");
        CHECK_STR_CONTAINS(m->notes, "no calibration file");
        {
                _cleanup_(ds_closep) struct ds *d = NULL;
                struct ap_fit_opts fo;
                struct ap_model *none = NULL;
                CHECK_INT(ds_open(path, &d), 0);
                ap_fit_opts_default(&fo);
                fo.backends = registry_backends;
                fo.calibration = "/nonexistent/calibration.yaml";
                CHECK_INT(ap_fit(d, &fo, &none, err, sizeof(err)), -ENOENT);
                CHECK_STR_CONTAINS(err, "/nonexistent/calibration.yaml: No such file");
                CHECK(!none);
        }
        aps_close(&s);
}

/* Lights all on one side: regularised, stated; saturated pixels masked, stated. */
static void test_one_side(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        struct aps_opts o;
        struct apscene s;
        char err[512];
        size_t masked = 0;

        aps_opts_default(&o, APS_SHARP);
        o.n_lamps = 4, o.arm_angles = 12, o.intensity *= 3;
        o.lamp_elevation_deg[0] = 20, o.lamp_elevation_deg[1] = 40;
        o.lamp_elevation_deg[2] = 60, o.lamp_elevation_deg[3] = 80;
        CHECK_INT(fit_at(make(dir, "side", &o, &s), 6, 12, &m, err, sizeof(err)), 0);
        fprintf(stderr, "notes: %s\n", m->notes);
        CHECK_STR_CONTAINS(m->notes, "lights on part of the sphere only");
        CHECK_STR_CONTAINS(m->notes, "regularised, tikhonov 0.01");
        CHECK_STR_CONTAINS(m->notes, "pixels masked for a saturated sample");
        for (int l = 0; l < o.n_lamps; l++) { /* a saturated pixel is out of the mask */
                struct gn_frame f;
                aps_render_lamp(&s, 0, 0, 0, l, &f, 0, NULL);
                for (int p = 0; p < f.width * f.height; p++)
                        if (rt_px(&f, p % f.width, p / f.width, 0) >= 0.995 * 65535 ||
                            rt_px(&f, p % f.width, p / f.width, 1) >= 0.995 * 65535) {
                                CHECK_INT(m->views[0].mask[p], 0);
                                masked++;
                        }
                gn_frame_free_data(&f);
        }
        CHECK(masked > 0);
        aps_close(&s);
}

/* No lamp-lit image at all, bad options: clear errors. */
static void test_no_lamps(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct ap_fit_opts fo;
        struct aps_opts o;
        struct apscene s;
        char err[512];
        const char *path;

        aps_opts_default(&o, APS_DIFFUSE);
        o.turntable_angles = 0;
        path = make(dir, "dark", &o, &s);
        store_unlit(&s, path, 0);
        CHECK_INT(fit_at(path, 6, 12, &m, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "no image rows with one lamp lit");
        CHECK_INT(ds_open(path, &d), 0);
        ap_fit_opts_default(&fo);
        fo.backends = registry_backends;
        fo.order = 0;
        CHECK_INT(ap_fit(d, &fo, &m, err, sizeof(err)), -EINVAL);
        aps_close(&s);
}

/* Models a and b equal to the bit: basis, mean, every view's weights and mask. */
static void check_same_model(const struct ap_model *a, const struct ap_model *b)
{
        size_t D = 3 * (size_t)a->n_coef;

        CHECK_INT(a->k, b->k);
        CHECK_INT(a->n_views, b->n_views);
        CHECK(memcmp(a->mean, b->mean, D * sizeof(float)) == 0);
        CHECK(memcmp(a->basis, b->basis, D * a->k * sizeof(float)) == 0);
        for (size_t v = 0; v < a->n_views; v++) {
                size_t n = (size_t)a->views[v].cam.width * a->views[v].cam.height;
                CHECK(memcmp(a->views[v].mask, b->views[v].mask, n) == 0);
                CHECK(memcmp(a->views[v].weights, b->views[v].weights, n * a->k * sizeof(float)) ==
                      0);
        }
}

/* Overwrites the image of the row of camera c0 at turntable angle tt lit by lamp 0. */
static void spoil_image(const char *path, double tt)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_free_ struct ds_capture *rows = NULL;
        size_t n;
        bool done = false;

        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_rows_collect(d, NULL, NULL, &rows, &n), 0);
        for (size_t i = 0; i < n && !done; i++)
                if (fabs(rows[i].pose.deg[GN_ROLE_TURNTABLE] - tt) < 1e-6 &&
                    rows[i].pose.lamps == 1) {
                        char file[1024];
                        FILE *f;
                        snprintf(file, sizeof(file), "%s/%s", path, rows[i].file);
                        CHECK((f = fopen(file, "w")) != NULL);
                        fputs("not a PNG", f);
                        fclose(f);
                        done = true;
                }
        CHECK(done);
}

/* The views on 1, 2 and 3 threads: the same model to the bit (the pilot views, the PCA
 * fitted while the other views go on, views kept until the basis is known). An unreadable
 * image in a pilot view or another: the fit fails with its name, whatever the threads. */
static void test_threads(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *one = NULL;
        static const int threads[] = {1, 2, 3};
        struct aps_opts o;
        struct apscene s;
        char err[512];
        const char *path;

        aps_opts_default(&o, APS_GLOSSY);
        o.turntable_angles = 10, o.n_lamps = 3, o.arm_angles = 6; /* pilots: 0, 2, 4, 6, 8 */
        path = make(dir, "views", &o, &s);
        for (int t = 0; t < 3; t++) {
                _cleanup_(ds_closep) struct ds *d = NULL;
                _cleanup_(ap_model_freep) struct ap_model *m = NULL;
                struct ap_fit_opts fo;
                CHECK_INT(ds_open(path, &d), 0);
                ap_fit_opts_default(&fo);
                fo.backends = registry_backends;
                fo.order = 4, fo.k = 8, fo.tile = 4, fo.threads = threads[t];
                CHECK_INT(ap_fit(d, &fo, t ? &m : &one, err, sizeof(err)), 0);
                CHECK_INT(one->n_views, 10);
                if (m)
                        check_same_model(one, m);
        }
        for (int bad = 0; bad < 2; bad++) { /* view 1, then the pilot view 8 */
                spoil_image(path, bad ? 288 : 36);
                for (int t = 0; t < 2; t++) {
                        _cleanup_(ds_closep) struct ds *d = NULL;
                        struct ap_model *m = NULL;
                        struct ap_fit_opts fo;
                        CHECK_INT(ds_open(path, &d), 0);
                        ap_fit_opts_default(&fo);
                        fo.backends = registry_backends;
                        fo.order = 4, fo.k = 8, fo.tile = 4, fo.threads = threads[t];
                        CHECK_INT(ap_fit(d, &fo, &m, err, sizeof(err)), -EBADMSG);
                        CHECK_STR_CONTAINS(err, ".png: ");
                        CHECK(!m);
                }
        }
        aps_close(&s);
}

#ifdef AP_CALFILE
/* A calibration file with the lamps' sections: used (stated as calibrated), its positions
 * those of the fit (a lamp moved 100 mm in the file changes the model). */
static void test_calibration(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL, *moved = NULL;
        struct aps_opts o;
        struct apscene s;
        char err[512], cal[600];
        const char *path;
        double diff = 0;

        aps_opts_default(&o, APS_DIFFUSE);
        o.n_lamps = 4, o.arm_angles = 12;
        path = make(dir, "cal", &o, &s);
        snprintf(cal, sizeof(cal), "%s/calibration.yaml", path);
        for (int l = 0; l < o.n_lamps; l++) {
                struct cal_lamp_pos lp = {.rms_mm = 0.1, .n_obs = 10};
                snprintf(lp.name, sizeof(lp.name), "l%d", l);
                aps_lamp_position(&s, l, 0, lp.pos);
                CHECK_INT(cal_lamp_write(cal, &lp, true, err, sizeof(err)), 0);
        }
        CHECK_INT(fit_at(path, 4, 12, &m, err, sizeof(err)), 0);
        fprintf(stderr, "notes: %s\n", m->notes);
        CHECK_STR_CONTAINS(m->notes, "0 of 2 views' cameras and 96 of 96 lights' lamps calibrated");
        {
                struct cal_lamp_pos lp = {.name = "l0", .rms_mm = 0.01, .n_obs = 10};
                aps_lamp_position(&s, 0, 0, lp.pos);
                lp.pos[2] += 100;
                CHECK_INT(cal_lamp_write(cal, &lp, true, err, sizeof(err)), 0);
        }
        CHECK_INT(fit_at(path, 4, 12, &moved, err, sizeof(err)), 0);
        for (int i = 0; i < 48; i++)
                diff = fmax(diff, fabs(m->mean[i] - moved->mean[i]));
        CHECK(diff > 1e-3);
        aps_close(&s);
}
#endif

/* gonioctl model fit through the command line: written, read back, not replaced without
 * --force, options checked. */
static void test_gonioctl(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        struct aps_opts o;
        struct apscene s;
        char args[1024], out[8192], mdir[600], err[512];
        const char *path;

        if (!getenv("GONIOCTL"))
                exit(TEST_SKIP);
        aps_opts_default(&o, APS_GLOSSY);
        path = make(dir, "cli", &o, &s);
        snprintf(args, sizeof(args),
                 "--json model fit %s --name m1 --order 4 --components 8 "
                 "--tile 4 --reg tsvd",
                 path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "\"order\":4");
        snprintf(mdir, sizeof(mdir), "%s/models/m1", path);
        CHECK_INT(ap_model_read(mdir, &m, err, sizeof(err)), 0);
        CHECK_INT(m->order, 4);
        CHECK_INT(m->k, 8);
        CHECK_INT(m->n_views, 2);
        CHECK_STR(m->reg, "tsvd");
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "exists (--force replaces it)");
        snprintf(args, sizeof(args), "model fit %s --name m1 --force", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "order 6, 12 components, 2 views");
        snprintf(args, sizeof(args), "model fit %s --order 11", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        CHECK_INT(test_run_gonioctl("model fit /nonexistent", out, sizeof(out)), 6);
        CHECK_INT(test_run_gonioctl("model", out, sizeof(out)), 2);
        aps_close(&s);
}

/* Scales the 16-bit samples of f by k and adds b (full scale 1), clipping at full scale. */
static void expose(struct gn_frame *f, double k, double b)
{
        uint16_t *px = (uint16_t *)f->data;

        for (int i = 0; i < f->width * f->height * 3; i++)
                px[i] = (uint16_t)lrint(fmin(px[i] * k + b * 65535, 65535));
}

/* The scene's dataset taken as two brackets (2x and 1/2 the exposure, the long one saturated
 * on the highlights) over a dark frame: merged and dark-subtracted, the fit gives the model
 * of the plain dataset, in units of its base exposure (the long one, twice the plain's);
 * order 3 and K = 27, a lossless PCA, to compare the fits alone. */
/* The hdr dataset of test_hdr at path: per light two brackets (40 ms: 2x, saturating; 10 ms:
 * 1/2) over one dark frame of 0.02 full scale that every image references. */
static void make_hdr(struct apscene *s, const char *path)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct ds_capture dk = {.pose = {{0, 0, NAN}, 0}, .exposure_us = 40000, .kind = "dark"};
        struct gn_frame f;

        CHECK_INT(ds_create(path, "hdr", s->t.rc->text, &d), 0);
        aps_write_mesh(s, path);
        snprintf(dk.camera, sizeof(dk.camera), "c0");
        aps_render_lamp(s, 0, 0, 0, 0, &f, 0, NULL);
        expose(&f, 0, 0.02);
        CHECK_INT(ds_store(d, &f, &dk), 0);
        gn_frame_free_data(&f);
        for (int v = 0; v < 2; v++)
                for (int a = 0; a < 12; a++)
                        for (int l = 0; l < 6; l++)
                                for (int b = 0; b < 2; b++) {
                                        struct ds_capture c = {
                                                .pose = {{180.0 * v, 30.0 * a, NAN}, 1u << l},
                                                .exposure_us = b ? 10000 : 40000,
                                                .bracket = b,
                                                .dark_id = dk.id};
                                        snprintf(c.camera, sizeof(c.camera), "c0");
                                        aps_render_lamp(s, 0, 180.0 * v, 30.0 * a, l, &f, 0, NULL);
                                        expose(&f, b ? 0.5 : 2, 0.02);
                                        CHECK_INT(ds_store(d, &f, &c), 0);
                                        gn_frame_free_data(&f);
                                }
}

/* The scene's dataset taken as two brackets (2x and 1/2 the exposure, the long one saturated
 * on the highlights) over a dark frame: merged and dark-subtracted, the fit gives the model
 * of the plain dataset, in units of its base exposure (the long one, twice the plain's);
 * order 3 and K = 27, a lossless PCA, to compare the fits alone. */
static void test_hdr(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *plain = NULL, *hdr = NULL;
        const double d[3] = {0.36, -0.48, 0.8};
        struct aps_opts o;
        struct apscene s;
        char path[512], err[512];
        double worst = 0;

        aps_opts_default(&o, APS_GLOSSY);
        o.arm_angles = 12;
        CHECK_INT(fit_at(make(dir, "plain", &o, &s), 3, 27, &plain, err, sizeof(err)), 0);
        snprintf(path, sizeof(path), "%s/hdr", dir);
        make_hdr(&s, path);
        CHECK_INT(fit_at(path, 3, 27, &hdr, err, sizeof(err)), 0);
        fprintf(stderr, "notes: %s\n", hdr->notes);
        CHECK_INT(hdr->n_views, 2);
        for (size_t v = 0; v < 2; v++)
                for (int p = 0; p < o.width * o.height; p++) {
                        if (!plain->views[v].mask[p])
                                continue;
                        CHECK(hdr->views[v].mask[p]);
                        for (int ch = 0; ch < 3; ch++) /* the base: 40 ms, twice the plain's */
                                worst = fmax(
                                        worst,
                                        fabs(2 * model_radiance(plain, &plain->views[v], p, d, ch) -
                                             model_radiance(hdr, &hdr->views[v], p, d, ch)));
                }
        fprintf(stderr, "largest difference of the relit values %.3g\n", worst);
        CHECK(worst < 1e-4);
        aps_close(&s);
}

/* Light directions over the whole sphere: 6 elevations x 18 azimuths, as the light arm
 * gives them. */
static void sphere_dirs(double (*d)[3])
{
        for (int e = 0; e < 6; e++)
                for (int a = 0; a < 18; a++) {
                        double el = (-75 + 30 * e) * DEG, az = 20 * a * DEG;
                        d[e * 18 + a][0] = cos(el) * cos(az);
                        d[e * 18 + a][1] = cos(el) * sin(az);
                        d[e * 18 + a][2] = sin(el);
                }
}

/* The solve of an exactly band-limited function (order 6) sampled in 108 directions, in
 * float: coefficients recovered to float precision, by both regularisations. */
static void test_bandlimited_solve(void)
{
        enum { L = 108, M = 36 };
        static double dirs[L][3], A[L * M];
        float P[M * L], b[L];
        double c[M], worst = 0, cond;

        sphere_dirs(dirs);
        srand(7);
        for (int m = 0; m < M; m++)
                c[m] = (double)rand() / RAND_MAX - 0.5;
        for (int j = 0; j < L; j++) {
                double y[M], v = 0;
                ap_sh_eval(6, dirs[j], y);
                for (int m = 0; m < M; m++)
                        v += (A[j * M + m] = y[m]) * c[m];
                b[j] = (float)v;
        }
        for (int reg = AP_REG_TIKHONOV; reg <= AP_REG_TSVD; reg++) {
                CHECK_INT(ap_fit_pinv(A, L, M, reg, reg == AP_REG_TSVD ? 1e-3 : 0, P, &cond), 0);
                for (int m = 0; m < M; m++) {
                        double x = 0;
                        for (int j = 0; j < L; j++)
                                x += P[m * L + j] * b[j];
                        worst = fmax(worst, fabs(x - c[m]));
                }
        }
        fprintf(stderr, "condition number %.3g, largest coefficient error %.3g\n", cond, worst);
        CHECK(worst < 2e-6);
}

/* The sphere's point seen at pixel p of camera 0 at turntable angle tt, in the object frame;
 * false where the pixel sees no sphere (or only its rim). */
static bool sphere_point(const struct apscene *s, double tt, int p, double X[3])
{
        struct gn_pose st = {{tt, 0, NAN}, 0, false};
        struct sim_cam_geom g;
        double d[3], C[3], q[3], b, cc, t, a = -tt * DEG, r = APS_SIZE_MM / 2;

        CHECK_INT(sim_camera_geom(s->t.s, &st, 0, &g), 0);
        q[0] = (p % g.width - g.cx) / g.fx, q[1] = (p / g.width - g.cy) / g.fy, q[2] = 1;
        for (int k = 0; k < 3; k++) { /* world: d = R^T q, C = -R^T t, less the centre */
                d[k] = g.R[k] * q[0] + g.R[3 + k] * q[1] + g.R[6 + k] * q[2];
                C[k] = -(g.R[k] * g.t[0] + g.R[3 + k] * g.t[1] + g.R[6 + k] * g.t[2]);
        }
        C[2] -= r;
        b = C[0] * d[0] + C[1] * d[1] + C[2] * d[2];
        cc = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        t = b * b - cc * (C[0] * C[0] + C[1] * C[1] + C[2] * C[2] - 0.8 * r * r);
        if (t < 0) /* the inner 0.9 of the radius: away from the silhouette */
                return false;
        t = (-b - sqrt(b * b - cc * (C[0] * C[0] + C[1] * C[1] + C[2] * C[2] - r * r))) / cc;
        for (int k = 0; k < 3; k++)
                q[k] = C[k] + t * d[k] + (k == 2 ? r : 0);
        X[0] = cos(a) * q[0] - sin(a) * q[1], X[1] = sin(a) * q[0] + cos(a) * q[1], X[2] = q[2];
        return true;
}

/* The band-limited coefficients (order 4) of pixel p, view tt, channel ch: the mean plus
 * sum_k a_k(p) b_k, a 7-dimensional affine set (basis: 8 rows of 48). */
static double bl_coef(const double *basis, int p, double tt, int m, int ch)
{
        double c = basis[m * 3 + ch];

        for (int k = 1; k <= 7; k++)
                c += sin(p * 0.37 * k + tt + k) * 0.5 * basis[k * 48 + m * 3 + ch];
        return c;
}

/* The 16-bit image of view tt, light (lamp, arm) of the band-limited radiance (coef: 48 per
 * pixel, bl_coef), with the
 * lamp's inverse-square falloff from the sphere's points pts (sphere_point; NAN: none seen,
 * 0.5). */
static void bandlimited_frame(const struct apscene *s, double tt, int lamp, double arm,
                              const double *coef, const double *pts, struct gn_frame *f)
{
        double P[3], W[3], a = -tt * DEG, R = s->o.lamp_radius_mm;

        aps_lamp_position(s, lamp, arm, W);
        P[0] = cos(a) * W[0] - sin(a) * W[1], P[1] = sin(a) * W[0] + cos(a) * W[1], P[2] = W[2];
        CHECK_INT(gn_frame_alloc(f, s->o.width, s->o.height, 3, 16), 0);
        for (int p = 0; p < f->width * f->height; p++) {
                const double *X = &pts[3 * p];
                double d[3], y[16], r;
                bool hit = !isnan(X[0]);
                for (int k = 0; k < 3; k++)
                        d[k] = P[k] - (hit ? X[k] : 0);
                r = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                for (int k = 0; k < 3; k++)
                        d[k] /= r;
                ap_sh_eval(4, d, y);
                for (int ch = 0; ch < 3; ch++) {
                        double v = 0;
                        for (int m = 0; m < 16; m++)
                                v += y[m] * coef[48 * p + m * 3 + ch];
                        v = hit ? v * R * R / (r * r) : 0.5;
                        ((uint16_t *)f->data)[3 * p + ch] = (uint16_t)lrint(v * 65535);
                }
        }
}

/* The whole fit of a synthetic dataset whose radiance on the sphere is exactly band-limited
 * (order 4; the lamps' falloff and direction from each point, the true mesh, tiles of one
 * pixel), PCA with K = 8 on a 7-dimensional set: the model gives the radiance back to the
 * images' 16-bit precision. */
/* The dataset of test_bandlimited at path: 2 views x 108 lights of bandlimited_frame. */
static void make_bandlimited(struct apscene *s, const char *path, const double *basis)
{
        static double pts[3 * 96 * 72], coef[48 * 96 * 72];
        _cleanup_(ds_closep) struct ds *d = NULL;
        int n = s->o.width * s->o.height;

        CHECK(n <= 96 * 72);
        CHECK_INT(ds_create(path, "bandlimited", s->t.rc->text, &d), 0);
        aps_write_mesh(s, path);
        for (int v = 0; v < 2; v++) {
                for (int p = 0; p < n; p++) {
                        if (!sphere_point(s, 90.0 * v, p, &pts[3 * p]))
                                pts[3 * p] = NAN;
                        for (int i = 0; i < 48; i++)
                                coef[48 * p + i] = bl_coef(basis, p, 90.0 * v, i / 3, i % 3);
                }
                for (int a = 0; a < 18; a++)
                        for (int l = 0; l < 6; l++) {
                                struct ds_capture c = {.pose = {{90.0 * v, 20.0 * a, NAN}, 1u << l},
                                                       .exposure_us = 20000};
                                struct gn_frame f;
                                snprintf(c.camera, sizeof(c.camera), "c0");
                                bandlimited_frame(s, 90.0 * v, l, 20.0 * a, coef, pts, &f);
                                CHECK_INT(ds_store(d, &f, &c), 0);
                                gn_frame_free_data(&f);
                        }
        }
}

/* The whole fit of a synthetic dataset whose radiance on the sphere is exactly band-limited
 * (order 4; the lamps' falloff and direction from each point, the true mesh, tiles of one
 * pixel), PCA with K = 8 on a 7-dimensional set: the model gives the radiance back to the
 * images' 16-bit precision. */
static void test_bandlimited(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        _cleanup_(ds_closep) struct ds *d = NULL;
        static double basis[8 * 48], dirs[108][3];
        struct ap_fit_opts fo;
        struct aps_opts o;
        struct apscene s;
        char path[512], err[512];
        double worst = 0;

        aps_opts_default(&o, APS_DIFFUSE);
        o.lamp_radius_mm = 1e5, o.intensity = 1;
        for (int e = 0; e < 6; e++)
                o.lamp_elevation_deg[e] = -75 + 30 * e;
        for (int i = 0; i < 8 * 48; i++) /* row 0 the mean: 0.5 in band 0; rows 1-7 small */
                basis[i] = i < 48 ? (i < 3 ? 0.5 / 0.28209479177387814 : 0) : 0.006 * sin(i * 1.3);
        aps_open(&s, &o);
        snprintf(path, sizeof(path), "%s/ds", dir);
        make_bandlimited(&s, path, basis);
        CHECK_INT(ds_open(path, &d), 0);
        ap_fit_opts_default(&fo);
        fo.backends = registry_backends;
        fo.order = 4, fo.k = 8, fo.reg = AP_REG_TSVD, fo.reg_param = 1e-4, fo.tile = 1;
        CHECK_INT(ap_fit(d, &fo, &m, err, sizeof(err)), 0);
        sphere_dirs(dirs);
        for (size_t v = 0; v < m->n_views; v++)
                for (int p = 0; p < o.width * o.height; p++) {
                        double X[3], y[16], truth;
                        if (!sphere_point(&s, 90.0 * v, p, X))
                                continue;
                        CHECK(m->views[v].mask[p]);
                        for (int j = 0; j < 108; j += 5) {
                                ap_sh_eval(4, dirs[j], y);
                                truth = 0;
                                for (int q = 0; q < 16; q++)
                                        truth += y[q] * bl_coef(basis, p, 90.0 * v, q, 1);
                                worst = fmax(worst,
                                             fabs(model_radiance(m, &m->views[v], p, dirs[j], 1) -
                                                  truth));
                        }
                }
        fprintf(stderr, "largest error of the relit radiance %.3g (16-bit step %.3g); notes: %s\n",
                worst, 1 / 65535.0, m->notes);
        CHECK(worst < 3e-5);
        aps_close(&s);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"scene", test_scene},
                {"heldout", test_heldout},
                {"bandlimited-solve", test_bandlimited_solve},
                {"bandlimited", test_bandlimited},
                {"hdr", test_hdr},
                {"few-lights", test_few_lights},
                {"one-side", test_one_side},
                {"no-lamps", test_no_lamps},
                {"threads", test_threads},
                {"gonioctl", test_gonioctl},
#ifdef AP_CALFILE
                {"calibration", test_calibration},
#endif
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
