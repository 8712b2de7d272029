/* relight.c - issue 10's relighting benchmark: a synthetic model of K = 12 components and
 * order 6 over 30 views (10 turntable angles x 3 camera elevations, 320x240 weight images)
 * on a 20k-triangle sphere, rendered at 640x480 in the per-pixel view mode on 2 threads
 * while the point light and the view move every frame; then the same in the per-object
 * mode. Target: at least 60 frames/s per pixel. Last line:
 * {"bench":"relight","fps":...,"width":640,"height":480}. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "bench/clock.h"
#include "appearance/model.h"
#include "appearance/raster.h"
#include "appearance/render.h"
#include "common/cleanup.h"

#define RADIUS 30.0
#define ROWS   100 /* sphere rows: 2 * ROWS * ROWS triangles */
#define K      12
#define ORDER  6
#define FRAMES 240

static void sphere(struct ap_mesh *m)
{
        int cols = 2 * ROWS;
        size_t v = 0, t = 0;

        m->nv = (size_t)(ROWS + 1) * (cols + 1);
        m->nt = (size_t)ROWS * cols * 2;
        m->pos = malloc(3 * m->nv * sizeof(float));
        m->idx = malloc(3 * m->nt * sizeof(uint32_t));
        if (!m->pos || !m->idx)
                exit(1);
        for (int i = 0; i <= ROWS; i++)
                for (int j = 0; j <= cols; j++, v++) {
                        double th = M_PI * i / ROWS, ph = 2 * M_PI * j / cols;
                        m->pos[3 * v] = (float)(RADIUS * sin(th) * cos(ph));
                        m->pos[3 * v + 1] = (float)(RADIUS * sin(th) * sin(ph));
                        m->pos[3 * v + 2] = (float)(RADIUS * cos(th));
                }
        for (int i = 0; i < ROWS; i++)
                for (int j = 0; j < cols; j++) {
                        uint32_t a = (uint32_t)(i * (cols + 1) + j), b = a + (uint32_t)cols + 1;
                        uint32_t q[6] = {a, a + 1, b + 1, a, b + 1, b};
                        for (int k = 0; k < 6; k++)
                                m->idx[3 * t + k] = q[k];
                        t += 2;
                }
}

static void camera_at(double az, double el, double dist, int w, int h, double f,
                      struct ap_camera *c)
{
        struct ap_camera in = {w, h, f, f, w / 2.0 - 0.5, h / 2.0 - 0.5};
        double a = az * M_PI / 180, e = el * M_PI / 180, o[3] = {0};
        double eye[3] = {dist * cos(e) * cos(a), dist * cos(e) * sin(a), dist * sin(e)};

        if (ap_camera_look_at(&in, eye, o, c) < 0)
                exit(1);
}

/* Weights of one view: smooth functions of the surface point, from its depth map. */
static void fill_view(struct ap_view *v, const struct ap_mesh *m)
{
        const struct ap_camera *c = &v->cam;
        struct ap_pinhole ph = {c->width, c->height, c->fx, c->fy, c->cx, c->cy};
        size_t n = (size_t)c->width * c->height;
        _cleanup_free_ float *depth = malloc(n * sizeof(float));

        for (int i = 0; i < 9; i++)
                ph.R[i] = c->R[i];
        for (int i = 0; i < 3; i++)
                ph.t[i] = c->t[i];
        if (!depth || ap_view_alloc(v, K) < 0 || ap_raster(m, &ph, depth, NULL) < 0)
                exit(1);
        for (size_t i = 0; i < n; i++) {
                double x = ((double)(i % c->width) - c->cx) / c->fx * depth[i];
                if (!isfinite(depth[i]))
                        continue;
                v->mask[i] = 1;
                for (int k = 0; k < K; k++)
                        v->weights[i * K + k] = (float)(sin(0.05 * (k + 1) * x + k) / (k + 1));
        }
}

static struct ap_model *make_model(const struct ap_mesh *mesh)
{
        struct ap_model *m = NULL;
        size_t n = 0;

        if (ap_model_new(ORDER, K, 30, &m) < 0)
                exit(1);
        for (int i = 0; i < 3 * ORDER * ORDER; i++)
                m->mean[i] = (float)(0.5 / (1 + i));
        for (int i = 0; i < 3 * ORDER * ORDER * K; i++)
                m->basis[i] = (float)(0.3 * cos(0.7 * i) / (1 + i % 36));
        m->light_distance_mm = 300, m->light_intensity = 1;
        for (int e = 0; e < 3; e++)
                for (int a = 0; a < 10; a++, n++) {
                        struct ap_view *v = &m->views[n];
                        double az = 36.0 * a, el = 10 + 25.0 * e;
                        camera_at(az, el, 400, 320, 240, 800, &v->cam);
                        v->dir[0] = cos(el * M_PI / 180) * cos(az * M_PI / 180);
                        v->dir[1] = cos(el * M_PI / 180) * sin(az * M_PI / 180);
                        v->dir[2] = sin(el * M_PI / 180);
                        fill_view(v, mesh);
                }
        return m;
}

/* Frames per second of FRAMES frames in mode, light and view moving. */
static double run(struct ap_renderer *r, enum ap_view_mode mode, float *rgb, uint8_t *mask,
                  size_t *covered, double *cpu_ms)
{
        double t0 = bench_wall_s(), c0 = bench_cpu_self_s();

        for (int f = 0; f < FRAMES; f++) {
                struct ap_camera cam;
                double a = 2 * M_PI * f / FRAMES;
                struct ap_light l = {AP_LIGHT_POINT,
                                     {300 * cos(3 * a), 300 * sin(3 * a), 150 + 100 * sin(a)},
                                     1,
                                     NULL};
                camera_at(360.0 * f / FRAMES, 35 + 15 * sin(a), 150, 640, 480, 1000, &cam);
                if (ap_render(r, &cam, &l, mode, 2, rgb, mask) < 0)
                        exit(1);
        }
        *cpu_ms = (bench_cpu_self_s() - c0) * 1e3 / FRAMES;
        *covered = 0;
        for (size_t i = 0; i < 640 * 480; i++)
                *covered += mask[i];
        return FRAMES / (bench_wall_s() - t0);
}

int main(void)
{
        struct ap_mesh mesh;
        _cleanup_free_ float *rgb = malloc(3 * 640 * 480 * sizeof(float));
        _cleanup_free_ uint8_t *mask = malloc(640 * 480);
        struct ap_renderer *r = NULL;
        struct ap_model *m;
        double t0 = bench_wall_s(), fps_px, fps_obj, setup, cpu_px, cpu_obj;
        size_t cov;

        sphere(&mesh);
        if (ap_mesh_orient(&mesh) < 0)
                return 1;
        m = make_model(&mesh);
        t0 = bench_wall_s();
        if (!rgb || !mask || ap_renderer_new(m, &mesh, &r) < 0)
                return 1;
        setup = bench_wall_s() - t0;
        fps_obj = run(r, AP_VIEW_OBJECT, rgb, mask, &cov, &cpu_obj);
        fps_px = run(r, AP_VIEW_PIXEL, rgb, mask, &cov, &cpu_px);
        printf("relight: %zu triangles (%s), %zu views, K=%d, P=%d; renderer setup %.3f s\n",
               mesh.nt, mesh.front ? "closed: back faces skipped" : "open", m->n_views, K, ORDER,
               setup);
        printf("relight: 640x480, %zu object pixels in the last frame (%.0f%%), 2 threads\n", cov,
               100.0 * cov / (640 * 480));
        printf("relight: per-object view mode %.1f fps, %.1f ms CPU a frame\n", fps_obj, cpu_obj);
        printf("relight: per-pixel view mode %.1f fps, %.1f ms CPU a frame (target >= 60 fps)\n",
               fps_px, cpu_px);
        printf("relight: (2 threads on an idle machine: at most 2000 / CPU ms fps)\n");
        printf("{\"bench\":\"relight\",\"fps\":%.1f,\"fps_object\":%.1f,\"width\":640,"
               "\"height\":480}\n",
               fps_px, fps_obj);
        ap_renderer_free(r);
        ap_model_free(m);
        ap_mesh_free(&mesh);
        return 0;
}
