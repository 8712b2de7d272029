/* test-render-example.c - the example rig (examples/rigs/sim.yaml, given as argument)
 * shows what the rig does: its frames at turntable 0, 90, 180 and 270 degrees differ
 * clearly (beyond sensor noise), every lamp lights the object seen by every camera at
 * every light-arm angle of the demo, the laser line shows, and a dark frame sits at the
 * black level instead of zero. Set RTEST_DUMP=DIR to look at the frames. */
#include <stdint.h>

#include "drivers/registry.h"
#include "rtest.h"
#include "tests/test-frame.h"

struct example {
        struct rig_config *rc;
        struct sim_scene *s;
};

static struct gn_pose pose(double tt, double la, uint32_t lamps, bool laser)
{
        return (struct gn_pose){.deg = {tt, la, 0.0}, .lamps = lamps, .lasers = laser};
}

static void render(struct example *e, int cam, const struct gn_pose *p, uint64_t seq,
                   struct gn_frame *f)
{
        *f = (struct gn_frame){0};
        CHECK_INT(sim_render(e->s, p, cam, &(struct sim_expose){0}, seq, f, 0, NULL), 0);
}

/* Turntable 0, 90, 180, 270 with all lamps: every pair differs by far more than two
 * frames of one state (sensor noise). */
static void test_rotation(struct example *e)
{
        struct gn_pose p = pose(0, 0, (UINT32_C(1) << e->rc->n_lamps) - 1, false);
        struct gn_frame f[4], again;
        char name[32];

        for (int cam = 0; cam < (int)e->rc->n_cameras; cam++) {
                for (int k = 0; k < 4; k++) {
                        p.deg[GN_ROLE_TURNTABLE] = 90.0 * k;
                        render(e, cam, &p, (uint64_t)k, &f[k]);
                        snprintf(name, sizeof name, "example-cam%d-tt%d", cam, 90 * k);
                        rt_dump(&f[k], name);
                }
                p.deg[GN_ROLE_TURNTABLE] = 0.0;
                render(e, cam, &p, 99, &again);
                double noise = test_frame_mean_abs_diff(&f[0], &again);
                for (int i = 0; i < 4; i++)
                        for (int j = i + 1; j < 4; j++) {
                                double d = test_frame_mean_abs_diff(&f[i], &f[j]);
                                fprintf(stderr, "cam%d: tt %d vs %d: %.2f (noise %.2f)\n", cam,
                                        90 * i, 90 * j, d, noise);
                                CHECK(d > 3.0 * noise && d > 2.0);
                        }
                for (int k = 0; k < 4; k++)
                        gn_frame_free_data(&f[k]);
                gn_frame_free_data(&again);
        }
}

/* Each lamp alone, at the light-arm angles of the demo, against the dark frame: the
 * object is lit (not an all-black frame), and the dark frame is at the black level. */
static void test_lamps(struct example *e)
{
        struct gn_frame dark, lit;
        char name[48];

        for (int cam = 0; cam < (int)e->rc->n_cameras; cam++) {
                struct gn_pose p = pose(0, 0, 0, false);
                render(e, cam, &p, 0, &dark);
                double black = test_frame_mean(&dark);
                fprintf(stderr, "cam%d: dark %.2f\n", cam, black);
                CHECK(black > 2.0 && black < 40.0);
                for (int la = 0; la < 360; la += 90)
                        for (size_t l = 0; l < e->rc->n_lamps; l++) {
                                p = pose(0, la, UINT32_C(1) << l, false);
                                render(e, cam, &p, 1, &lit);
                                snprintf(name, sizeof name, "example-cam%d-la%d-lamp%zu", cam, la,
                                         l);
                                rt_dump(&lit, name);
                                fprintf(stderr, "cam%d: arm %d lamp%zu: %.2f\n", cam, la, l,
                                        test_frame_mean(&lit));
                                CHECK(test_frame_mean(&lit) > black + 2.0);
                                gn_frame_free_data(&lit);
                        }
                gn_frame_free_data(&dark);
        }
}

/* The laser alone draws a line that stands out: a few hundred pixels (the line across the
 * object and the disc) 40 DN or more above the dark frame, in every camera. */
static void test_laser(struct example *e)
{
        struct gn_pose off = pose(0, 0, 0, false), on = pose(0, 0, 0, true);
        struct gn_frame a, b;
        char name[32];

        CHECK(e->rc->n_lasers);
        for (int cam = 0; cam < (int)e->rc->n_cameras; cam++) {
                render(e, cam, &off, 0, &a);
                render(e, cam, &on, 0, &b);
                snprintf(name, sizeof name, "example-cam%d-laser", cam);
                rt_dump(&b, name);
                int line = 0;
                for (int y = 0; y < b.height; y++)
                        for (int x = 0; x < b.width; x++)
                                line += rt_px(&b, x, y, 0) >= rt_px(&a, x, y, 0) + 40.0;
                fprintf(stderr, "cam%d: laser line %d px\n", cam, line);
                CHECK(line > 300);
                gn_frame_free_data(&a);
                gn_frame_free_data(&b);
        }
}

int main(int argc, char **argv)
{
        struct example e = {0};
        char err[512] = "";

        CHECK(argc == 2);
        int r = rigconf_load(argv[1], registry_backends, &e.rc, err, sizeof err);
        if (r >= 0)
                r = sim_scene_new(e.rc, &e.s, err, sizeof err);
        if (r < 0)
                fprintf(stderr, "%s: %s\n", argv[1], err);
        CHECK_INT(r, 0);
        test_rotation(&e);
        test_lamps(&e);
        test_laser(&e);
        sim_scene_free(e.s);
        rigconf_free(e.rc);
        return 0;
}
