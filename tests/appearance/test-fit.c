/* test-fit.c - the appearance fit (appearance/fit.h) on synthetic datasets (apscene.h). */
#include <math.h>
#include <stdlib.h>
#include <time.h>

#include "appearance/fit.h"
#include "appearance/sh.h"
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
        fprintf(stderr, "dataset of 120 captures in %.2f s\n", now_s() - t0);
        aps_render_lamp(&s, 0, 30, 60, 2, &a, 0, NULL);
        aps_lamp_position(&s, 2, 60, p);
        aps_render_light(&s, 0, 30, p, &b, 0, NULL);
        CHECK(tu_frames_equal(&a, &b));
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

/* The model's value of channel ch at pixel p of view v for a point light of the rig's
 * intensity at P (object frame) seen from surface point X: the reference evaluation. */
static double model_value(const struct ap_model *m, const struct ap_view *v, size_t p,
                          const double P[3], const float X[3], int ch)
{
        double d[3] = {P[0] - X[0], P[1] - X[1], P[2] - X[2]}, y[AP_ORDER_MAX * AP_ORDER_MAX];
        double r = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), sum = 0;
        int D = 3 * m->n_coef;

        for (int k = 0; k < 3; k++)
                d[k] /= r;
        ap_sh_eval(m->order, d, y);
        for (int j = 0; j < m->n_coef; j++) {
                double c = m->mean[j * 3 + ch];
                for (int k = 0; k < m->k; k++)
                        c += v->weights[p * m->k + k] * m->basis[k * D + j * 3 + ch];
                sum += y[j] * c;
        }
        return sum * m->light_distance_mm * m->light_distance_mm / (r * r);
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

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"scene", test_scene},
                {"heldout", test_heldout},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
