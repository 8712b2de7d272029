/* test-model.c - the SH basis (appearance/sh.h) against quadrature and closed forms, and the
 * model's files (appearance/model.h) written and read back, and refused when malformed. */
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>

#include "appearance/model.h"
#include "appearance/sh.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "tests/dataset/ds-util.h"
#include "tests/test.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);

static void rm_rfp(char **dir)
{
        if (*dir)
                tu_rm_rf(*dir);
        free(*dir);
}

#define GL_N   24 /* Gauss-Legendre nodes in z: exact to degree 47 */
#define PHI_N  48 /* uniform in phi: exact for frequencies below 48 */
#define N_MAXC (AP_ORDER_MAX * AP_ORDER_MAX)

/* Gauss-Legendre nodes and weights on [-1, 1] by Newton's method. */
static void gauss_legendre(int n, double *x, double *w)
{
        for (int i = 0; i < n; i++) {
                double z = cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0;
                for (int it = 0; it < 100; it++) {
                        double p0 = 1, p1 = z;
                        for (int k = 2; k <= n; k++) {
                                double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
                                p0 = p1;
                                p1 = p2;
                        }
                        dp = n * (z * p1 - p0) / (z * z - 1);
                        z -= p1 / dp;
                }
                x[i] = z;
                w[i] = 2 / ((1 - z * z) * dp * dp);
        }
}

/* The Gram matrix of the basis of order AP_ORDER_MAX is the identity. */
static void test_orthonormal(void)
{
        static double G[N_MAXC][N_MAXC];
        double x[GL_N], w[GL_N], y[N_MAXC], worst = 0;

        gauss_legendre(GL_N, x, w);
        for (int i = 0; i < GL_N; i++)
                for (int j = 0; j < PHI_N; j++) {
                        double phi = 2 * M_PI * j / PHI_N, s = sqrt(1 - x[i] * x[i]);
                        double d[3] = {s * cos(phi), s * sin(phi), x[i]};
                        ap_sh_eval(AP_ORDER_MAX, d, y);
                        for (int a = 0; a < N_MAXC; a++)
                                for (int b = 0; b < N_MAXC; b++)
                                        G[a][b] += w[i] * 2 * M_PI / PHI_N * y[a] * y[b];
                }
        for (int a = 0; a < N_MAXC; a++)
                for (int b = 0; b < N_MAXC; b++)
                        worst = fmax(worst, fabs(G[a][b] - (a == b)));
        fprintf(stderr, "Gram matrix of %d functions: largest error %.3g\n", N_MAXC, worst);
        CHECK(worst < 1e-12);
}

/* Bands 0-3 against their closed forms (no Condon-Shortley phase), and the float version. */
static void test_closed_forms(void)
{
        const double d[3] = {0.36, -0.48, 0.8};
        const double x = d[0], y = d[1], z = d[2], pi = M_PI;
        const double want[16] = {
                0.5 / sqrt(pi),
                sqrt(3 / (4 * pi)) * y,
                sqrt(3 / (4 * pi)) * z,
                sqrt(3 / (4 * pi)) * x,
                0.5 * sqrt(15 / pi) * x * y,
                0.5 * sqrt(15 / pi) * y * z,
                0.25 * sqrt(5 / pi) * (3 * z * z - 1),
                0.5 * sqrt(15 / pi) * x * z,
                0.25 * sqrt(15 / pi) * (x * x - y * y),
                0.25 * sqrt(35 / (2 * pi)) * y * (3 * x * x - y * y),
                0.5 * sqrt(105 / pi) * x * y * z,
                0.25 * sqrt(21 / (2 * pi)) * y * (5 * z * z - 1),
                0.25 * sqrt(7 / pi) * z * (5 * z * z - 3),
                0.25 * sqrt(21 / (2 * pi)) * x * (5 * z * z - 1),
                0.25 * sqrt(105 / pi) * z * (x * x - y * y),
                0.25 * sqrt(35 / (2 * pi)) * x * (x * x - 3 * y * y),
        };
        const float df[3] = {0.36f, -0.48f, 0.8f};
        double got[16];
        float gotf[N_MAXC];
        double all[N_MAXC];

        ap_sh_eval(4, d, got);
        for (int i = 0; i < 16; i++)
                CHECK_NEAR(got[i], want[i], 1e-14);
        ap_sh_eval(AP_ORDER_MAX, d, all);
        ap_sh_evalf(AP_ORDER_MAX, df, gotf);
        for (int i = 0; i < N_MAXC; i++) {
                CHECK_NEAR(gotf[i], all[i], 2e-5 * (1 + fabs(all[i])));
                if (i < 16)
                        CHECK_NEAR(all[i], want[i], 1e-14); /* a higher order, same values */
        }
}

/* A small model with every field set. */
static struct ap_model *sample_model(void)
{
        struct ap_model *m;

        CHECK_INT(ap_model_new(3, 5, 2, &m), 0);
        snprintf(m->name, sizeof(m->name), "m1");
        snprintf(m->notes, sizeof(m->notes), "order 3: \"few\" lights");
        snprintf(m->reg, sizeof(m->reg), "tikhonov");
        m->light_distance_mm = 500, m->light_intensity = 3e5, m->reg_param = 1e-3;
        m->rms_sh = 0.01, m->rms_pca = 0.002, m->fit_seconds = 1.5;
        for (int i = 0; i < 27 * 6; i++)
                (i < 27 ? m->mean : m->basis)[i % 27 + (i >= 27 ? i - 27 - i % 27 : 0)] =
                        (float)sin(i);
        for (size_t v = 0; v < 2; v++) {
                struct ap_view *w = &m->views[v];
                snprintf(w->camera, sizeof(w->camera), "c%zu", v);
                w->turntable_deg = 30.0 * v, w->camera_arm_deg = v ? NAN : 5;
                w->dir[2] = 1;
                w->cam = (struct ap_camera){.width = 7 + v,
                                            .height = 5,
                                            .fx = 100,
                                            .fy = 101,
                                            .cx = 3.5,
                                            .cy = 2,
                                            .dist = {0.1, -0.01},
                                            .R = {1, 0, 0, 0, 1, 0, 0, 0, 1},
                                            .t = {0, 0, 400}};
                CHECK_INT(ap_view_alloc(w, m->k), 0);
                for (int p = 0; p < w->cam.width * 5; p++) {
                        w->mask[p] = p % 3 != 0;
                        for (int k = 0; k < m->k; k++)
                                w->weights[p * m->k + k] =
                                        w->mask[p] ? (float)cos(p * 0.7 + k) * k : 0;
                }
        }
        return m;
}

static void check_same(const struct ap_model *a, const struct ap_model *b)
{
        CHECK_STR(b->name, a->name);
        CHECK_STR(b->notes, a->notes);
        CHECK_STR(b->reg, a->reg);
        CHECK_INT(b->order, a->order);
        CHECK_INT(b->k, a->k);
        CHECK_INT(b->n_views, a->n_views);
        CHECK_NEAR(b->light_distance_mm, a->light_distance_mm, 0);
        CHECK_NEAR(b->rms_pca, a->rms_pca, 1e-12);
        for (int i = 0; i < 27; i++)
                CHECK(b->mean[i] == a->mean[i]);
        for (int i = 0; i < 27 * a->k; i++)
                CHECK(b->basis[i] == a->basis[i]);
        for (size_t v = 0; v < a->n_views; v++) {
                const struct ap_view *x = &a->views[v], *y = &b->views[v];
                CHECK_STR(y->camera, x->camera);
                CHECK(isnan(x->camera_arm_deg) ? isnan(y->camera_arm_deg)
                                               : y->camera_arm_deg == x->camera_arm_deg);
                CHECK(memcmp(&y->cam, &x->cam, sizeof(x->cam)) == 0);
                for (int p = 0; p < x->cam.width * x->cam.height; p++) {
                        CHECK_INT(y->mask[p], x->mask[p]);
                        for (int k = 0; k < a->k; k++) /* 16-bit quantisation over [-4, 4] */
                                CHECK_NEAR(y->weights[p * a->k + k], x->weights[p * a->k + k],
                                           5e-5 * k + 1e-7);
                }
        }
}

/* Written, read back equal (weights to their 16-bit quantisation), rewritten in place. */
static void test_roundtrip(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = sample_model(), *r = NULL, *r2 = NULL;
        char path[512], err[512];

        CHECK_INT(ap_model_write(m, dir), 0);
        snprintf(path, sizeof(path), "%s/models/m1", dir);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), 0);
        check_same(m, r);
        m->views[0].weights[1 * 5 + 4] = 9; /* replaced whole */
        CHECK_INT(ap_model_write(m, dir), 0);
        CHECK_INT(ap_model_read(path, &r2, err, sizeof(err)), 0);
        check_same(m, r2);
        snprintf(path, sizeof(path), "%s/models/.m1.tmp", dir);
        CHECK(access(path, F_OK) < 0);
        snprintf(path, sizeof(path), "%s/models/none", dir);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), -ENOENT);
}

/* Replaces file of the model at dir with text (len bytes). */
static void put(const char *dir, const char *file, const void *text, size_t len)
{
        char path[512];

        snprintf(path, sizeof(path), "%s/%s", dir, file);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, text, len, NULL), 0);
}

/* Each malformed file refused with its name and the problem. */
static void test_malformed(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_model_freep) struct ap_model *m = sample_model(), *r = NULL;
        char path[512], err[512];

        CHECK_INT(ap_model_write(m, dir), 0);
        snprintf(path, sizeof(path), "%s/models/m1", dir);
        put(path, "basis.f32", "abcd", 4);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "basis.f32: 4 bytes");
        put(path, "views/001_w1.png", "not a png", 9);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "views/001_w1.png: not a PNG");
        put(path, "views/001_w0.png", NULL, 0);
        snprintf(err, sizeof(err), "%s/views/000_mask.png", path);
        CHECK_INT(unlink(err), 0);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "views/000_mask.png: No such file");
        put(path, "model.json", "{\"format\": \"gonio-appearance 1\", \"name\": 3}", 43);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "model.json: ");
        put(path, "model.json", "{", 1);
        CHECK_INT(ap_model_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "model.json: line 1");
        CHECK(r == NULL);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"sh-orthonormal", test_orthonormal},
                {"sh-closed-forms", test_closed_forms},
                {"io-roundtrip", test_roundtrip},
                {"io-malformed", test_malformed},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
