/* envscene.c - the glossy sphere under an environment map, in gonio-sim and as a BRDF model
 * (envscene.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "appearance/raster.h"
#include "envscene.h"

#define RESPONSE  8.0e6
#define FULL_WELL 1.0e5
#define EXPOSURE  0.02

/* A sky brighter at the zenith, a darker ground half, a sun of radius 0.25 rad at 35 degrees
 * elevation. */
static void write_env(const char *path, int w, int h)
{
        FILE *f = fopen(path, "wb");
        double s[3] = {cos(0.61) * cos(0.9), cos(0.61) * sin(0.9), sin(0.61)};

        CHECK(f != NULL);
        fprintf(f, "PF\n%d %d\n-1.0\n", w, h);
        for (int y = h - 1; y >= 0; y--)
                for (int x = 0; x < w; x++) {
                        double th = M_PI * (y + 0.5) / h, ph = 2 * M_PI * (x + 0.5) / w;
                        double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
                        double c = d[0] * s[0] + d[1] * s[1] + d[2] * s[2];
                        float sky[3] = {0.10f, 0.13f, 0.20f}, v;
                        for (int k = 0; k < 3; k++) {
                                v = d[2] > 0 ? sky[k] * (float)(0.6 + 0.6 * d[2]) : 0.03f;
                                v += acos(fmin(c, 1.0)) < 0.25 ? 1.2f - 0.15f * k : 0;
                                fwrite(&v, 4, 1, f);
                        }
                }
        fclose(f);
}

/* Every texel: the true material at the atlas's interpolated normal, the tangent the
 * simulator's (its z axis projected on the tangent plane). */
static void texels_fixture(struct ap_brdf_model *m, const struct envscene_opts *o)
{
        const struct ap_atlas *a = &m->atlas;
        const float alb[3] = ENVSCENE_ALBEDO;

        m->texels = calloc((size_t)a->width * a->height, sizeof(*m->texels));
        CHECK(m->texels != NULL);
        for (size_t i = 0; i < (size_t)a->width * a->height; i++) {
                struct ap_brdf_texel *x = &m->texels[i];
                float p[3], n[3], t[3], l;
                if (!ap_atlas_point(a, i, p, n)) {
                        x->flags = AP_BRDF_MASKED; /* no triangle's: as the fit leaves it */
                        continue;
                }
                for (int q = 0; q < 3; q++)
                        t[q] = (q == 2) - n[2] * n[q];
                l = sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
                *x = (struct ap_brdf_texel){{alb[0], alb[1], alb[2]},
                                            (float)o->ks,
                                            (float)o->ax,
                                            (float)o->ay,
                                            ENVSCENE_F0,
                                            {n[0], n[1], n[2]},
                                            {t[0] / l, t[1] / l, t[2] / l},
                                            0,
                                            1,
                                            AP_BRDF_FITTED};
        }
}

static void build_model(struct envscene *es)
{
        struct sim_mesh sm;
        struct ap_mesh mesh;
        struct ap_brdf_model *m = calloc(1, sizeof(*m));

        CHECK(m != NULL);
        CHECK_INT(sim_object_mesh(es->t.s, es->o.mesh_rows ? es->o.mesh_rows : 96, &sm), 0);
        mesh = (struct ap_mesh){sm.nv, sm.nt, sm.pos, sm.idx, 0};
        CHECK_INT(ap_mesh_orient(&mesh), 0);
        CHECK_INT(ap_atlas_build(&mesh, AP_ATLAS_MIN_CELL, &m->atlas), 0);
        texels_fixture(m, &es->o);
        m->response = 1;
        snprintf(m->name, sizeof(m->name), "envscene");
        es->model = m;
}

static void camera_of(struct envscene *es)
{
        struct sim_cam_geom g;
        struct gn_pose st = {0};

        CHECK_INT(sim_camera_geom(es->t.s, &st, 0, &g), 0);
        es->cam = (struct ap_camera){g.width, g.height, g.fx, g.fy, g.cx, g.cy};
        memcpy(es->cam.R, g.R, sizeof(g.R));
        memcpy(es->cam.t, g.t, sizeof(g.t));
}

void envscene_open(struct envscene *es, const struct envscene_opts *o)
{
        char cams[512], scene[1024], lamps[256], err[256];
        int fd;

        memset(es, 0, sizeof(*es));
        es->o = *o;
        snprintf(es->env_path, sizeof(es->env_path), "/tmp/gonio-envscene-XXXXXX");
        fd = mkstemp(es->env_path);
        CHECK(fd >= 0);
        close(fd);
        write_env(es->env_path, o->env_width, o->env_width / 2);
        CHECK_INT(ap_envmap_load(es->env_path, &es->env, err, sizeof(err)), 0);
        snprintf(cams, sizeof(cams),
                 "cameras:\n  - { name: c0, sim: { bus: frames }, elevation: %g, distance: 400, "
                 "azimuth: 20, target: [0, 0, 30], width: %d, height: %d, fx: %g, fy: %g, "
                 "cx: %g, cy: %g, exposure_us: 20000, gain: 1.0 }\n",
                 o->elevation, o->width, o->height, o->width * 3.0, o->width * 3.0,
                 (o->width - 1) / 2.0, (o->height - 1) / 2.0);
        snprintf(scene, sizeof(scene),
                 "scene:\n  object: { shape: sphere, size: 60, material: { albedo: [%g, %g, %g], "
                 "specular: { model: beckmann, ks: %g, alpha_x: %g, alpha_y: %g, ior: 0 } } }\n"
                 "  turntable: { radius: %g, albedo: 0.5 }\n"
                 "  %s: { envmap: %s, threshold: 0.00001, max_elements: %d }\n"
                 "  sensor: { response: %g, full_well: %g, read_noise: 0, black_level: 0 }\n",
                 0.55, 0.35, 0.25, o->ks, o->ax, o->ay, o->ground_radius, o->lamp ? "#" : "dome",
                 es->env_path, o->dome_elements, RESPONSE, FULL_WELL);
        snprintf(lamps, sizeof(lamps),
                 "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 45, "
                 "radius: 300, azimuth: 60, intensity: %g }\n",
                 ENVSCENE_LAMP_I);
        rt_open(&es->t, o->lamp ? lamps : "", "", cams, scene);
        if (o->lamp)
                CHECK_INT(
                        sim_lamp_position(es->t.s, &(struct gn_pose){.lamps = 1}, 0, es->lamp_pos),
                        0);
        build_model(es);
        camera_of(es);
}

void envscene_close(struct envscene *es)
{
        if (es->model) {
                ap_atlas_free(&es->model->atlas);
                free(es->model->texels);
                free(es->model);
        }
        ap_envmap_free(&es->env);
        rt_close(&es->t);
        unlink(es->env_path);
}

void envscene_reference(struct envscene *es, float *rgb, double *seconds)
{
        static const struct sim_expose ideal16 = {.bits = 16, .no_noise = true};
        struct gn_pose st = {.lamps = es->o.lamp};
        struct gn_frame f;
        struct timespec t0, t1;
        double k = FULL_WELL / (RESPONSE * EXPOSURE * 65535);

        clock_gettime(CLOCK_MONOTONIC, &t0);
        rt_render(&es->t, &st, &ideal16, 0, &f, 0, NULL);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        *seconds = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
        for (int y = 0; y < f.height; y++)
                for (int x = 0; x < f.width; x++)
                        for (int c = 0; c < 3; c++)
                                rgb[3 * ((size_t)y * f.width + x) + c] =
                                        (float)(rt_px(&f, x, y, c) * k);
        gn_frame_free_data(&f);
}

double envscene_psnr(const float *a, const float *b, const uint8_t *mask, size_t n)
{
        double se = 0, peak = 0;
        size_t cnt = 0;

        for (size_t i = 0; i < n; i++) {
                if (mask && !mask[i])
                        continue;
                for (int c = 0; c < 3; c++) {
                        se += pow(a[3 * i + c] - b[3 * i + c], 2);
                        peak = fmax(peak, b[3 * i + c]);
                }
                cnt += 3;
        }
        return cnt && se > 0 ? 10 * log10(peak * peak / (se / cnt)) : INFINITY;
}

void envscene_dump(const float *a, const float *b, int w, int h, const char *name)
{
        const char *dir = getenv("RTEST_DUMP");
        char path[512];
        FILE *o;

        if (!dir)
                return;
        snprintf(path, sizeof(path), "%s/%s.ppm", dir, name);
        o = fopen(path, "wb");
        if (!o)
                return;
        fprintf(o, "P6\n%d %d\n255\n", 2 * w, h);
        for (int y = 0; y < h; y++)
                for (int x = 0; x < 2 * w; x++)
                        for (int q = 0; q < 3; q++) {
                                float v = (x < w ? a : b)[3 * ((size_t)y * w + x % w) + q];
                                fputc((int)fminf(255, 255 * powf(fmaxf(v, 0) / 0.6f, 1 / 2.2f)), o);
                        }
        fclose(o);
}
