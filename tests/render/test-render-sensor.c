/* test-render-sensor.c - the sensor model: same seed and frame number give the same bytes
 * whatever the thread count; noise variance as the shot + read model says; exposure and
 * gain linear; black level, saturation, 8/16 bit; Bayer RGGB and mono sample the RGB
 * image as documented. */
#include <math.h>

#include "rtest.h"

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 90, "
        "radius: 300, intensity: 1.0e5 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 60, distance: 400, azimuth: 10,\n"
        "      target: [0, 0, 0], width: 96, height: 64, fx: 150, fy: 150,\n"
        "      exposure_us: 10000, gain: 1.0, bits: 8 }\n";

/* A gem on a grey disc; sensor: 1e4 e- full well, 5e5 e-/(radiance s), read noise 3 e-. */
static void open_scene(struct rtest *t, int seed, int threads, const char *sensor)
{
        char scene[1024];

        snprintf(scene, sizeof(scene),
                 "scene:\n  seed: %d\n  threads: %d\n"
                 "  object: { shape: gem, size: 60, material: { albedo: [0.9, 0.5, 0.2] } }\n"
                 "  turntable: { radius: 150, albedo: 0.5 }\n"
                 "  sensor: { full_well: 10000, response: 5.0e5, read_noise: 3%s }\n",
                 seed, threads, sensor);
        rt_open(t, lamps, "", cams, scene);
}

static bool same(const struct gn_frame *a, const struct gn_frame *b)
{
        return gn_frame_bytes(a) == gn_frame_bytes(b) &&
               memcmp(a->data, b->data, gn_frame_bytes(a)) == 0;
}

static void test_determinism(void)
{
        struct rtest t1, t2, t3;
        struct gn_pose st = {.deg[GN_ROLE_TURNTABLE] = 33, .lamps = 1};
        struct gn_frame a, b, c, d, e;

        open_scene(&t1, 7, 2, "");
        open_scene(&t2, 7, 1, "");
        open_scene(&t3, 8, 2, "");
        rt_render(&t1, &st, NULL, 5, &a, 0, NULL);
        rt_render(&t1, &st, NULL, 5, &b, 0, NULL);
        rt_render(&t2, &st, NULL, 5, &c, 0, NULL);
        rt_render(&t1, &st, NULL, 6, &d, 0, NULL);
        rt_render(&t3, &st, NULL, 5, &e, 0, NULL);
        CHECK(same(&a, &b)); /* same seed, same frame number */
        CHECK(same(&a, &c)); /* whatever the thread count */
        CHECK(!same(&a, &d));
        CHECK(!same(&a, &e));
        CHECK_INT(a.seq, 5);
        CHECK_INT(a.exposure_us, 10000);
        CHECK_NEAR(a.gain, 1.0, 0);
        CHECK(a.timestamp_ns > 0);
        gn_frame_free_data(&a);
        gn_frame_free_data(&b);
        gn_frame_free_data(&c);
        gn_frame_free_data(&d);
        gn_frame_free_data(&e);
        rt_close(&t1);
        rt_close(&t2);
        rt_close(&t3);
}

/* Over the lit disc: var(DN1 - DN2) / 2 = k^2 (e + read^2) + 1/12 with k = DN per e-. */
static void test_noise_statistics(void)
{
        struct rtest t;
        struct gn_pose st = {.lamps = 1};
        struct sim_expose ideal = {.bits = 16, .no_noise = true}, noisy = {.bits = 16};
        struct gn_frame f0, f1, f2;
        double k = 65535 / 10000.0, sum = 0, want = 0;
        int n = 0;

        open_scene(&t, 1, 2, "");
        rt_render(&t, &st, &ideal, 0, &f0, 0, NULL);
        rt_render(&t, &st, &noisy, 1, &f1, 0, NULL);
        rt_render(&t, &st, &noisy, 2, &f2, 0, NULL);
        for (int v = 0; v < f0.height; v++)
                for (int u = 0; u < f0.width; u++) {
                        double m = rt_px(&f0, u, v, 1);
                        if (m < 2000 || m > 60000)
                                continue;
                        double dd = rt_px(&f1, u, v, 1) - rt_px(&f2, u, v, 1);
                        sum += dd * dd / 2;
                        want += k * k * (m / k + 9) + 1.0 / 12;
                        n++;
                }
        fprintf(stderr, "noise: %d pixels, variance %.1f, model %.1f DN^2\n", n, sum / n, want / n);
        CHECK(n > 1000);
        CHECK_NEAR(sum / n, want / n, 0.08 * want / n);
        gn_frame_free_data(&f0);
        gn_frame_free_data(&f1);
        gn_frame_free_data(&f2);
        rt_close(&t);
}

/* Exposure and gain scale linearly (a fractional gain, reported exactly: an integer one
 * would hide a gain truncated anywhere); black level and saturation; 8 and 16 bit. */
static void test_levels(void)
{
        struct rtest t;
        struct gn_pose st = {.lamps = 1};
        struct sim_expose e1 = {.bits = 16, .no_noise = true, .exposure_us = 2000};
        struct sim_expose e2 = {.bits = 16, .no_noise = true, .exposure_us = 4000};
        struct sim_expose g2 = {.bits = 16, .no_noise = true, .exposure_us = 2000, .gain = 2.5};
        struct sim_expose sat = {.bits = 8, .no_noise = true, .exposure_us = 1000000};
        struct gn_frame a, b, c, d;
        double black = 0.05 * 65535; /* in DN, before rounding */
        int n = 0;

        open_scene(&t, 1, 2, ", black_level: 0.05");
        rt_render(&t, &st, &e1, 0, &a, 0, NULL);
        rt_render(&t, &st, &e2, 0, &b, 0, NULL);
        rt_render(&t, &st, &g2, 0, &c, 0, NULL);
        rt_render(&t, &st, &sat, 0, &d, 0, NULL);
        CHECK_INT(a.bits, 16);
        CHECK_INT(d.bits, 8);
        CHECK_NEAR(c.gain, 2.5, 0);
        CHECK_NEAR(rt_px(&a, 0, 0, 0), round(black), 0); /* the corner sees the background */
        CHECK_NEAR(rt_px(&d, 0, 0, 0), round(0.05 * 255), 0);
        for (int v = 0; v < a.height; v++)
                for (int u = 0; u < a.width; u++) {
                        double x = rt_px(&a, u, v, 0) - black;
                        if (x < 100)
                                continue;
                        /* rounding: 0.5 DN in b or c plus 2 or 2.5 x 0.5 DN carried over from a
                         * (and float arithmetic in the sensor: 0.01 DN) */
                        CHECK_NEAR(rt_px(&b, u, v, 0) - black, 2 * x, 1.51);
                        CHECK_NEAR(rt_px(&c, u, v, 0) - black, 2.5 * x, 1.76);
                        CHECK_NEAR(rt_px(&d, u, v, 0), 255, 0);
                        n++;
                }
        CHECK(n > 1000);
        gn_frame_free_data(&a);
        gn_frame_free_data(&b);
        gn_frame_free_data(&c);
        gn_frame_free_data(&d);
        rt_close(&t);
}

/* RGGB takes R on even rows/even columns, B on odd/odd, G elsewhere; mono the mean. */
static void test_mosaic(void)
{
        struct rtest rgb, bayer, mono;
        struct gn_pose st = {.lamps = 1};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct gn_frame a, b, c;

        open_scene(&rgb, 1, 2, "");
        open_scene(&bayer, 1, 2, ", format: rggb");
        open_scene(&mono, 1, 2, ", format: mono");
        rt_render(&rgb, &st, &ex, 0, &a, 0, NULL);
        rt_render(&bayer, &st, &ex, 0, &b, 0, NULL);
        rt_render(&mono, &st, &ex, 0, &c, 0, NULL);
        CHECK_INT(a.channels, 3);
        CHECK_INT(b.channels, 1);
        CHECK_INT(c.channels, 1);
        for (int v = 0; v < a.height; v++)
                for (int u = 0; u < a.width; u++) {
                        int ch = (v & 1) + (u & 1);
                        double mean = 0;
                        CHECK_NEAR(rt_px(&b, u, v, 0), rt_px(&a, u, v, ch), 0);
                        for (int k = 0; k < 3; k++)
                                mean += rt_px(&a, u, v, k) / 3;
                        CHECK_NEAR(rt_px(&c, u, v, 0), mean, 1);
                }
        gn_frame_free_data(&a);
        gn_frame_free_data(&b);
        gn_frame_free_data(&c);
        rt_close(&rgb);
        rt_close(&bayer);
        rt_close(&mono);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"determinism", test_determinism},
                {"noise", test_noise_statistics},
                {"levels", test_levels},
                {"mosaic", test_mosaic},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
