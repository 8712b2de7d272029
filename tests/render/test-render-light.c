/* test-render-light.c - lighting against closed forms: a Lambert sphere under one point
 * lamp, the inverse-square law, the shadow edge of a sphere, the dome's irradiance and
 * its adaptive split, the dome as a lat-long environment map (a constant map on a Lambert
 * sphere gives the closed form; the picture converges as the elements grow). Noise off,
 * 16-bit output. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "rtest.h"
#include "sim/render/internal.h"

#define CAMERA                                                                                     \
        "cameras:\n"                                                                               \
        "  - { name: c0, sim: { bus: frames }, elevation: %s, distance: 400, azimuth: 0,\n"        \
        "      target: [0, 0, 30], width: 160, height: 120, fx: 260, fy: 260, cx: 79.5,\n"         \
        "      cy: 59.5, exposure_us: 20000, gain: 1.0 }\n"

#define SENSOR "  sensor: { response: 8.0e6, full_well: 1.0e5, read_noise: 0, black_level: 0 }\n"

static const struct sim_expose ideal16 = {.bits = 16, .no_noise = true};

/* Expected DN of radiance L with the sensor above (16 bit, 20 ms). */
static double dn_of(double L)
{
        return L * 0.02 * 8.0e6 / 1.0e5 * 65535;
}

/* Analytic ray through pixel (u, v) (no distortion) against the sphere; returns t or -1. */
static double ray_sphere(const struct sim_cam_geom *g, double u, double v, const double c[3],
                         double r, double p[3])
{
        double dc[3] = {(u - g->cx) / g->fx, (v - g->cy) / g->fy, 1}, d[3], o[3], oc[3];
        double b = 0, cc = 0, dd = 0, disc, t;

        for (int i = 0; i < 3; i++) {
                d[i] = g->R[i] * dc[0] + g->R[3 + i] * dc[1] + g->R[6 + i] * dc[2];
                o[i] = -(g->R[i] * g->t[0] + g->R[3 + i] * g->t[1] + g->R[6 + i] * g->t[2]);
                oc[i] = o[i] - c[i];
        }
        for (int i = 0; i < 3; i++) {
                b += oc[i] * d[i];
                cc += oc[i] * oc[i];
                dd += d[i] * d[i];
        }
        disc = b * b - dd * (cc - r * r);
        if (disc < 0)
                return -1;
        t = (-b - sqrt(disc)) / dd;
        for (int i = 0; i < 3; i++)
                p[i] = o[i] + t * d[i];
        return t;
}

static void test_lambert_sphere(void)
{
        struct rtest t;
        struct gn_pose st = {.deg[GN_ROLE_LIGHT_ARM] = 25, .lamps = 1};
        struct sim_cam_geom g;
        struct gn_frame f;
        double lamp[3], c[3] = {0, 0, 30}, p[3], worst = 0;
        char cams[512];
        int n = 0;

        snprintf(cams, sizeof(cams), CAMERA, "30");
        rt_open(&t,
                "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, "
                "elevation: 40, radius: 300, azimuth: 35, intensity: 1.0e5 }\n",
                "", cams,
                "scene:\n  object: { shape: sphere, size: 60, material: { albedo: [0.8, 0.5, 0.2] "
                "} }\n"
                "  turntable: { radius: 0 }\n" SENSOR);
        rt_render(&t, &st, &ideal16, 0, &f, 0, NULL);
        CHECK_INT(sim_camera_geom(t.s, &st, 0, &g), 0);
        CHECK_INT(sim_lamp_position(t.s, &st, 0, lamp), 0);
        CHECK_NEAR(lamp[2], 300 * sin(40 * M_PI / 180), 1e-9);
        CHECK_NEAR(atan2(lamp[1], lamp[0]) * 180 / M_PI, 60, 1e-9);
        for (int v = 1; v < f.height - 1; v++)
                for (int u = 1; u < f.width - 1; u++) {
                        double q[3], l[3], nrm[3], d2 = 0, nl = 0, ok = 1;
                        for (int k = 0; k < 4; k++) /* keep 1 px off the silhouette */
                                ok = ok &&
                                     ray_sphere(&g, u + (k & 1 ? 1 : -1) * (k < 2),
                                                v + (k & 1 ? 1 : -1) * (k >= 2), c, 30, q) > 0;
                        if (!ok || ray_sphere(&g, u, v, c, 30, p) < 0)
                                continue;
                        for (int i = 0; i < 3; i++) {
                                l[i] = lamp[i] - p[i];
                                nrm[i] = (p[i] - c[i]) / 30;
                                d2 += l[i] * l[i];
                        }
                        for (int i = 0; i < 3; i++)
                                nl += nrm[i] * l[i] / sqrt(d2);
                        if (nl < 0.05)
                                continue;
                        for (int ch = 0; ch < 3; ch++) {
                                double alb = ch == 0 ? 0.8 : ch == 1 ? 0.5 : 0.2;
                                double want = dn_of(alb / M_PI * 1e5 * nl / d2);
                                double got = rt_px(&f, u, v, ch);
                                CHECK_NEAR(got, want, 0.01 * want + 1);
                                worst = fmax(worst, fabs(got - want) / want);
                        }
                        n++;
                }
        fprintf(stderr, "lambert: %d pixels, worst relative error %.5f\n", n, worst);
        CHECK(n > 600);
        gn_frame_free_data(&f);
        rt_close(&t);
}

static void test_inverse_square(void)
{
        struct rtest t;
        struct gn_pose s0 = {.lamps = 1}, s1 = {.lamps = 2};
        struct gn_frame f0, f1;
        struct sim_truth tr;
        char cams[512];
        int n = 0;

        snprintf(cams, sizeof(cams), CAMERA, "50");
        rt_open(&t,
                "lamps:\n"
                "  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 90, "
                "radius: 200, intensity: 1.0e5 }\n"
                "  - { name: l1, modbus-coil: { bus: relays, coil: 1 }, elevation: 90, "
                "radius: 400, intensity: 1.0e5 }\n",
                "", cams, "scene:\n  turntable: { radius: 150, albedo: 0.5 }\n" SENSOR);
        rt_render(&t, &s0, &ideal16, 0, &f0, SIM_TRUTH_POINT, &tr);
        rt_render(&t, &s1, &ideal16, 0, &f1, 0, NULL);
        for (int v = 0; v < f0.height; v++)
                for (int u = 0; u < f0.width; u++) {
                        const float *p = tr.point + 3 * (v * f0.width + u);
                        double r2 = (double)p[0] * p[0] + (double)p[1] * p[1], d0, d1, got;
                        if (isnan(p[0]))
                                continue;
                        d0 = r2 + (200 - p[2]) * (200 - p[2]);
                        d1 = r2 + (400 - p[2]) * (400 - p[2]);
                        /* E = I cos / d^2 with cos = h / d */
                        double e0 = 1e5 * 200 / pow(d0, 1.5), e1 = 1e5 * 400 / pow(d1, 1.5);
                        got = rt_px(&f0, u, v, 1);
                        CHECK_NEAR(got, dn_of(0.5 / M_PI * e0), 0.01 * got + 1);
                        CHECK_NEAR(got / rt_px(&f1, u, v, 1), e0 / e1, 0.005 * e0 / e1);
                        n++;
                }
        fprintf(stderr, "inverse square: %d pixels\n", n);
        CHECK(n > 5000);
        sim_truth_free(&tr);
        gn_frame_free_data(&f0);
        gn_frame_free_data(&f1);
        rt_close(&t);
}

static void test_shadow_edge(void)
{
        struct rtest t;
        struct gn_pose st = {.lamps = 1};
        struct gn_frame f;
        struct sim_truth tr;
        double rho_s = 400 * tan(asin(30.0 / 370));
        char cams[512];
        int lit = 0, dark = 0;

        snprintf(cams, sizeof(cams), CAMERA, "60");
        rt_open(&t,
                "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, "
                "elevation: 90, radius: 400, intensity: 1.0e5 }\n",
                "", cams,
                "scene:\n  object: { shape: sphere, size: 60 }\n"
                "  turntable: { radius: 150, albedo: 0.5 }\n" SENSOR);
        rt_render(&t, &st, &ideal16, 0, &f, SIM_TRUTH_POINT | SIM_TRUTH_LAMP, &tr);
        for (int i = 0; i < f.width * f.height; i++) {
                const float *p = tr.point + 3 * i;
                double rho;
                if (isnan(p[0]) || fabsf(p[2]) > 1e-3f)
                        continue; /* the disc only */
                rho = hypot(p[0], p[1]);
                if (fabs(rho - rho_s) < 0.02)
                        continue;
                CHECK_INT(tr.lamp_mask[i] & 1, rho > rho_s);
                CHECK_INT(rt_px(&f, i % f.width, i / f.width, 0) > 0, rho > rho_s);
                lit += rho > rho_s;
                dark += rho < rho_s;
        }
        fprintf(stderr, "shadow: radius %.3f mm, %d lit, %d dark pixels\n", rho_s, lit, dark);
        CHECK(lit > 1000 && dark > 300);
        sim_truth_free(&tr);
        gn_frame_free_data(&f);
        rt_close(&t);
}

static void test_dome(void)
{
        struct rtest t;
        struct gn_pose st = {0};
        struct gn_frame f;
        struct dome_el *els;
        struct dome d = {.radiance = 1, .zenith_ratio = 3, .threshold = 0.01, .max_elements = 512};
        double e = 0, total = 0, want;
        char cams[512];
        int n;

        /* adaptive split: every element below the threshold, energy conserved */
        CHECK_INT(dome_build(&d, &els, &n), 0);
        for (int i = 0; i < n; i++) {
                CHECK(els[i].w[0] <= 0.01 * 2 * M_PI * 2 + 1e-9);
                total += els[i].w[0];
        }
        /* closed form: int L0 (1 + 2 cos) dw over the hemisphere = 2 pi + 2 pi = 4 pi */
        CHECK_NEAR(total, 4 * M_PI, 0.005 * 4 * M_PI);
        free(els);

        snprintf(cams, sizeof(cams), CAMERA, "60");
        rt_open(&t, "", "", cams,
                "scene:\n  turntable: { radius: 150, albedo: 0.5 }\n"
                "  dome: { radiance: 0.5, threshold: 0.005 }\n" SENSOR);
        rt_render(&t, &st, &ideal16, 0, &f, 0, NULL);
        /* uniform dome: E = pi L, so the disc's radiance is albedo * L */
        want = dn_of(0.5 * 0.5);
        for (int v = f.height / 2 - 5; v < f.height / 2 + 5; v++)
                for (int u = f.width / 2 - 5; u < f.width / 2 + 5; u++) {
                        CHECK_NEAR(rt_px(&f, u, v, 0), want, 0.015 * want);
                        e = fmax(e, fabs(rt_px(&f, u, v, 0) - want) / want);
                }
        fprintf(stderr, "dome: %d elements, worst relative error %.4f\n", t.s->n_dome, e);
        gn_frame_free_data(&f);
        rt_close(&t);
}

/* A w x h lat-long PFM at path: radiance base everywhere plus, within 0.3 rad of (30 deg
 * elevation, azimuth 40 deg), a bright patch of radiance sun (RGB ratios 1 : 0.8 : 0.6). */
static void write_env(const char *path, int w, int h, const float base[3], float sun)
{
        FILE *f = fopen(path, "wb");
        double s[3] = {cos(M_PI / 6) * cos(0.7), cos(M_PI / 6) * sin(0.7), sin(M_PI / 6)};

        CHECK(f != NULL);
        fprintf(f, "PF\n%d %d\n-1.0\n", w, h);
        for (int y = h - 1; y >= 0; y--) /* bottom row first */
                for (int x = 0; x < w; x++) {
                        double th = M_PI * (y + 0.5) / h, ph = 2 * M_PI * (x + 0.5) / w;
                        double d = sin(th) * cos(ph) * s[0] + sin(th) * sin(ph) * s[1] +
                                   cos(th) * s[2];
                        bool in = acos(fmin(d, 1.0)) < 0.3;
                        for (int c = 0; c < 3; c++) {
                                float v = base[c] + (in ? sun * (1 - 0.2f * c) : 0);
                                fwrite(&v, 4, 1, f);
                        }
                }
        fclose(f);
}

static void open_env(struct rtest *t, const char *env, int max_elements, const char *object)
{
        char cams[512], scene[1024];

        snprintf(cams, sizeof(cams), CAMERA, "30");
        snprintf(scene, sizeof(scene),
                 "scene:\n  object: { shape: sphere, size: 60, material: { albedo: [0.8, 0.5, "
                 "0.2] } }\n%s"
                 "  dome: { envmap: %s, threshold: 0.00001, max_elements: %d }\n" SENSOR,
                 object, env, max_elements);
        rt_open(t, "", "", cams, scene);
}

static void test_envmap_constant(void)
{
        char env[] = "/tmp/test-envmap-XXXXXX";
        float L[3] = {0.5f, 0.3f, 0.2f}, alb[3] = {0.8f, 0.5f, 0.2f};
        struct rtest t;
        struct gn_pose st = {0};
        struct gn_frame f;
        struct sim_truth tr;
        double worst = 0;
        int n = 0;

        close(mkstemp(env));
        write_env(env, 64, 32, L, 0);
        open_env(&t, env, 512, "  turntable: { radius: 0 }\n");
        rt_render(&t, &st, &ideal16, 0, &f, SIM_TRUTH_POINT, &tr);
        /* a convex Lambert object under a constant sphere of light: E = pi L everywhere */
        for (int i = 0; i < f.width * f.height; i++) {
                if (isnan(tr.point[3 * i]))
                        continue;
                for (int c = 0; c < 3; c++) {
                        double want = dn_of(alb[c] * L[c]),
                               got = rt_px(&f, i % f.width, i / f.width, c);
                        CHECK_NEAR(got, want, 0.01 * want);
                        worst = fmax(worst, fabs(got - want) / want);
                }
                n++;
        }
        fprintf(stderr, "envmap constant: %d elements, %d pixels, worst relative error %.4f\n",
                t.s->n_dome, n, worst);
        CHECK(n > 1000);
        sim_truth_free(&tr);
        gn_frame_free_data(&f);
        rt_close(&t);
        /* a square map is no lat-long map: refused with a sentence */
        char scene[512], err[512];
        write_env(env, 32, 32, L, 0);
        snprintf(scene, sizeof(scene), "scene:\n  dome: { envmap: %s }\n", env);
        CHECK(rt_try_open(&t, "", "", "", scene, err, sizeof(err)) < 0);
        fprintf(stderr, "square map: %s\n", err);
        CHECK(strstr(err, "latitude-longitude") != NULL);
        rt_close(&t);
        unlink(env);
}

/* RMS difference of two frames (all channels), in DN. */
static double frame_rms(const struct gn_frame *a, const struct gn_frame *b)
{
        double s = 0;

        for (int y = 0; y < a->height; y++)
                for (int x = 0; x < a->width; x++)
                        for (int c = 0; c < 3; c++)
                                s += pow(rt_px(a, x, y, c) - rt_px(b, x, y, c), 2);
        return sqrt(s / (3.0 * a->width * a->height));
}

static void test_envmap_converges(void)
{
        static const int steps[] = {32, 128, 512, 2048};
        char env[] = "/tmp/test-envmap-XXXXXX";
        struct gn_frame f[4];
        struct gn_pose st = {0};
        double err[3], ref_mean = 0;

        close(mkstemp(env));
        write_env(env, 128, 64, (const float[3]){0.05f, 0.06f, 0.08f}, 4.0f);
        for (int k = 0; k < 4; k++) {
                struct rtest t;
                open_env(&t, env, steps[k], "  turntable: { radius: 150, albedo: 0.5 }\n");
                rt_render(&t, &st, &ideal16, 0, &f[k], 0, NULL);
                rt_close(&t);
        }
        for (int i = 0; i < f[3].width * f[3].height; i++)
                ref_mean += rt_px(&f[3], i % f[3].width, i / f[3].width, 0);
        ref_mean /= f[3].width * f[3].height;
        for (int k = 0; k < 3; k++) {
                err[k] = frame_rms(&f[k], &f[3]) / ref_mean;
                fprintf(stderr, "envmap: %4d elements: RMS %.4f of the mean against %d\n", steps[k],
                        err[k], steps[3]);
        }
        CHECK(err[1] < err[0] && err[2] < err[1]);
        CHECK(err[2] < 0.03);
        for (int k = 0; k < 4; k++)
                gn_frame_free_data(&f[k]);
        unlink(env);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"lambert", test_lambert_sphere},
                {"inverse-square", test_inverse_square},
                {"shadow", test_shadow_edge},
                {"dome", test_dome},
                {"envmap-constant", test_envmap_constant},
                {"envmap-converges", test_envmap_converges},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
