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

/* Per-triangle atlas: two triangles to a square cell of `cell` texels a side. */
static void atlas_fixture(struct ap_atlas *a, int cell)
{
        size_t nt = a->mesh.nt, cells = (nt + 1) / 2;
        int cols = (int)ceil(sqrt((double)cells)), rows = (int)((cells + cols - 1) / cols);

        a->cell = cell;
        a->width = cols * cell;
        a->height = rows * cell;
        a->uv = malloc(6 * sizeof(float) * nt);
        a->tri = malloc(sizeof(int32_t) * a->width * a->height);
        a->bary = malloc(3 * sizeof(float) * a->width * a->height);
        CHECK(a->uv && a->tri && a->bary);
        for (size_t t = 0; t < nt; t++) {
                float cx = (float)((t / 2) % cols * cell), cy = (float)((t / 2) / cols * cell),
                      c = cell;
                float q[6] = {cx, cy, cx + c, cy, cx, cy + c};
                float o[6] = {cx + c, cy + c, cx, cy + c, cx + c, cy};
                for (int k = 0; k < 6; k++)
                        a->uv[6 * t + k] = (t & 1 ? o[k] : q[k]) / (k & 1 ? a->height : a->width);
        }
        for (int y = 0; y < a->height; y++)
                for (int x = 0; x < a->width; x++) {
                        size_t i = (size_t)y * a->width + x,
                               ci = (size_t)(y / cell) * cols + x / cell;
                        float lx = x % cell + 0.5f, ly = y % cell + 0.5f, *w = a->bary + 3 * i;
                        bool up = lx + ly < cell;
                        size_t t = 2 * ci + !up;
                        w[1] = (up ? lx : cell - lx) / cell;
                        w[2] = (up ? ly : cell - ly) / cell;
                        w[0] = 1 - w[1] - w[2];
                        a->tri[i] = t < nt ? (int32_t)t : -1;
                }
}

/* Every texel: the true material, the normal interpolated from area-weighted vertex normals. */
static void texels_fixture(struct ap_brdf_model *m, const struct envscene_opts *o)
{
        const struct ap_atlas *a = &m->atlas;
        const struct ap_mesh *ms = &a->mesh;
        float *vn = calloc(3 * ms->nv, sizeof(float)), alb[3] = ENVSCENE_ALBEDO;

        m->texels = calloc((size_t)a->width * a->height, sizeof(*m->texels));
        CHECK(vn && m->texels);
        for (size_t t = 0; t < ms->nt; t++) {
                const uint32_t *ix = ms->idx + 3 * t;
                const float *p0 = ms->pos + 3 * ix[0], *p1 = ms->pos + 3 * ix[1],
                            *p2 = ms->pos + 3 * ix[2];
                float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
                float e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
                float fn[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                               e1[0] * e2[1] - e1[1] * e2[0]};
                for (int k = 0; k < 3; k++)
                        for (int q = 0; q < 3; q++)
                                vn[3 * ix[k] + q] += fn[q] * (ms->front < 0 ? -1.f : 1.f);
        }
        for (size_t i = 0; i < (size_t)a->width * a->height; i++) {
                struct ap_brdf_texel *x = &m->texels[i];
                const float *w = a->bary + 3 * i;
                float n[3] = {0}, l, tz;
                if (a->tri[i] < 0)
                        continue;
                for (int k = 0; k < 3; k++)
                        for (int q = 0; q < 3; q++)
                                n[q] += w[k] * vn[3 * ms->idx[3 * a->tri[i] + k] + q];
                l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                for (int q = 0; q < 3; q++) {
                        x->normal[q] = n[q] / l;
                        x->albedo[q] = alb[q];
                }
                tz = x->normal[2]; /* the tangent: z projected on the plane (the simulator's) */
                x->tangent[0] = -tz * x->normal[0];
                x->tangent[1] = -tz * x->normal[1];
                x->tangent[2] = 1 - tz * x->normal[2];
                l = sqrtf(x->tangent[0] * x->tangent[0] + x->tangent[1] * x->tangent[1] +
                          x->tangent[2] * x->tangent[2]);
                for (int q = 0; q < 3 && l > 0; q++)
                        x->tangent[q] /= l;
                *x = (struct ap_brdf_texel){{x->albedo[0], x->albedo[1], x->albedo[2]},
                                            (float)o->ks,
                                            (float)o->ax,
                                            (float)o->ay,
                                            ENVSCENE_F0,
                                            {x->normal[0], x->normal[1], x->normal[2]},
                                            {x->tangent[0], x->tangent[1], x->tangent[2]},
                                            0,
                                            1,
                                            AP_BRDF_FITTED};
        }
        free(vn);
}

static void build_model(struct envscene *es)
{
        struct sim_mesh sm;
        struct ap_brdf_model *m = calloc(1, sizeof(*m));

        CHECK(m != NULL);
        CHECK_INT(sim_object_mesh(es->t.s, 96, &sm), 0);
        m->atlas.mesh = (struct ap_mesh){sm.nv, sm.nt, sm.pos, sm.idx, 0};
        CHECK_INT(ap_mesh_orient(&m->atlas.mesh), 0);
        atlas_fixture(&m->atlas, 4);
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
        char cams[512], scene[1024], err[256];
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
                 "  dome: { envmap: %s, threshold: 0.00001, max_elements: %d }\n"
                 "  sensor: { response: %g, full_well: %g, read_noise: 0, black_level: 0 }\n",
                 0.55, 0.35, 0.25, o->ks, o->ax, o->ay, o->ground_radius, es->env_path,
                 o->dome_elements, RESPONSE, FULL_WELL);
        rt_open(&es->t, "", "", cams, scene);
        build_model(es);
        camera_of(es);
}

void envscene_close(struct envscene *es)
{
        if (es->model) {
                ap_mesh_free(&es->model->atlas.mesh);
                free(es->model->atlas.uv);
                free(es->model->atlas.tri);
                free(es->model->atlas.bary);
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
        struct gn_pose st = {0};
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
