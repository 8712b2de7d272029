/* viewer.c - issue 11's viewer benchmark: a fitted model (a glossy 60 mm sphere, 3 cameras x
 * 12 turntable angles at 320x240, 6 lamps x 12 light-arm angles; generated once into
 * $XDG_CACHE_HOME/gonio/bench-viewer) shown by the WebGL viewer (gonioctl model view) in
 * headless Chromium at 1280x720, per pixel, the light moving every frame, against the CPU
 * renderer (render.h, 2 threads) on the same model, frame and light in the same run; and the
 * bytes the page downloads before its first relit frame against the model's size on disk.
 * Last line: {"bench":"viewer","fps":...,"cpu_fps":...,"first_frame_bytes":...,
 * "model_bytes":...}. Usage: viewer [--size WxH]. */
#include <dirent.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "bench/clock.h"
#include "appearance/mesh.h"
#include "appearance/render.h"
#include "common/cleanup.h"
#include "drivers/registry.h"
#include "tests/appearance/apscene.h"

#define CPU_FRAMES 20

/* The cached dataset with its model, made when missing. */
static void ensure_model(const char *ds, const char *model)
{
        struct aps_opts o;
        struct apscene s;
        struct ap_model *m;
        struct stat st;
        double t0 = bench_wall_s();

        if (stat(model, &st) == 0)
                return;
        fprintf(stderr, "viewer: generating %s (once)\n", ds);
        aps_opts_default(&o, APS_GLOSSY);
        o.width = 320, o.height = 240;
        o.n_cameras = 3, o.turntable_angles = 12, o.arm_angles = 12;
        aps_open(&s, &o);
        aps_fit_dataset(&s, ds, 8, &m);
        ap_model_free(m);
        aps_close(&s);
        fprintf(stderr, "viewer: generated in %.0f s\n", bench_wall_s() - t0);
}

/* Bytes of the regular files under dir. */
static long long dir_bytes(const char *dir)
{
        DIR *d = opendir(dir);
        struct dirent *e;
        long long n = 0;

        while (d && (e = readdir(d))) {
                char p[4400];
                struct stat st;
                if (e->d_name[0] == '.')
                        continue;
                snprintf(p, sizeof(p), "%s/%s", dir, e->d_name);
                if (stat(p, &st) == 0)
                        n += S_ISDIR(st.st_mode) ? dir_bytes(p) : st.st_size;
        }
        if (d)
                closedir(d);
        return n;
}

/* The CPU renderer's frames per second at w x h, per pixel, the light moving as the page's. */
static double cpu_fps(const char *ds, const char *model, int w, int h)
{
        struct ap_model *m;
        struct ap_mesh mesh;
        struct ap_renderer *r;
        struct ap_camera cam, in = {w, h, 0, 0, w / 2.0 - 0.5, h / 2.0 - 0.5};
        char err[1024], src[4200];
        double c[3], eye[3], t0, dir[3];
        float *rgb = malloc(3 * sizeof(float) * w * h);
        uint8_t *mask = malloc((size_t)w * h);

        if (!rgb || !mask || ap_model_read(model, &m, err, sizeof(err)) < 0 ||
            ap_mesh_for_dataset(ds, registry_backends, &mesh, src, sizeof(src), err, sizeof(err)) <
                    0 ||
            ap_renderer_new(m, &mesh, &r) < 0)
                exit(1);
        ap_renderer_centre(r, c);
        memcpy(dir, m->views[0].dir, sizeof(dir));
        in.fx = in.fy = m->views[0].cam.fx *
                        fmin((double)w / m->views[0].cam.width, (double)h / m->views[0].cam.height);
        for (int i = 0; i < 3; i++)
                eye[i] = c[i] + 400 * dir[i];
        ap_camera_look_at(&in, eye, c, &cam);
        t0 = bench_wall_s();
        for (int f = 0; f < CPU_FRAMES; f++) {
                double a = (40.0 + f) * M_PI / 180;
                struct ap_light l = {AP_LIGHT_POINT,
                                     {c[0] + 500 * cos(a), c[1] + 500 * sin(a), c[2] + 350}};
                if (ap_render(r, &cam, &l, AP_VIEW_PIXEL, 2, rgb, mask) < 0)
                        exit(1);
        }
        t0 = CPU_FRAMES / (bench_wall_s() - t0);
        ap_renderer_free(r);
        ap_mesh_free(&mesh);
        ap_model_free(m);
        free(rgb);
        free(mask);
        return t0;
}

int main(int argc, char **argv)
{
        const char *cache = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
        char dir[4096], ds[4200], model[4300], cmd[9000], line[4096] = "", last[4096] = "";
        int w = 1280, h = 720;
        double fps = 0, cpu;
        long long first = 0, bytes;
        FILE *p;

        if (argc == 3 && strcmp(argv[1], "--size") == 0 && sscanf(argv[2], "%dx%d", &w, &h) != 2)
                return 2;
        snprintf(dir, sizeof(dir), "%s%s/gonio", cache && *cache ? cache : home ?: "/tmp",
                 cache && *cache ? "" : "/.cache");
        snprintf(ds, sizeof(ds), "%s/bench-viewer", dir);
        snprintf(model, sizeof(model), "%s/models/default", ds);
        mkdir(dir, 0755);
        ensure_model(ds, model);
        bytes = dir_bytes(model);
        cpu = cpu_fps(ds, model, w, h);
        printf("viewer: CPU renderer %.1f fps at %dx%d per pixel (2 threads)\n", cpu, w, h);
        snprintf(cmd, sizeof(cmd), "python3 %s/bench/viewer-page.py %s/client/gonioctl %s %dx%d",
                 GONIO_SOURCE_DIR, GONIO_BUILD_DIR, model, w, h);
        if (!(p = popen(cmd, "r")))
                return 1;
        while (fgets(line, sizeof(line), p))
                snprintf(last, sizeof(last), "%s", line);
        if (pclose(p) != 0 ||
            sscanf(last, "{\"fps\": %lf, \"first_frame_bytes\": %lld", &fps, &first) != 2) {
                fprintf(stderr, "viewer: the browser half failed: %s\n", last);
                return 1;
        }
        printf("viewer: WebGL page %.1f fps at %dx%d (headless Chromium, software GL), %.2fx the "
               "CPU renderer\n",
               fps, w, h, fps / cpu);
        printf("viewer: %lld bytes before the first frame, of %lld on disk (%.2f)\n", first, bytes,
               (double)first / bytes);
        printf("{\"bench\":\"viewer\",\"fps\":%.2f,\"cpu_fps\":%.2f,\"first_frame_bytes\":%lld,"
               "\"model_bytes\":%lld}\n",
               fps, cpu, first, bytes);
        return 0;
}
