/* lltest.c - the rendered scene of the laser line tests and bench (see lltest.h). */
#include <math.h>
#include <stdio.h>

#include "lltest.h"

#define PLATE_X 30.0 /* the plate faces +x at x = 30, z from 10 to 100, y from -45 to 45 */

static const char cams_fmt[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 10, distance: 350, azimuth: 25,\n"
        "      target: [30, -20, 55], width: %d, height: %d, fx: %g, fy: %g,\n"
        "      distortion: [-0.12, 0.06, 0.0008, -0.0005, 0], exposure_us: 20000 }\n";
static const char laser_fmt[] =
        "laser: { name: laser, modbus-coil: { bus: relays, coil: 7 }, azimuth: 0,\n"
        "         origin: [600, 0, 60], width: 0.5, power: %g, channel: red }\n";
static const char lamp_fmt[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 30,\n"
        "      radius: 450, azimuth: -20, intensity: %g }\n";
/* the ball sits on the camera's line of sight to the laser line, 31 mm off the laser plane */
static const char scene[] =
        "scene:\n"
        "  seed: 3\n"
        "  object: { shape: sphere, size: 12, material: { albedo: 0.6 },\n"
        "            pose: { translate: [123.7, 37.7, 65.7] } }\n"
        "  targets:\n"
        "    - { type: chessboard, squares: [6, 6], square: 15, margin: 0, white: 0.8,\n"
        "        black: 0.8, pose: { translate: [30, -45, 100], rotate_x: -90, rotate_z: 90 } }\n"
        "  turntable: { radius: 0 }\n"
        "  sensor: { black_level: 0.02 }\n";

/* The analytic image of (PLATE_X, 0, z) crossing row v, z in [0, 110]: bisection. */
static bool line_at_row(const struct sim_cam_geom *g, double v, double *u, double *z)
{
        double lo = 0, hi = 110, uv_lo[2], uv_hi[2], uv[2] = {NAN, NAN}, m = 0;

        CHECK_INT(sim_cam_project(g, (double[3]){PLATE_X, 0, lo}, uv_lo), 0);
        CHECK_INT(sim_cam_project(g, (double[3]){PLATE_X, 0, hi}, uv_hi), 0);
        if ((uv_lo[1] - v) * (uv_hi[1] - v) > 0)
                return false;
        for (int it = 0; it < 60; it++) {
                m = (lo + hi) / 2;
                CHECK_INT(sim_cam_project(g, (double[3]){PLATE_X, 0, m}, uv), 0);
                if ((uv[1] - v) * (uv_lo[1] - v) > 0)
                        lo = m;
                else
                        hi = m;
        }
        *u = uv[0];
        *z = m;
        return true;
}

/* How many of the pixels u0-k..u0+k of row v see the plate (the rest see the ball or nothing). */
static int plate_hits(const struct sim_truth *tr, int v, int u0, int k)
{
        int n = 0;

        for (int u = u0 - k; u <= u0 + k; u++)
                n += u >= 0 && u < tr->width &&
                     fabsf(tr->point[3 * ((size_t)v * tr->width + u)] - (float)PLATE_X) < 0.3f;
        return n;
}

static void classify(struct llscene *s, const struct sim_truth *tr)
{
        struct gn_pose st = {.lasers = 1};
        struct sim_cam_geom g;
        int k = (int)lround(6.0 * s->w / 640); /* px: the line's reach (4 sigma) at this scale */

        CHECK_INT(sim_camera_geom(s->t.s, &st, 0, &g), 0);
        for (int v = 0; v < s->h; v++) {
                double u, z;
                int hits;

                s->u[v] = NAN;
                s->row[v] = LL_GAP;
                if (!line_at_row(&g, v, &u, &z))
                        continue;
                if (z < 9 || z > 101) /* beyond the plate's edges, with a margin */
                        continue;
                s->u[v] = u;
                hits = plate_hits(tr, v, (int)lround(u), k);
                if (z < 11 || z > 99 || (hits > 0 && hits < 2 * k + 1))
                        s->row[v] = LL_EDGE;
                else if (hits == 2 * k + 1)
                        s->row[v] = LL_VISIBLE;
        }
}

void ll_open(struct llscene *s, int w, int h, double laser_power, double lamp_intensity)
{
        char cams[512], laser[256], lamps[256] = "";
        struct gn_pose st = {.lasers = 1};
        struct sim_expose ex = {.bits = 8};
        struct sim_truth tr = {0};
        struct gn_frame f;

        snprintf(cams, sizeof(cams), cams_fmt, w, h, 1.4 * w, 1.4 * w);
        snprintf(laser, sizeof(laser), laser_fmt, laser_power);
        if (lamp_intensity > 0)
                snprintf(lamps, sizeof(lamps), lamp_fmt, lamp_intensity);
        rt_open(&s->t, lamps, laser, cams, scene);
        s->w = w;
        s->h = h;
        s->u = calloc(h, sizeof(*s->u));
        s->row = calloc(h, sizeof(*s->row));
        CHECK(s->u && s->row);
        rt_render(&s->t, &st, &ex, 0, &f, SIM_TRUTH_POINT, &tr);
        classify(s, &tr);
        sim_truth_free(&tr);
        gn_frame_free_data(&f);
}

void ll_close(struct llscene *s)
{
        rt_close(&s->t);
        free(s->u);
        free(s->row);
}

void ll_render(struct llscene *s, bool laser, bool lamp, int bits, uint64_t seq, struct gn_frame *f)
{
        struct gn_pose st = {.lasers = laser, .lamps = lamp ? 1 : 0};
        struct sim_expose ex = {.bits = bits};

        rt_render(&s->t, &st, &ex, seq, f, 0, NULL);
}

double ll_score(const struct llscene *s, const struct laserline_result *r, int *visible,
                int *missed, int *spurious)
{
        double sum = 0;
        int n = 0;

        *visible = *missed = *spurious = 0;
        for (int v = 0; v < s->h && v < r->n; v++) {
                double c = r->centre[v];
                if (s->row[v] == LL_GAP && !isnan(c))
                        (*spurious)++;
                if (s->row[v] != LL_VISIBLE)
                        continue;
                (*visible)++;
                if (isnan(c))
                        (*missed)++;
                else if (fabs(c - s->u[v]) > 1)
                        (*spurious)++;
                else {
                        sum += (c - s->u[v]) * (c - s->u[v]);
                        n++;
                }
        }
        return n ? sqrt(sum / n) : NAN;
}
