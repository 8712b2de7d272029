/* test-fit.c - the appearance fit (appearance/fit.h) on synthetic datasets (apscene.h). */
#include <math.h>
#include <stdlib.h>
#include <time.h>

#include "common/cleanup.h"
#include "tests/appearance/apscene.h"
#include "tests/dataset/ds-util.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);

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
                CHECK_INT(ds_count(d), 2 * 12 * 5);
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

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"scene", test_scene},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
