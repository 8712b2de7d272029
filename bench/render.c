/* bench/render.c - frames per second of the renderer at 720x480 (a 100k-triangle object,
 * one lamp with shadow rays, the laser, sensor noise) against the raw Embree throughput of
 * the same rays (the same primary 16-ray packets plus one shadow packet each, nothing
 * else) on the same scene and cores, and their ratio. Last line: one JSON object. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/rigconf.h"
#include "drivers/registry.h"
#include "sim/render/internal.h"

static const char rig[] =
        "rig: bench\n"
        "buses:\n"
        "  - { name: relays, type: modbus-rtu, port: /nonexistent/relays }\n"
        "  - { name: frames, type: sim, port: /nonexistent/frames.sock }\n"
        "lamps:\n"
        "  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 30, radius: 450,"
        " intensity: 4.0e5 }\n"
        "laser: { name: laser, modbus-coil: { bus: relays, coil: 7 }, azimuth: 0,"
        " origin: [600, 0, 150], width: 0.6, power: 2.0e3, channel: red }\n"
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 15, distance: 600, azimuth: 30,"
        " target: [0, 0, 80], width: 720, height: 480, fx: 1100, fy: 1100,"
        " distortion: [-0.08, 0.05, 0.0005, -0.0003, 0], exposure_us: 20000 }\n"
        "scene:\n"
        "  object: { shape: sphere, size: 170, resolution: 158,\n" /* 99,856 triangles */
        "            material: { albedo: [0.7, 0.55, 0.35],\n"
        "                        specular: { model: beckmann, ks: 0.3, alpha_x: 0.25,"
        " alpha_y: 0.12, ior: 1.5 } } }\n"
        "  turntable: { radius: 150 }\n";

struct raw {
        const struct sim_scene *s;
        float M[9];
        struct v3 org, lamp;
        int w, h, tiles_x, n_tiles;
        atomic_int next;
        atomic_long rays;
};

static double now(void)
{
        return (double)gn_monotonic_ns() * 1e-9;
}

/* The same packets as the renderer: 4x4 tiles, primary rays, one shadow packet. */
static long raw_tile(const struct raw *c, int tile)
{
        struct RTCRayHit16 rh;
        struct RTCRay16 sh;
        struct RTCIntersectContext ic;
        _Alignas(64) int valid[16];
        _Alignas(64) int on[16];
        long n = 0;

        for (int i = 0; i < 16; i++) {
                int x = (tile % c->tiles_x) * 4 + (i & 3), y = (tile / c->tiles_x) * 4 + (i >> 2);
                const float *d = c->s->cams[0].dirs + 3 * (y * c->w + x);
                struct v3 dw = m3_mul(c->M, v3(d[0], d[1], d[2]));
                valid[i] = x < c->w && y < c->h ? -1 : 0;
                rh.ray.org_x[i] = c->org.x, rh.ray.org_y[i] = c->org.y, rh.ray.org_z[i] = c->org.z;
                rh.ray.dir_x[i] = dw.x, rh.ray.dir_y[i] = dw.y, rh.ray.dir_z[i] = dw.z;
                rh.ray.tnear[i] = 0, rh.ray.tfar[i] = INFINITY, rh.ray.mask[i] = ~0u;
                rh.ray.flags[i] = 0, rh.ray.time[i] = 0;
                rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
                n += valid[i] != 0;
        }
        rtcInitIntersectContext(&ic);
        ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        rtcIntersect16(valid, c->s->scn, &ic, &rh);
        for (int i = 0; i < 16; i++) {
                struct v3 p = v3(rh.ray.org_x[i] + rh.ray.tfar[i] * rh.ray.dir_x[i],
                                 rh.ray.org_y[i] + rh.ray.tfar[i] * rh.ray.dir_y[i],
                                 rh.ray.org_z[i] + rh.ray.tfar[i] * rh.ray.dir_z[i]);
                struct v3 l = v3_sub(c->lamp, p);
                float dist = v3_len(l);
                on[i] = valid[i] && rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID ? -1 : 0;
                sh.org_x[i] = p.x, sh.org_y[i] = p.y, sh.org_z[i] = p.z;
                sh.dir_x[i] = l.x / dist, sh.dir_y[i] = l.y / dist, sh.dir_z[i] = l.z / dist;
                sh.tnear[i] = 1e-3f, sh.tfar[i] = dist, sh.mask[i] = ~0u, sh.flags[i] = 0;
                sh.time[i] = 0;
                n += on[i] != 0;
        }
        rtcInitIntersectContext(&ic);
        rtcOccluded16(on, c->s->scn, &ic, &sh);
        return n;
}

static void *raw_worker(void *arg)
{
        struct raw *c = arg;
        long n = 0;
        int t;

        while ((t = atomic_fetch_add(&c->next, 1)) < c->n_tiles)
                n += raw_tile(c, t);
        atomic_fetch_add(&c->rays, n);
        return NULL;
}

static void raw_frame(struct raw *c, int threads)
{
        pthread_t th[16];
        int n = 0;

        atomic_store(&c->next, 0);
        for (int i = 1; i < threads && i < 16; i++)
                if (pthread_create(&th[n], NULL, raw_worker, c) == 0)
                        n++;
        raw_worker(c);
        for (int i = 0; i < n; i++)
                pthread_join(th[i], NULL);
}

static void raw_setup(struct raw *c, const struct sim_scene *s, const struct gn_pose *st)
{
        struct sim_cam_geom g;
        double lamp[3];

        sim_camera_geom(s, st, 0, &g);
        sim_lamp_position(s, st, 0, lamp);
        c->s = s;
        for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                        c->M[i * 3 + j] = (float)g.R[j * 3 + i];
        c->org = v3(-(float)(g.R[0] * g.t[0] + g.R[3] * g.t[1] + g.R[6] * g.t[2]),
                    -(float)(g.R[1] * g.t[0] + g.R[4] * g.t[1] + g.R[7] * g.t[2]),
                    -(float)(g.R[2] * g.t[0] + g.R[5] * g.t[1] + g.R[8] * g.t[2]));
        c->lamp = v3((float)lamp[0], (float)lamp[1], (float)lamp[2]);
        c->w = g.width;
        c->h = g.height;
        c->tiles_x = (c->w + 3) / 4;
        c->n_tiles = c->tiles_x * ((c->h + 3) / 4);
}

static int load(struct rig_config **rc, struct sim_scene **s)
{
        char path[] = "/tmp/gonio-bench-render-XXXXXX.yaml", err[512];
        int fd = mkstemps(path, 5), r;
        FILE *f = fd >= 0 ? fdopen(fd, "w") : NULL;

        if (!f)
                return -1;
        fputs(rig, f);
        fclose(f);
        r = rigconf_load(path, registry_backends, rc, err, sizeof(err));
        if (r >= 0)
                r = sim_scene_new(*rc, s, err, sizeof(err));
        unlink(path);
        if (r < 0)
                fprintf(stderr, "bench/render: %s\n", err);
        return r;
}

int main(int argc, char **argv)
{
        struct rig_config *rc = NULL;
        struct sim_scene *s = NULL;
        struct gn_pose st = {.deg[GN_ROLE_TURNTABLE] = 10, .lamps = 1, .lasers = 1};
        struct raw raw = {0};
        double secs = argc > 1 ? atof(argv[1]) : 3, t0, fps, raw_fps, t_render = 0, t_raw = 0;
        int frames = 0, raw_frames = 0;

        if (load(&rc, &s) < 0)
                return 1;
        raw_setup(&raw, s, &st);
        /* alternate short blocks of both, so a change in machine load hits both alike */
        for (double start = now(); now() - start < 2 * secs;) {
                for (t0 = now(); now() - t0 < 0.25; frames++) {
                        struct gn_frame f;
                        if (sim_render(s, &st, 0, NULL, frames, &f, 0, NULL) < 0)
                                return 1;
                        gn_frame_free_data(&f);
                }
                t_render += now() - t0;
                for (t0 = now(); now() - t0 < 0.25; raw_frames++)
                        raw_frame(&raw, s->threads);
                t_raw += now() - t0;
        }
        fps = frames / t_render;
        raw_fps = raw_frames / t_raw;
        printf("render: %d frames 720x480, %zu triangles, %d threads: %.1f fps\n", frames,
               s->geoms[0].mesh.nt, s->threads, fps);
        printf("raw embree: %.2f Mrays/s (%.0f rays/frame): %.1f frames/s\n",
               atomic_load(&raw.rays) / t_raw / 1e6, (double)atomic_load(&raw.rays) / raw_frames,
               raw_fps);
        printf("{\"bench\":\"render\",\"fps\":%.2f,\"raw_ray_fps\":%.2f,\"ratio\":%.3f}\n", fps,
               raw_fps, fps / raw_fps);
        sim_scene_free(s);
        rigconf_free(rc);
        return 0;
}
