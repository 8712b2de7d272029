/* test-render-laser.c - the laser line: its centre in the image, row by row, within
 * 0.02 px of the analytic intersection of the laser plane with a plate, projected by the
 * Brown-Conrady model written out here (not sim/render's); the camera has strong
 * distortion and sees the line far from its principal point, where the undistorted
 * projection is more than a pixel away (checked); the laser plane as reported; its shadow
 * behind an occluding sphere where the geometry puts it. */
#include <math.h>
#include <stdbool.h>

#include "common/cleanup.h"
#include "rtest.h"

#define PLATE_X  30.0
#define LINE_TOL 0.02 /* px: the line centre against the analytic one */
#define DIST_MIN 1.0  /* px: least shift distortion gives a checked row (50 x LINE_TOL) */

static const char laser[] =
        "laser: { name: laser, modbus-coil: { bus: relays, coil: 7 }, azimuth: 0,\n"
        "         origin: [600, 0, 60], width: 0.5, power: 2.0e3, channel: red }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 10, distance: 350, azimuth: 25,\n"
        "      target: [30, -55, 50], width: 320, height: 240, fx: 700, fy: 700, cx: 161.3,\n"
        "      cy: 118.7, distortion: [-0.5, 0.3, 0.004, -0.003, -0.1],\n"
        "      exposure_us: 20000 }\n";
/* a uniform plate facing +x at x = 30 (a board with equal squares), a sphere occluder */
static const char scene[] =
        "scene:\n"
        "  object: { shape: sphere, size: 16, pose: { translate: [100, 0, 42] } }\n"
        "  targets:\n"
        "    - { type: chessboard, squares: [6, 6], square: 15, margin: 0, white: 0.8,\n"
        "        black: 0.8, pose: { translate: [30, -45, 100], rotate_x: -90, rotate_z: 90 } }\n"
        "  turntable: { radius: 0 }\n"
        "  sensor: { response: 2.0e6, full_well: 1.0e5, read_noise: 0 }\n";

/* Is the segment from the emitter to (PLATE_X, 0, z) blocked by the sphere (margin mm)? */
static int blocked(double z, double margin)
{
        double e[3] = {600, 0, 60}, q[3] = {PLATE_X, 0, z}, c[3] = {100, 0, 50};
        double d[3], w[3], dd = 0, wd = 0, s, dist2 = 0;

        for (int i = 0; i < 3; i++) {
                d[i] = q[i] - e[i];
                w[i] = c[i] - e[i];
                dd += d[i] * d[i];
                wd += w[i] * d[i];
        }
        s = wd / dd;
        for (int i = 0; i < 3; i++)
                dist2 += pow(w[i] - s * d[i], 2);
        return sqrt(dist2) < 8 - margin ? 1 : sqrt(dist2) > 8 + margin ? 0 : -1;
}

/* World point p to pixel: x_cam = R p + t, then Brown-Conrady (k1, k2, p1, p2, k3) as
 * OpenCV documents it (calib3d, "Detailed Description") when distorted, else the pinhole. */
static void project_ref(const struct sim_cam_geom *g, const double p[3], bool distorted,
                        double uv[2])
{
        const double *k = g->dist;
        double c[3], x, y, r2, rad, xd, yd;

        for (int i = 0; i < 3; i++)
                c[i] = g->R[3 * i] * p[0] + g->R[3 * i + 1] * p[1] + g->R[3 * i + 2] * p[2] +
                       g->t[i];
        x = c[0] / c[2];
        y = c[1] / c[2];
        r2 = x * x + y * y;
        rad = 1 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2;
        xd = distorted ? x * rad + 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x) : x;
        yd = distorted ? y * rad + k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y : y;
        uv[0] = g->fx * xd + g->cx;
        uv[1] = g->fy * yd + g->cy;
}

/* Analytic image of (PLATE_X, 0, z) crossing row v: bisection on z. */
static int line_at_row(const struct sim_cam_geom *g, bool distorted, double v, double *u, double *z)
{
        double lo = 10, hi = 100, uv_lo[2], uv_hi[2], uv[2], m = 0;

        project_ref(g, (double[3]){PLATE_X, 0, lo}, distorted, uv_lo);
        project_ref(g, (double[3]){PLATE_X, 0, hi}, distorted, uv_hi);
        if ((uv_lo[1] - v) * (uv_hi[1] - v) > 0)
                return 0;
        for (int it = 0; it < 80; it++) {
                m = (lo + hi) / 2;
                project_ref(g, (double[3]){PLATE_X, 0, m}, distorted, uv);
                if ((uv[1] - v) * (uv_lo[1] - v) > 0)
                        lo = m;
                else
                        hi = m;
        }
        *u = uv[0];
        *z = m;
        return 1;
}

static double centroid(const struct gn_frame *f, int v, int u0, double *peak)
{
        double s = 0, su = 0;

        *peak = 0;
        for (int u = MAX(u0 - 6, 0); u <= MIN(u0 + 6, f->width - 1); u++) {
                double x = rt_px(f, u, v, 0);
                s += x;
                su += x * u;
                *peak = fmax(*peak, x);
        }
        return s > 0 ? su / s : NAN;
}

int main(void)
{
        struct rtest t;
        struct gn_pose st = {.lasers = 1};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct sim_cam_geom g;
        struct gn_frame f;
        double n[3], d, worst = 0, least_shift = INFINITY;
        int rows = 0, shadowed = 0;

        rt_open(&t, "", laser, cams, scene);
        CHECK_INT(sim_laser_plane(t.s, 0, n, &d), 0);
        CHECK_NEAR(n[0], 0, 1e-12);
        CHECK_NEAR(n[1], 1, 1e-12);
        CHECK_NEAR(d, 0, 1e-12);
        CHECK_INT(sim_camera_geom(t.s, &st, 0, &g), 0);
        rt_render(&t, &st, &ex, 0, &f, 0, NULL);
        rt_dump(&f, "laser");
        for (int v = 0; v < f.height; v++) {
                double u, z, u0, z0, peak, c, uv[2];
                if (!line_at_row(&g, true, v, &u, &z) || z < 15 || z > 95)
                        continue;
                /* sim/render's own projection agrees with the one written out here */
                CHECK_INT(sim_cam_project(&g, (double[3]){PLATE_X, 0, z}, uv), 0);
                CHECK_NEAR(uv[0], u, 1e-6);
                CHECK_NEAR(uv[1], v, 1e-6);
                /* and an undistorted camera would put the line elsewhere */
                CHECK(line_at_row(&g, false, v, &u0, &z0));
                CHECK(fabs(u0 - u) > DIST_MIN);
                least_shift = fmin(least_shift, fabs(u0 - u));
                c = centroid(&f, v, (int)lround(u), &peak);
                if (blocked(z, 1.0) == 1) {
                        CHECK(peak < 1);
                        shadowed++;
                } else if (blocked(z, 1.0) == 0) {
                        CHECK(peak > 1000);
                        CHECK_NEAR(c, u, LINE_TOL);
                        worst = fmax(worst, fabs(c - u));
                        rows++;
                }
        }
        fprintf(stderr,
                "laser: %d rows, worst centre error %.4f px, %d rows shadowed, distortion "
                "shifts the line by >= %.2f px\n",
                rows, worst, shadowed, least_shift);
        CHECK(rows > 60 && shadowed > 5);
        /* the green and blue channels carry no laser light; laser off means no light */
        for (int v = 0; v < f.height; v++)
                for (int u = 0; u < f.width; u++)
                        CHECK(rt_px(&f, u, v, 1) == 0 && rt_px(&f, u, v, 2) == 0);
        gn_frame_free_data(&f);
        st.lasers = 0;
        rt_render(&t, &st, &ex, 0, &f, 0, NULL);
        for (int v = 0; v < f.height; v++)
                for (int u = 0; u < f.width; u++)
                        CHECK(rt_px(&f, u, v, 0) == 0);
        gn_frame_free_data(&f);
        rt_close(&t);
        return 0;
}
