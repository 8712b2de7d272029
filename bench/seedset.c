/* seedset.c - the seed-scale dataset of the appearance benchmarks (seedset.h): the rig file
 * of its geometry, rendered view by view into a dataset by gonio-sim's renderer. */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "bench/clock.h"
#include "bench/seedset.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds_png.h"
#include "common/rigconf.h"
#include "drivers/registry.h"
#include "sim/render/render.h"

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

void seedset_die(const char *what, int r)
{
        fprintf(stderr, "bench: %s: %s\n", what, strerror(r < 0 ? -r : r));
        exit(1);
}

/* Renders and stores every view under every light into a new dataset at path. */
static void generate(const struct seedset_opts *o, const char *path)
{
        _cleanup_free_ char *rigpath = NULL;
        struct rig_config *rc = NULL;
        struct sim_scene *s = NULL;
        struct sim_expose ex = {.bits = 8, .no_noise = true};
        struct ds *d;
        char err[512];
        double t0 = bench_wall_s();
        int r;

        if (asprintf(&rigpath, "%s.rig.yaml", path) < 0)
                seedset_die("asprintf", -ENOMEM);
        r = gn_write_atomic(AT_FDCWD, rigpath, rig_fmt, strlen(rig_fmt), NULL);
        if (r == 0)
                r = rigconf_load(rigpath, registry_backends, &rc, err, sizeof(err));
        if (r == 0)
                r = sim_scene_new(rc, &s, err, sizeof(err));
        if (r == 0)
                r = ds_create(path, "bench-fit", rig_fmt, &d);
        if (r < 0)
                seedset_die(err[0] ? err : "generate", r);
        for (int c = 0; c < o->cameras; c++)
                for (int v = 0; v < o->turntable; v++)
                        for (int a = 0; a < o->arm; a++)
                                for (int l = 0; l < SEEDSET_LAMPS; l++) {
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
                                                seedset_die("render or store", r);
                                }
        ds_close(d);
        sim_scene_free(s);
        rigconf_free(rc);
        unlink(rigpath);
        fprintf(stderr, "bench: generated %s in %.0f s\n", path, bench_wall_s() - t0);
}

void seedset_parse(int argc, char **argv, struct seedset_opts *o)
{
        static const struct option lo[] = {{"cameras", 1, NULL, 'c'},
                                           {"turntable", 1, NULL, 't'},
                                           {"arm", 1, NULL, 'a'},
                                           {"dir", 1, NULL, 'd'},
                                           {}};
        const char *cache = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
        int c;

        *o = (struct seedset_opts){.cameras = 4, .turntable = 19, .arm = 20};
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

void seedset_open(const struct seedset_opts *o, struct ds **d)
{
        char path[4400];
        int r;

        snprintf(path, sizeof(path), "%s/bench-fit-%dx%dx%dx%d", o->dir, o->cameras, o->turntable,
                 o->arm, SEEDSET_LAMPS);
        if (access(path, F_OK) < 0) {
                char dir[sizeof(o->dir)];
                memcpy(dir, o->dir, sizeof(dir));
                for (char *s = strchr(dir + 1, '/'); s; s = strchr(s + 1, '/')) {
                        *s = 0;
                        mkdir(dir, 0755);
                        *s = '/';
                }
                mkdir(dir, 0755);
                generate(o, path);
        }
        if ((r = ds_open(path, d)) < 0)
                seedset_die(path, r);
}

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

double seedset_decode_all(struct ds *d)
{
        struct decode_job j = {.dir = ds_path(d), .lock = PTHREAD_MUTEX_INITIALIZER};
        pthread_t t;
        double t0;

        if (ds_rows_collect(d, NULL, NULL, &j.rows, &j.n) < 0)
                seedset_die("rows", -EIO);
        t0 = bench_wall_s();
        pthread_create(&t, NULL, decode_worker, &j);
        decode_worker(&j);
        pthread_join(t, NULL);
        t0 = bench_wall_s() - t0;
        free(j.rows);
        return t0;
}
