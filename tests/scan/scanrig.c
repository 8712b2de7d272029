/* scanrig.c - helpers of the scan tests (see scanrig.h). */
#include <math.h>
#include <stdio.h>

#include "calib/scan.h"
#include "scanrig.h"

static const char lamps_yaml[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 40, "
        "radius: 400, azimuth: 20, intensity: 2.0e5 }\n";
static const char laser_yaml[] =
        "laser: { name: laser, modbus-coil: { bus: relays, coil: 7 }, azimuth: 0,\n"
        "         origin: [500, 0, 60], width: 0.5, power: 1.2e3, channel: red }\n";
static const char cams_fmt[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: %g, distance: 380, azimuth: 30,\n"
        "      target: [0, 0, %g], width: %d, height: %d, fx: %d, fy: %d,\n"
        "      distortion: [-0.25, 0.12, 0.001, -0.0008, 0], exposure_us: 20000 }\n";
static const char scene_fmt[] = "scene:\n"
                                "  seed: 5\n"
                                "  object: %s\n"
                                "  turntable: { radius: 0 }\n"
                                "  sensor: { black_level: 0.02 }\n";

void st_open(struct rtest *t, const char *object, double elevation_deg, double target_z)
{
        char cams[512], scene[1024];

        snprintf(cams, sizeof(cams), cams_fmt, elevation_deg, target_z, ST_W, ST_H, 17 * ST_W / 10,
                 17 * ST_W / 10);
        snprintf(scene, sizeof(scene), scene_fmt, object);
        rt_open(t, lamps_yaml, laser_yaml, cams, scene);
}

void st_render(struct rtest *t, double deg, bool laser, uint32_t lamps, uint64_t seq,
               struct gn_frame *f)
{
        struct gn_pose st = {.lasers = laser, .lamps = lamps};
        struct sim_expose ex = {.bits = 8};

        for (int k = 0; k < GN_ROLE_COUNT; k++)
                st.deg[k] = NAN;
        st.deg[GN_ROLE_TURNTABLE] = deg;
        rt_render(t, &st, &ex, seq, f, 0, NULL);
}

void st_scan(struct rtest *t, int n, struct sec_ctx *c)
{
        struct scan_calib cal;
        struct laserline_opts o;
        float centre[ST_H];
        struct laserline_result r = {.centre = centre, .n = ST_H};

        CHECK_INT(scan_nominal_calib(t->rc, "c0", NAN, &cal), 0);
        CHECK_INT(sec_init(c, &cal.cam), 0);
        CHECK_INT(sec_add_laser(c, cal.plane_p[0], cal.plane_n[0]), 0);
        laserline_opts_default(&o, t->rc->lasers[0].laser_channel);
        for (int i = 0; i < n; i++) {
                double deg = 360.0 * i / n;
                struct gn_frame on, off, lamp;
                st_render(t, deg, true, 0, 3 * (uint64_t)i, &on);
                st_render(t, deg, false, 0, 3 * (uint64_t)i + 1, &off);
                st_render(t, deg, false, 1, 3 * (uint64_t)i + 2, &lamp);
                CHECK(laserline_extract(&on, &off, &o, &r) >= 0);
                CHECK(sec_add_line(c, 0, deg, &r, false, &lamp) >= 0);
                gn_frame_free_data(&on);
                gn_frame_free_data(&off);
                gn_frame_free_data(&lamp);
        }
}

double st_sphere_dist(const float x[3])
{
        return hypot(hypot(x[0], x[1]), x[2] - 50.0) - 50.0;
}
