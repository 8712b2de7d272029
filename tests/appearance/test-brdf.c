/* test-brdf.c - the BRDF model of issue 12 (appearance/brdf.h, brdf_fit.h): its evaluation
 * against gonio-sim's own SPEC_BECKMANN lobe (sim/render/material.c) at random directions
 * and parameters. */
#include <math.h>
#include <stdlib.h>

#include "appearance/brdf.h"
#include "sim/render/internal.h"
#include "tests/test.h"

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

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"eval", test_eval},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
