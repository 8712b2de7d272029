/* bench/fit.c - the appearance fit (appearance/fit.h) of a seed-scale synthetic dataset
 * (76 views x 100 lights x 720x480 by default: 4 cameras x 19 turntable angles, 5 lamps x 20
 * light-arm angles; a glossy 250 mm sphere rendered by gonio-sim's renderer, 8-bit, noise off),
 * generated once and cached in $XDG_CACHE_HOME/gonio/bench-fit-<shape> (else
 * ~/.cache/...), fitted end to end (SH order 6 + PCA K 12, written), against in the same run
 * the time to merely decode its images (2 threads) and the time of the fit's matrix products
 * (36 x L by L x 3N per view, OpenBLAS on 2 threads). Targets: fit at most 60 s on 2 cores and
 * at most 2 x (decode + product). Options: --turntable N (views per camera: fewer for a
 * smaller run), --arm N, --cameras N, --dir DIR. The CPU seconds of each part go to stderr
 * (the machine is shared: wall times move with its load). Last line: one JSON object. */
#include <cblas.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "appearance/fit.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds.h"
#include "dataset/ds_png.h"
#include "drivers/registry.h"
#include "sim/render/render.h"

#define LAMPS 5

struct opts {
        int cameras, turntable, arm;
        char dir[4096];
};

static const char rig_fmt[] =
        "rig: bench-fit\n"
        "buses:\n"
        "  - { name: relays, type: modbus-rtu, port: /nonexistent/relays }\n"
        "  - { name: frames, type: sim, port: /nonexistent/frames.sock }\n"
        "lamps:\n"
        "  - { name: l0, elevation: -40, radius: 800, intensity: 1.2e6, modbus-coil: { bus: "
        "relays, coil: 0 } }\n"
        "  - { name: l1, elevation: -10, radius: 800, intensity: 1.2e6, modbus-coil: { bus: "
        "relays, coil: 1 } }\n"
        "  - { name: l2, elevation: 20, radius: 800, intensity: 1.2e6, modbus-coil: { bus: relays, "
        "coil: 2 } }\n"
        "  - { name: l3, elevation: 50, radius: 800, intensity: 1.2e6, modbus-coil: { bus: relays, "
        "coil: 3 } }\n"
        "  - { name: l4, elevation: 80, radius: 800, intensity: 1.2e6, modbus-coil: { bus: relays, "
        "coil: 4 } }\n"
        "cameras:\n"
        "  - { name: cam0, elevation: 10, distance: 600, azimuth: 0, target: [0, 0, 125], width: "
        "720, height: 480, fx: 1100, fy: 1100, exposure_us: 20000, sim: { bus: frames } }\n"
        "  - { name: cam1, elevation: 27, distance: 600, azimuth: 0, target: [0, 0, 125], width: "
        "720, height: 480, fx: 1100, fy: 1100, exposure_us: 20000, sim: { bus: frames } }\n"
        "  - { name: cam2, elevation: 44, distance: 600, azimuth: 0, target: [0, 0, 125], width: "
        "720, height: 480, fx: 1100, fy: 1100, exposure_us: 20000, sim: { bus: frames } }\n"
        "  - { name: cam3, elevation: 61, distance: 600, azimuth: 0, target: [0, 0, 125], width: "
        "720, height: 480, fx: 1100, fy: 1100, exposure_us: 20000, sim: { bus: frames } }\n"
        "scene:\n"
        "  seed: 1\n"
        "  object: { shape: sphere, size: 250, material: { albedo: [0.7, 0.55, 0.4],\n"
        "            specular: { model: beckmann, ks: 0.2, alpha: 0.4, ior: 1.5 } } }\n"
        "  turntable: { radius: 0 }\n";

static double now_s(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* CPU seconds of the process so far (user + system, all threads). */
static double cpu_s(void)
{
        struct rusage u;

        getrusage(RUSAGE_SELF, &u);
        return u.ru_utime.tv_sec + u.ru_utime.tv_usec * 1e-6 + u.ru_stime.tv_sec +
               u.ru_stime.tv_usec * 1e-6;
}

static void die(const char *what, int r)
{
        fprintf(stderr, "bench/fit: %s: %s\n", what, strerror(r < 0 ? -r : r));
        exit(1);
}

/* Renders and stores every view under every light into a new dataset at path. */
static void generate(const struct opts *o, const char *path)
{
        _cleanup_free_ char *rigpath = NULL;
        struct rig_config *rc = NULL;
        struct sim_scene *s = NULL;
        struct sim_expose ex = {.bits = 8, .no_noise = true};
        struct ds *d;
        char err[512];
        double t0 = now_s();
        int r;

        if (asprintf(&rigpath, "%s.rig.yaml", path) < 0)
                die("asprintf", -ENOMEM);
        r = gn_write_atomic(AT_FDCWD, rigpath, rig_fmt, strlen(rig_fmt), NULL);
        if (r == 0)
                r = rigconf_load(rigpath, registry_backends, &rc, err, sizeof(err));
        if (r == 0)
                r = sim_scene_new(rc, &s, err, sizeof(err));
        if (r == 0)
                r = ds_create(path, "bench-fit", rig_fmt, &d);
        if (r < 0)
                die(err[0] ? err : "generate", r);
        for (int c = 0; c < o->cameras; c++)
                for (int v = 0; v < o->turntable; v++)
                        for (int a = 0; a < o->arm; a++)
                                for (int l = 0; l < LAMPS; l++) {
                                        struct ds_capture cap = {.pose = {{360.0 * v / o->turntable,
                                                                           360.0 * a / o->arm, NAN},
                                                                          1u << l},
                                                                 .exposure_us = 20000};
                                        struct gn_frame f;
                                        snprintf(cap.camera, sizeof(cap.camera), "cam%d", c);
                                        snprintf(cap.lamps, sizeof(cap.lamps), "l%d", l);
                                        r = sim_render(s, &cap.pose, c, &ex, 0, &f, 0, NULL);
                                        if (r == 0)
                                                r = ds_store(d, &f, &cap);
                                        gn_frame_free_data(&f);
                                        if (r < 0)
                                                die("render or store", r);
                                }
        ds_close(d);
        sim_scene_free(s);
        rigconf_free(rc);
        unlink(rigpath);
        fprintf(stderr, "bench/fit: generated %s in %.0f s\n", path, now_s() - t0);
}

/* ---- decoding alone ---- */

struct decode_job {
        struct ds_capture *rows;
        size_t n, next;
        const char *dir;
        pthread_mutex_t lock;
};

static void *decode_worker(void *arg)
{
        struct decode_job *j = arg;

        for (;;) {
                _cleanup_free_ void *buf = NULL;
                struct gn_frame f = {0};
                char path[8192];
                size_t i, len;
                pthread_mutex_lock(&j->lock);
                i = j->next++;
                pthread_mutex_unlock(&j->lock);
                if (i >= j->n)
                        return NULL;
                snprintf(path, sizeof(path), "%s/%s", j->dir, j->rows[i].file);
                if (gn_read_file_at(AT_FDCWD, path, (size_t)1 << 30, &buf, &len) == 0 &&
                    ds_png_decode(buf, len, &f) == 0)
                        gn_frame_free_data(&f);
        }
}

/* Seconds to read and decode every image of d on 2 threads. */
static double decode_all(struct ds *d)
{
        struct decode_job j = {.dir = ds_path(d), .lock = PTHREAD_MUTEX_INITIALIZER};
        pthread_t t;
        double t0;

        if (ds_rows_collect(d, NULL, NULL, &j.rows, &j.n) < 0)
                die("rows", -EIO);
        t0 = now_s();
        pthread_create(&t, NULL, decode_worker, &j);
        decode_worker(&j);
        pthread_join(t, NULL);
        t0 = now_s() - t0;
        free(j.rows);
        return t0;
}

/* Seconds of the fit's products: per view 36 x L by L x 3N, OpenBLAS on 2 threads. */
static double gemm_all(int views, int lights)
{
        size_t N = 3 * 720 * 480;
        float *P = calloc((size_t)36 * lights, sizeof(float)),
              *D = malloc(N * lights * sizeof(float));
        float *C = malloc(N * 36 * sizeof(float));
        double t0;

        if (!P || !D || !C)
                die("gemm", -ENOMEM);
        for (size_t i = 0; i < N * lights; i++)
                D[i] = (float)(i % 251) / 251;
        openblas_set_num_threads(2);
        t0 = now_s();
        for (int v = 0; v < views; v++)
                cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, 36, (int)N, lights, 1, P,
                            lights, D, (int)N, 0, C, (int)N);
        t0 = now_s() - t0;
        free(P), free(D), free(C);
        return t0;
}

static void parse(int argc, char **argv, struct opts *o)
{
        static const struct option lo[] = {{"cameras", 1, NULL, 'c'},
                                           {"turntable", 1, NULL, 't'},
                                           {"arm", 1, NULL, 'a'},
                                           {"dir", 1, NULL, 'd'},
                                           {}};
        const char *cache = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
        int c;

        *o = (struct opts){.cameras = 4, .turntable = 19, .arm = 20};
        snprintf(o->dir, sizeof(o->dir), "%s%s/gonio", cache && *cache ? cache : home ?: "/tmp",
                 cache && *cache ? "" : "/.cache");
        while ((c = getopt_long(argc, argv, "", lo, NULL)) != -1) {
                int *n = c == 'c' ? &o->cameras : c == 't' ? &o->turntable : &o->arm;
                if (c == 'd')
                        snprintf(o->dir, sizeof(o->dir), "%s", optarg);
                else if (c == '?' || (*n = atoi(optarg)) < 1)
                        exit(2);
        }
        if (o->cameras > 4)
                exit(2);
}

int main(int argc, char **argv)
{
        struct ap_fit_opts fo;
        struct ap_model *m = NULL;
        struct opts o;
        struct ds *d;
        char path[4400], err[1024];
        double fit_s, decode_s, gemm_s, cpu[4];
        int r;

        parse(argc, argv, &o);
        snprintf(path, sizeof(path), "%s/bench-fit-%dx%dx%dx%d", o.dir, o.cameras, o.turntable,
                 o.arm, LAMPS);
        if (access(path, F_OK) < 0) {
                char *p = o.dir;
                for (char *s = strchr(p + 1, '/'); s; s = strchr(s + 1, '/')) {
                        *s = 0;
                        mkdir(p, 0755);
                        *s = '/';
                }
                mkdir(o.dir, 0755);
                generate(&o, path);
        }
        if ((r = ds_open(path, &d)) < 0)
                die(path, r);
        cpu[0] = cpu_s();
        decode_s = decode_all(d);
        cpu[1] = cpu_s();
        gemm_s = gemm_all(o.cameras * o.turntable, o.arm * LAMPS);
        cpu[2] = cpu_s();
        ap_fit_opts_default(&fo);
        fo.backends = registry_backends;
        fit_s = now_s();
        r = ap_fit(d, &fo, &m, err, sizeof(err));
        if (r == 0)
                r = ap_model_write(m, ds_path(d));
        fit_s = now_s() - fit_s;
        cpu[3] = cpu_s();
        if (r < 0)
                die(err, r);
        fprintf(stderr,
                "bench/fit: %zu views: fit %.1f s (rms sh %.4f, pca %.4f; %s), decode %.1f "
                "s, products %.1f s: %.2f x (decode + products); CPU seconds: fit %.1f, decode "
                "%.1f, products %.1f\n",
                m->n_views, fit_s, m->rms_sh, m->rms_pca, m->notes, decode_s, gemm_s,
                fit_s / (decode_s + gemm_s), cpu[3] - cpu[2], cpu[1] - cpu[0], cpu[2] - cpu[1]);
        printf("{\"bench\":\"fit\",\"fit_s\":%.2f,\"decode_s\":%.2f,\"gemm_s\":%.2f,\"views\":%d,"
               "\"lights\":%d}\n",
               fit_s, decode_s, gemm_s, o.cameras * o.turntable, o.arm * LAMPS);
        ap_model_free(m);
        ds_close(d);
        return 0;
}
