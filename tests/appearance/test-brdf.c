/* test-brdf.c - the BRDF model of issue 12 (appearance/brdf.h, brdf_fit.h): its evaluation
 * against gonio-sim's own SPEC_BECKMANN lobe (sim/render/material.c) at random directions
 * and parameters; its files written and read back, malformed ones refused by name. */
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <unistd.h>

#include "appearance/brdf.h"
#include "appearance/brdf_fit.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "drivers/registry.h"
#include "sim/render/internal.h"
#include "tests/appearance/apscene.h"
#include "tests/dataset/ds-util.h"
#include "tests/test.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_brdf_model *, ap_brdf_model_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);

#define DEG (M_PI / 180)

static double urand(unsigned *seed, double lo, double hi)
{
        return lo + (hi - lo) * rand_r(seed) / (double)RAND_MAX;
}

/* A random unit vector (the upper half about z when up). */
static struct v3 random_dir(unsigned *seed, bool up)
{
        for (;;) {
                struct v3 d = v3((float)urand(seed, -1, 1), (float)urand(seed, -1, 1),
                                 (float)urand(seed, up ? 0 : -1, 1));
                float n = v3_len(d);
                if (n > 0.1f && n <= 1)
                        return v3_scale(d, 1 / n);
        }
}

/* A random texel and the simulator's surface of the same material. */
static void random_material(unsigned *seed, struct ap_brdf_texel *x, struct surf *s, struct v3 *n,
                            struct v3 *t)
{
        struct v3 a = random_dir(seed, false);

        *n = random_dir(seed, false);
        *t = v3_norm(v3_madd(a, *n, -v3_dot(a, *n)));
        *x = (struct ap_brdf_texel){.albedo = {(float)urand(seed, 0, 1), (float)urand(seed, 0, 1),
                                               (float)urand(seed, 0, 1)},
                                    .ks = (float)urand(seed, 0, 1),
                                    .ax = (float)urand(seed, 0.02, 1),
                                    .ay = (float)urand(seed, 0.02, 1),
                                    .f0 = (float)urand(seed, 0.02, 1),
                                    .normal = {n->x, n->y, n->z},
                                    .tangent = {t->x, t->y, t->z}};
        *s = (struct surf){.model = SPEC_BECKMANN,
                           .albedo = {x->albedo[0], x->albedo[1], x->albedo[2]},
                           .ks = x->ks,
                           .ax = x->ax,
                           .ay = x->ay,
                           .f0 = x->f0};
}

/* ap_brdf_eval equals the simulator's brdf_cos (to float rounding) everywhere, half of the
 * pairs near the mirror direction where the lobe peaks. */
static void test_eval(void)
{
        unsigned seed = 12;
        int lit = 0;

        for (int i = 0; i < 20000; i++) {
                struct ap_brdf_texel x;
                struct surf s;
                struct v3 n, t, l, v;
                float got[3], want[3];
                random_material(&seed, &x, &s, &n, &t);
                l = random_dir(&seed, false);
                v = random_dir(&seed, false);
                if (i % 2) /* v near the mirror of l */
                        v = v3_norm(v3_add(v3_madd(v3_scale(l, -1), n, 2 * v3_dot(l, n)),
                                           v3_scale(v, 0.1f)));
                brdf_cos(&s, n, t, l, v, want);
                ap_brdf_eval(&x, (float[]){l.x, l.y, l.z}, (float[]){v.x, v.y, v.z}, got);
                for (int c = 0; c < 3; c++)
                        CHECK(fabsf(got[c] - want[c]) <= 1e-5f * (1 + fabsf(want[c])));
                lit += want[0] > 0;
        }
        CHECK(lit > 2000);
}

/* A model on a tetrahedron with random texels, named "m". */
static struct ap_brdf_model *small_model(void)
{
        static const float pos[] = {0, 0, 0, 10, 0, 0, 0, 10, 0, 0, 0, 10};
        static const uint32_t idx[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
        struct ap_brdf_model *m = calloc(1, sizeof(*m));
        struct ap_mesh me = {4, 4, malloc(sizeof(pos)), malloc(sizeof(idx)), 0};
        unsigned seed = 3;
        size_t n;

        CHECK(m && me.pos && me.idx);
        memcpy(me.pos, pos, sizeof(pos));
        memcpy(me.idx, idx, sizeof(idx));
        CHECK_INT(ap_atlas_build(&me, 8, &m->atlas), 0);
        n = (size_t)m->atlas.width * m->atlas.height;
        m->texels = calloc(n, sizeof(*m->texels));
        CHECK(m->texels);
        for (size_t i = 0; i < n; i++) {
                struct surf s;
                struct v3 nn, t;
                random_material(&seed, &m->texels[i], &s, &nn, &t);
                m->texels[i].rms = (float)i, m->texels[i].n_samples = (uint32_t)i;
                m->texels[i].flags = 1u << (i % 3);
        }
        snprintf(m->name, sizeof(m->name), "m");
        snprintf(m->notes, sizeof(m->notes), "a note");
        m->response = 1.5, m->fit_seconds = 2;
        return m;
}

static void put(const char *dir, const char *file, const void *buf, size_t len)
{
        _cleanup_close_ int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);

        CHECK(fd >= 0);
        CHECK_INT(gn_write_atomic(fd, file, buf, len, NULL), 0);
}

/* Written and read back bit for bit; a second write replaces the first. */
static void test_io_roundtrip(void)
{
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = small_model(), *r = NULL;
        _cleanup_free_ char *dir = tu_tmpdir();
        char path[512], err[512];
        size_t n = (size_t)m->atlas.width * m->atlas.height;

        CHECK_INT(ap_brdf_write(m, dir), 0);
        CHECK_INT(ap_brdf_write(m, dir), 0);
        snprintf(path, sizeof(path), "%s/models/m", dir);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), 0);
        CHECK_STR(r->name, "m");
        CHECK_STR(r->notes, "a note");
        CHECK(r->response == 1.5 && r->fit_seconds == 2);
        CHECK_INT(r->atlas.width, m->atlas.width);
        CHECK_INT(r->atlas.cell, 8);
        CHECK(memcmp(r->atlas.uv, m->atlas.uv, 24 * m->atlas.mesh.nt) == 0);
        CHECK(memcmp(r->texels, m->texels, n * sizeof(*m->texels)) == 0);
        snprintf(path, sizeof(path), "%s/models/none", dir);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -ENOENT);
        tu_rm_rf(dir);
}

/* Each malformed file refused with a sentence naming it and the problem. */
static void test_io_malformed(void)
{
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = small_model();
        _cleanup_free_ char *dir = tu_tmpdir();
        struct ap_brdf_model *r = NULL;
        char path[512], sub[600], err[512];

        m->texels[5].ax = NAN;
        CHECK_INT(ap_brdf_write(m, dir), 0);
        snprintf(path, sizeof(path), "%s/models/m", dir);
        snprintf(sub, sizeof(sub), "%s/brdf", path);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "texels.f32: texel 5: a parameter out of range");
        put(sub, "texels.u32", "1234", 4);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "texels.u32: 4 bytes, expected");
        put(sub, "mesh.bin", "GNBRDFM0", 8);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "brdf/mesh.bin: 8 bytes");
        CHECK_INT(unlink(strcat(sub, "/mesh.bin")), 0);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "mesh.bin: No such file");
        *strrchr(sub, '/') = 0;
        put(sub, "brdf.json", "{\"format\": \"gonio-brdf 2\"}", 25);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "brdf.json: ");
        put(sub, "brdf.json", "{", 1);
        CHECK_INT(ap_brdf_read(path, &r, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, "brdf/brdf.json: line 1");
        CHECK(r == NULL);
        tu_rm_rf(dir);
}

/* A BRDF model fitted to a synthetic dataset (apscene.h) of scene options ao. */
struct fitted {
        struct apscene s;
        char *dir, ds[512];
        struct ap_brdf_model *m;
};

static void fit_scene(struct fitted *f, const struct aps_opts *ao, size_t texels)
{
        struct ap_brdf_fit_opts o;
        _cleanup_(ds_closep) struct ds *d = NULL;
        char err[512];

        aps_open(&f->s, ao);
        f->dir = tu_tmpdir();
        snprintf(f->ds, sizeof(f->ds), "%s/ds", f->dir);
        d = aps_make_dataset(&f->s, f->ds);
        ap_brdf_fit_opts_default(&o);
        o.backends = registry_backends;
        o.texels = texels;
        CHECK_INT(ap_brdf_fit(d, &o, &f->m, err, sizeof(err)), 0);
        fprintf(stderr, "fit: %.2f s (read %.2f s), notes: %s\n", f->m->fit_seconds,
                f->m->read_seconds, f->m->notes);
}

static void fitted_close(struct fitted *f)
{
        ap_brdf_model_free(f->m);
        aps_close(&f->s);
        tu_rm_rf(f->dir);
        free(f->dir);
}

static int cmp_float(const void *a, const void *b)
{
        float x = *(const float *)a, y = *(const float *)b;

        return (x > y) - (x < y);
}

/* The q-quantile of v[0..n) (sorted in place). */
static float quantile(float *v, size_t n, double q)
{
        qsort(v, n, sizeof(float), cmp_float);
        return n ? v[(size_t)(q * (n - 1))] : NAN;
}

/* The truth's tangent at normal n: the sphere's z axis on its tangent plane. */
static void true_tangent(const float n[3], float t[3])
{
        float l;

        t[0] = -n[2] * n[0], t[1] = -n[2] * n[1], t[2] = 1 - n[2] * n[2];
        l = sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        for (int i = 0; i < 3; i++)
                t[i] /= l;
}

/* Errors of texel x against the truth: relative roughness along and across (pairing the
 * fitted tangent or its perpendicular with the true one), the tangent's angle, albedo, ks. */
static void texel_errors(const struct aps_opts *ao, const struct ap_brdf_texel *x, float e[5])
{
        float t[3], c, ax = x->ax, ay = x->ay, ang;

        true_tangent(x->normal, t);
        c = fabsf(t[0] * x->tangent[0] + t[1] * x->tangent[1] + t[2] * x->tangent[2]);
        ang = acosf(fminf(c, 1));
        if (ang > (float)M_PI_4) /* the fitted tangent is the true bitangent */
                ax = x->ay, ay = x->ax, ang = (float)M_PI_2 - ang;
        e[0] = fabsf(ax / (float)ao->alpha - 1);
        e[1] = fabsf(ay / (float)ao->alpha_y - 1);
        e[2] = ang / (float)DEG;
        e[3] = 0;
        for (int k = 0; k < 3; k++)
                e[3] = fmaxf(e[3], fabsf(x->albedo[k] / (float)ao->albedo[k] - 1));
        e[4] = fabsf(x->ks / (float)ao->ks - 1);
}

/* An anisotropic lobe (alpha 0.15 along the sphere's meridians, 0.3 across), noise on, two
 * cameras and four turntable angles, the mesh a 12-ring UV sphere: at the texels seen in 100
 * samples or more the median error of roughness within 5%, tangent within 3 degrees, albedo
 * within 3% and ks within 5% (the facets' distance from the true sphere, up to 0.26 mm, and
 * the highlights' coverage limit the rest: 90% of the texels are within about 10%). */
static void test_fit_aniso(void)
{
        struct fitted f = {0};
        struct aps_opts ao;
        size_t n = 0, fitted = 0;
        float *e[5];

        aps_opts_default(&ao, APS_SHARP);
        ao.alpha = 0.15, ao.alpha_y = 0.3, ao.noise = true, ao.mesh_rings = 12;
        ao.n_cameras = 2, ao.turntable_angles = 4, ao.arm_angles = 12;
        fit_scene(&f, &ao, 3000);
        for (int k = 0; k < 5; k++)
                CHECK(e[k] = malloc((size_t)f.m->atlas.width * f.m->atlas.height * sizeof(float)));
        for (size_t i = 0; i < (size_t)f.m->atlas.width * f.m->atlas.height; i++) {
                const struct ap_brdf_texel *x = &f.m->texels[i];
                float ei[5];
                fitted += x->flags == AP_BRDF_FITTED;
                if (x->flags != AP_BRDF_FITTED || x->n_samples < 100 || fabsf(x->normal[2]) > 0.9f)
                        continue;
                texel_errors(&ao, x, ei);
                for (int k = 0; k < 5; k++)
                        e[k][n] = ei[k];
                n++;
        }
        fprintf(stderr, "%zu texels fitted, %zu seen in 100 samples or more; ", fitted, n);
        CHECK(n > 1000);
        for (int k = 0; k < 5; k++) {
                static const char *const what[] = {"ax", "ay", "tangent", "albedo", "ks"};
                static const float median_max[] = {0.05f, 0.05f, 3, 0.03f, 0.05f};
                static const float q75_max[] = {0.08f, 0.08f, 3, 0.05f, 0.1f};
                float q75 = quantile(e[k], n, 0.75), med = quantile(e[k], n, 0.5);
                fprintf(stderr, "%s: median %.3f, 75%% %.3f, 90%% %.3f%s", what[k], med, q75,
                        quantile(e[k], n, 0.9), k < 4 ? "; " : "\n");
                CHECK(med < median_max[k] && q75 < q75_max[k]);
        }
        for (int k = 0; k < 5; k++)
                free(e[k]);
        fitted_close(&f);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"eval", test_eval},
                {"io-roundtrip", test_io_roundtrip},
                {"io-malformed", test_io_malformed},
                {"fit-aniso", test_fit_aniso},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
