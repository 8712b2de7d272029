/* test-views.c - the triangulated sphere of sampled views (appearance/views.h): weights that
 * sum to 1, exact at the sampled views, gnomonic inside faces, continuous across faces and
 * outside the covered region; and the environment maps (appearance/envmap.h): a map of a
 * known SH function projects back onto its coefficients, bad files are refused. */
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "appearance/envmap.h"
#include "appearance/model.h"
#include "appearance/sh.h"
#include "appearance/views.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds_png.h"
#include "tests/dataset/ds-util.h"
#include "tests/test.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_views *, ap_views_free);

#define MAX_VIEWS 64

static void dir_of(double az_deg, double el_deg, double d[3])
{
        double az = az_deg * M_PI / 180, el = el_deg * M_PI / 180;

        d[0] = cos(el) * cos(az), d[1] = cos(el) * sin(az), d[2] = sin(el);
}

/* n_az azimuths at each of the n_el elevations els: the rig's grid of views. */
static size_t grid(int n_az, const double *els, int n_el, double (*dirs)[3])
{
        size_t n = 0;

        for (int e = 0; e < n_el; e++)
                for (int a = 0; a < n_az; a++)
                        dir_of(360.0 * a / n_az + 7 * e, els[e], dirs[n++]);
        return n;
}

static double rnd(void)
{
        return rand() / (RAND_MAX + 1.0);
}

static void random_dir(float d[3])
{
        double z = 2 * rnd() - 1, phi = 2 * M_PI * rnd(), s = sqrt(1 - z * z);

        d[0] = (float)(s * cos(phi)), d[1] = (float)(s * sin(phi)), d[2] = (float)z;
}

/* The weights as a dense vector over the views. */
static void dense(const struct ap_views *v, const float d[3], size_t n, double *out)
{
        int idx[3];
        float w[3];
        int k = ap_views_weights(v, d, idx, w);

        CHECK(k >= 1 && k <= 3);
        for (size_t i = 0; i < n; i++)
                out[i] = 0;
        for (int j = 0; j < 3; j++) {
                CHECK(idx[j] >= 0 && (size_t)idx[j] < n);
                CHECK(w[j] >= 0);
                out[idx[j]] += w[j];
        }
}

/* Sums, exactness at the views, continuity along random short steps within 20 degrees of
 * the covered region (beyond, the nearest boundary point jumps where two are equally near:
 * docs/appearance.md). */
static void check_views(const double (*dirs)[3], size_t n, double max_jump)
{
        _cleanup_(ap_views_freep) struct ap_views *v = NULL;
        double a[MAX_VIEWS], b[MAX_VIEWS];

        CHECK_INT(ap_views_new(dirs, n, &v), 0);
        for (size_t i = 0; i < n; i++) {
                float d[3] = {(float)dirs[i][0], (float)dirs[i][1], (float)dirs[i][2]};
                dense(v, d, n, a);
                CHECK_NEAR(a[i], 1, 1e-5);
                CHECK_NEAR(ap_views_outside_angle(v, dirs[i]), 0, 1e-3);
        }
        for (int t = 0; t < 20000; t++) {
                float d[3], e[3];
                double sum = 0, jump = 0, len;
                random_dir(d);
                for (int j = 0; j < 3; j++)
                        e[j] = d[j] + (float)(1e-4 * (rnd() - 0.5));
                len = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
                for (int j = 0; j < 3; j++)
                        e[j] /= (float)len;
                dense(v, d, n, a);
                dense(v, e, n, b);
                for (size_t i = 0; i < n; i++) {
                        sum += a[i];
                        jump = fmax(jump, fabs(a[i] - b[i]));
                }
                CHECK_NEAR(sum, 1, 1e-5);
                if (ap_views_outside_angle(v, (double[3]){d[0], d[1], d[2]}) > 20 * M_PI / 180)
                        continue;
                if (jump > max_jump)
                        fprintf(stderr, "jump %g at (%g %g %g)\n", jump, d[0], d[1], d[2]);
                CHECK(jump <= max_jump);
        }
}

/* Inside a face the blend of the views' directions points along d (gnomonic weights). */
static void check_gnomonic(const double (*dirs)[3], size_t n)
{
        _cleanup_(ap_views_freep) struct ap_views *v = NULL;
        int inside = 0;

        CHECK_INT(ap_views_new(dirs, n, &v), 0);
        CHECK(ap_views_n_faces(v) > 0);
        for (int t = 0; t < 5000; t++) {
                float d[3], w[3];
                double dd[3], s[3] = {0}, c[3];
                int idx[3];
                random_dir(d);
                for (int j = 0; j < 3; j++)
                        dd[j] = d[j];
                if (ap_views_outside_angle(v, dd) > 0)
                        continue;
                inside++;
                ap_views_weights(v, d, idx, w);
                for (int j = 0; j < 3; j++)
                        for (int a = 0; a < 3; a++)
                                s[a] += w[j] * dirs[idx[j]][a];
                c[0] = s[1] * dd[2] - s[2] * dd[1];
                c[1] = s[2] * dd[0] - s[0] * dd[2];
                c[2] = s[0] * dd[1] - s[1] * dd[0];
                CHECK(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) < 1e-5);
                CHECK(s[0] * dd[0] + s[1] * dd[1] + s[2] * dd[2] > 0);
        }
        CHECK(inside > 1000);
}

static void test_weights(void)
{
        static const double els[] = {10, 35, 60};
        double dirs[MAX_VIEWS][3];
        size_t n = grid(8, els, 3, dirs);

        srand(1);
        check_views((const double(*)[3])dirs, n, 0.02);
        check_gnomonic((const double(*)[3])dirs, n);
}

/* One ring of turntable angles (coplanar views), two views, one view. */
static void test_degenerate(void)
{
        static const double el[] = {20};
        double dirs[MAX_VIEWS][3];
        size_t n = grid(12, el, 1, dirs);
        _cleanup_(ap_views_freep) struct ap_views *v = NULL;
        float up[3] = {0, 0, 1}, w[3];
        int idx[3];

        srand(2);
        check_views((const double(*)[3])dirs, n, 0.02);
        CHECK_INT(ap_views_new((const double(*)[3])dirs, n, &v), 0);
        CHECK_INT((int)ap_views_n_faces(v), 0);
        CHECK_INT(ap_views_weights(v, up, idx, w), 2); /* the pole: on a ring edge */
        check_views((const double(*)[3])dirs, 2, 0.02);
        check_views((const double(*)[3])dirs, 1, 0);
        CHECK_INT(ap_views_new((const double(*)[3])dirs, 0, &v), -EINVAL);
}

#define ENV_W 256
#define ENV_H 128
#define ENV_P 4

/* A map of sum_m a_m Y_m (grey) into e. */
static void sh_map(const double *a, struct ap_envmap *e)
{
        double y[ENV_P * ENV_P], d[3];

        e->width = ENV_W, e->height = ENV_H;
        e->rgb = malloc(3 * ENV_W * ENV_H * sizeof(float));
        CHECK(e->rgb);
        for (int r = 0; r < ENV_H; r++)
                for (int x = 0; x < ENV_W; x++) {
                        double s = 0;
                        ap_envmap_dir(ENV_W, ENV_H, x + 0.5, r + 0.5, d);
                        ap_sh_eval(ENV_P, d, y);
                        for (int m = 0; m < ENV_P * ENV_P; m++)
                                s += a[m] * y[m];
                        for (int c = 0; c < 3; c++)
                                e->rgb[(r * ENV_W + x) * 3 + c] = (float)(s * (1 + 0.5 * c));
                }
}

static void write_pfm(const char *path, const struct ap_envmap *e)
{
        _cleanup_fclose_ FILE *f = fopen(path, "wb");

        CHECK(f);
        fprintf(f, "PF\n%d %d\n-1.0\n", e->width, e->height);
        for (int r = e->height - 1; r >= 0; r--)
                CHECK(fwrite(&e->rgb[(size_t)r * e->width * 3], sizeof(float), 3 * e->width, f) ==
                      3 * (size_t)e->width);
}

static void write_png16(const char *path, const struct ap_envmap *e, double scale)
{
        struct gn_frame f = {0};
        _cleanup_free_ void *buf = NULL;
        size_t len;

        CHECK_INT(gn_frame_alloc(&f, e->width, e->height, 3, 16), 0);
        for (int r = 0; r < e->height; r++)
                for (int i = 0; i < 3 * e->width; i++)
                        ((uint16_t *)(f.data + r * f.stride))[i] =
                                (uint16_t)lrint(e->rgb[(size_t)r * 3 * e->width + i] * scale);
        CHECK_INT(ds_png_encode(&f, 1, &buf, &len), 0);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, buf, len, NULL), 0);
        gn_frame_free_data(&f);
}

/* Projects path at order 6 against a (order ENV_P, colour c scaled by 1 + c / 2). */
static void check_projection(const char *path, const double *a, double scale, double tol)
{
        struct ap_envmap e;
        double coef[3 * 36];
        char err[256];

        CHECK_INT(ap_envmap_load(path, &e, err, sizeof(err)), 0);
        CHECK_INT(e.width, ENV_W);
        CHECK(e.ldr == (strstr(path, ".png") != NULL)); /* no HDR range: noted */
        ap_envmap_project(&e, 6, coef);
        for (int m = 0; m < 36; m++)
                for (int c = 0; c < 3; c++) {
                        double want = m < ENV_P * ENV_P ? a[m] * (1 + 0.5 * c) * scale : 0;
                        CHECK_NEAR(coef[m * 3 + c], want, tol);
                }
        ap_envmap_free(&e);
}

static void test_envmap(void)
{
        _cleanup_free_ char *dir = tu_tmpdir();
        char path[512];
        double a[ENV_P * ENV_P];
        struct ap_envmap e;

        srand(3);
        for (int m = 0; m < ENV_P * ENV_P; m++)
                a[m] = 0.3 * (rnd() - 0.5);
        a[0] = 4; /* positive everywhere, for the PNG */
        sh_map(a, &e);
        snprintf(path, sizeof(path), "%s/env.pfm", dir);
        write_pfm(path, &e);
        check_projection(path, a, 1, 2e-3);
        snprintf(path, sizeof(path), "%s/env.png", dir);
        write_png16(path, &e, 65535 / 8.0);
        check_projection(path, a, 1 / 8.0, 2e-3 / 8);
        ap_envmap_free(&e);
        tu_rm_rf(dir);
}

/* A w x h PFM of value v everywhere written as dir/name is refused with a sentence holding
 * why, nothing left allocated. */
static void check_refused(const char *dir, const char *name, int w, int h, float v, const char *why)
{
        struct ap_envmap e = {w, h, malloc(3 * sizeof(float) * w * h), false};
        char path[512], err[512];

        CHECK(e.rgb);
        for (int i = 0; i < 3 * w * h; i++)
                e.rgb[i] = v;
        snprintf(path, sizeof(path), "%s/%s", dir, name);
        write_pfm(path, &e);
        ap_envmap_free(&e);
        CHECK_INT(ap_envmap_load(path, &e, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, why);
        CHECK(e.rgb == NULL);
}

static void test_envmap_bad(void)
{
        _cleanup_free_ char *dir = tu_tmpdir();
        char path[512], err[512];
        struct ap_envmap e;
        _cleanup_fclose_ FILE *f = NULL;

        snprintf(path, sizeof(path), "%s/none.pfm", dir);
        CHECK_INT(ap_envmap_load(path, &e, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, path);
        snprintf(path, sizeof(path), "%s/junk.png", dir);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, "hello, world", 12, NULL), 0);
        CHECK_INT(ap_envmap_load(path, &e, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "not a PNG or PFM");
        snprintf(path, sizeof(path), "%s/short.pfm", dir);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, "PF\n4 2\n-1.0\n\0\0\0\0", 16, NULL), 0);
        CHECK_INT(ap_envmap_load(path, &e, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "truncated");
        snprintf(path, sizeof(path), "%s/bad.png", dir);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, "\x89PNG\r\n\x1a\n\0\0\0\0", 12, NULL), 0);
        CHECK_INT(ap_envmap_load(path, &e, err, sizeof(err)), -EBADMSG);
        CHECK(e.rgb == NULL);
        check_refused(dir, "square.pfm", 4, 4, 1, "not a lat-long map");
        check_refused(dir, "black.pfm", 8, 4, 0, "no light");
        check_refused(dir, "negative.pfm", 8, 4, -1, "negative");
        tu_rm_rf(dir);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"views-weights", test_weights},
                {"views-degenerate", test_degenerate},
                {"envmap-project", test_envmap},
                {"envmap-bad", test_envmap_bad},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
