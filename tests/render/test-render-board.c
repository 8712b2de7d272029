/* test-render-board.c - calibration boards are drawn where the geometry says, to within
 * 0.03 px: the edges between chessboard squares, located in the image by their exact
 * area coverage along rows and columns (model-free for a box-filtered step), against the
 * board edges projected with the target pose and the camera model (with distortion). */
#include <math.h>

#include "rtest.h"

#define SQ 30.0

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 20, "
        "radius: 900, azimuth: -5, intensity: 4.0e6 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 25, distance: 420, azimuth: 0,\n"
        "      target: [0, 0, 60], width: 320, height: 240, fx: 380, fy: 376, cx: 161.2,\n"
        "      cy: 118.9, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 "
        "}\n";
static const char scene[] =
        "scene:\n"
        "  targets:\n"
        "    - { type: chessboard, squares: [6, 5], square: 30,\n"
        "        pose: { translate: [20, -90, 165], rotate_x: -90, rotate_z: 90, rotate_y: 8 } }\n"
        "  turntable: { radius: 0 }\n"
        "  sensor: { response: 2.0e6, full_well: 1.0e5 }\n";

/* Pixel of board point (x, y). */
static void board_px(struct rtest *t, const struct gn_pose *st, double x, double y, double uv[2])
{
        struct sim_cam_geom g;
        double R[9], tt[3], w[3];

        CHECK_INT(sim_target_pose(t->s, st, 0, R, tt), 0);
        CHECK_INT(sim_camera_geom(t->s, st, 0, &g), 0);
        for (int i = 0; i < 3; i++)
                w[i] = R[i * 3] * x + R[i * 3 + 1] * y + tt[i];
        CHECK_INT(sim_cam_project(&g, w, uv), 0);
}

/* Where the board line {axis = c} crosses image line {other image coordinate = at}. */
static double crossing(struct rtest *t, const struct gn_pose *st, int vertical, double c, double lo,
                       double hi, double at)
{
        double uv[2], m = 0, flo;

        board_px(t, st, vertical ? c : lo, vertical ? lo : c, uv);
        flo = uv[vertical] - at;
        for (int it = 0; it < 60; it++) {
                m = (lo + hi) / 2;
                board_px(t, st, vertical ? c : m, vertical ? m : c, uv);
                if ((uv[vertical] - at) * flo > 0)
                        lo = m;
                else
                        hi = m;
        }
        return uv[!vertical];
}

/* Sample along the scan line: x runs across the edge, at is the fixed coordinate. */
static double sample(const struct gn_frame *f, int vertical, int x, int at)
{
        return vertical ? rt_px(f, x, at, 1) : rt_px(f, at, x, 1);
}

/* Edge position from the coverage of pixels [e-3, e+3] between the levels at e -+ 5. */
static double measured_edge(const struct gn_frame *f, int vertical, double e, int at)
{
        int c = (int)lround(e);
        double lo = sample(f, vertical, c - 5, at), hi = sample(f, vertical, c + 5, at), sum = 0;

        for (int x = c - 3; x <= c + 3; x++)
                sum += (sample(f, vertical, x, at) - lo) / (hi - lo);
        return c + 3.5 - sum; /* the brighter side is at larger x */
}

static void scan(struct rtest *t, const struct gn_pose *st, const struct gn_frame *f, int vertical,
                 double *worst, int *n)
{
        int nlines = vertical ? 5 : 4, nrun = vertical ? 5 : 6,
            len = vertical ? f->height : f->width;

        for (int k = 1; k <= nlines; k++)
                for (int at = 0; at < len; at++) {
                        double uv0[2], uv1[2], e;
                        int run = -1;
                        /* which square run does this scan line cross, well inside it? */
                        for (int j = 0; j < nrun && run < 0; j++) {
                                board_px(t, st, vertical ? k * SQ : (j + 0.3) * SQ,
                                         vertical ? (j + 0.3) * SQ : k * SQ, uv0);
                                board_px(t, st, vertical ? k * SQ : (j + 0.7) * SQ,
                                         vertical ? (j + 0.7) * SQ : k * SQ, uv1);
                                if ((uv0[vertical] - at) * (uv1[vertical] - at) < 0)
                                        run = j;
                        }
                        if (run < 0)
                                continue;
                        e = crossing(t, st, vertical, k * SQ, (run + 0.3) * SQ, (run + 0.7) * SQ,
                                     at);
                        double lo = sample(f, vertical, (int)lround(e) - 5, at);
                        double hi = sample(f, vertical, (int)lround(e) + 5, at);
                        if (hi < lo)
                                continue; /* the dark side on the right: the other parity */
                        double m = measured_edge(f, vertical, e, at);
                        CHECK_NEAR(m, e, 0.03);
                        *worst = fmax(*worst, fabs(m - e));
                        (*n)++;
                }
}

int main(void)
{
        struct rtest t;
        struct gn_pose st = {.deg[GN_ROLE_TURNTABLE] = 12, .lamps = 1};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct gn_frame f;
        double worst = 0;
        int n = 0;

        rt_open(&t, lamps, "", cams, scene);
        rt_render(&t, &st, &ex, 0, &f, 0, NULL);
        scan(&t, &st, &f, 1, &worst, &n);
        scan(&t, &st, &f, 0, &worst, &n);
        fprintf(stderr, "board edges: %d crossings, worst %.4f px\n", n, worst);
        CHECK(n > 200);
        gn_frame_free_data(&f);
        rt_close(&t);
        return 0;
}
