/* test-render-lasers.c - two lasers, each rendered alone or together on its own plane, with
 * its own colour channel: laser 0 (azimuth 0: the plane y = 0, red) and laser 1 (azimuth 90:
 * the plane x = 0, green) cross a level plate at z = 40 in two lines through the axis. Along
 * each line, where the camera projects points of it, that laser's channel is lit when (and
 * only when) it is on, and the other channel is dark away from the axis; the reported
 * planes are the rig file's. */
#include <math.h>
#include <stdbool.h>

#include "common/cleanup.h"
#include "rtest.h"

#define PLATE_Z 40.0
#define LIT     1000.0 /* a lit line's peak, far above the unlit plate's 0 */

static const char lasers[] =
        "lasers:\n"
        "  - { name: east, modbus-coil: { bus: relays, coil: 7 }, azimuth: 0,\n"
        "      origin: [300, 0, 200], width: 0.5, power: 2.0e3, channel: red }\n"
        "  - { name: north, modbus-coil: { bus: relays, coil: 8 }, azimuth: 90,\n"
        "      origin: [0, 300, 200], width: 0.5, power: 2.0e3, channel: green }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 60, distance: 300, azimuth: 225,\n"
        "      target: [0, 0, 40], width: 240, height: 240, fx: 400, fy: 400,\n"
        "      exposure_us: 20000 }\n";
/* a uniform plate (a board with equal squares) level at z = 40 over [-45, 45]^2 */
static const char scene[] =
        "scene:\n"
        "  object: { shape: sphere, size: 1, pose: { translate: [0, 0, -500] } }\n"
        "  targets:\n"
        "    - { type: chessboard, squares: [6, 6], square: 15, margin: 0, white: 0.8,\n"
        "        black: 0.8, pose: { translate: [-45, -45, 40] } }\n"
        "  turntable: { radius: 0 }\n"
        "  sensor: { response: 2.0e6, full_well: 1.0e5, read_noise: 0 }\n";

/* The brightest sample of channel ch within 2 px of where the camera sees world point p. */
static double peak_at(const struct gn_frame *f, const struct sim_cam_geom *g, const double p[3],
                      int ch)
{
        double uv[2], peak = 0;

        CHECK_INT(sim_cam_project(g, p, uv), 0);
        for (int v = (int)lround(uv[1]) - 2; v <= (int)lround(uv[1]) + 2; v++)
                for (int u = (int)lround(uv[0]) - 2; u <= (int)lround(uv[0]) + 2; u++)
                        if (u >= 0 && v >= 0 && u < f->width && v < f->height)
                                peak = fmax(peak, rt_px(f, u, v, ch));
        return peak;
}

/* Renders with the lasers of bit set lit and checks both lines at 5..40 mm from the axis. */
static void check_lit(struct rtest *t, uint32_t lit)
{
        struct gn_pose st = {.lasers = lit};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct sim_cam_geom g;
        struct gn_frame f;
        int seen[2] = {0, 0};

        CHECK_INT(sim_camera_geom(t->s, &st, 0, &g), 0);
        rt_render(t, &st, &ex, 0, &f, 0, NULL);
        rt_dump(&f, lit == 3 ? "lasers-both" : lit == 1 ? "lasers-east" : "lasers-north");
        for (double r = -40; r <= 40; r += 5) {
                double east[3] = {r, 0, PLATE_Z}, north[3] = {0, r, PLATE_Z};

                if (fabs(r) < 5)
                        continue; /* near the axis the lines cross */
                /* each laser's line in its own channel exactly when it is on */
                CHECK((peak_at(&f, &g, east, 0) > LIT) == ((lit & 1) != 0));
                CHECK((peak_at(&f, &g, north, 1) > LIT) == ((lit & 2) != 0));
                /* and never in the other's channel */
                CHECK(peak_at(&f, &g, east, 1) == 0 && peak_at(&f, &g, north, 0) == 0);
                seen[0] += peak_at(&f, &g, east, 0) > LIT;
                seen[1] += peak_at(&f, &g, north, 1) > LIT;
        }
        fprintf(stderr, "lasers 0x%x: east line lit at %d points, north at %d\n", lit, seen[0],
                seen[1]);
        gn_frame_free_data(&f);
}

int main(void)
{
        struct rtest t;
        double n[3], d;

        rt_open(&t, "", lasers, cams, scene);
        CHECK_INT(sim_laser_plane(t.s, 0, n, &d), 0);
        CHECK(fabs(n[0]) < 1e-12 && fabs(n[1] - 1) < 1e-12 && d == 0);
        CHECK_INT(sim_laser_plane(t.s, 1, n, &d), 0);
        CHECK(fabs(n[0] + 1) < 1e-12 && fabs(n[1]) < 1e-12 && d == 0);
        CHECK_INT(sim_laser_plane(t.s, 2, n, &d), -ENOENT);
        check_lit(&t, 1);
        check_lit(&t, 2);
        check_lit(&t, 3);
        check_lit(&t, 0);
        rt_close(&t);
        return 0;
}
