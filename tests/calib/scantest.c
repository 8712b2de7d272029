/* scantest.c - scans of 100 mm objects scored against the renderer's truth (scantest.h). */
#include <math.h>
#include <stdio.h>

#include "common/cleanup.h"
#include "common/riggeom.h"
#include "scantest.h"

#define DEG (M_PI / 180)

static const char cams_fmt[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: %g, distance: 380, azimuth: 30,\n"
        "      target: [0, 0, %g], width: %d, height: %d, fx: %g, fy: %g,\n"
        "      distortion: [-0.25, 0.12, 0.001, -0.0008, 0], exposure_us: 20000 }\n";
static const char laser_fmt[] =
        "laser: { name: laser, modbus-coil: { bus: relays, coil: 7 }, azimuth: %g,\n"
        "         origin: [%g, %g, %g], width: 0.5, power: 1.2e3, channel: red }\n";
static const char scene_fmt[] = "scene:\n"
                                "  seed: 5\n"
                                "  object: { shape: %s, size: 100, material: { albedo: 0.6 } }\n"
                                "  turntable: { radius: 0 }\n"
                                "  sensor: { black_level: 0.02 }\n";

void scan_camera_yaml(char *buf, size_t len, double elevation, double target_z)
{
        snprintf(buf, len, cams_fmt, elevation, target_z, SCAN_W, SCAN_H, 1.7 * SCAN_W,
                 1.7 * SCAN_W);
}

void scan_laser_yaml(char *buf, size_t len, double az, double target_z)
{
        double r = target_z < 10 ? 250 : 500, h = target_z < 10 ? 400 : 60;

        snprintf(buf, len, laser_fmt, az, r * cos(az * DEG), r * sin(az * DEG), h);
}

void scan_rigs(struct scan *s, const char *shape, double elevation, double target_z,
               const double *az, int n, int angles)
{
        char cams[512], scene[256], laser[256];

        CHECK(n <= SCAN_MAX_LASERS);
        memset(s, 0, sizeof(*s));
        s->angles = angles;
        scan_camera_yaml(cams, sizeof(cams), elevation, target_z);
        snprintf(scene, sizeof(scene), scene_fmt, shape);
        for (int i = 0; i < n; i++) {
                scan_laser_yaml(laser, sizeof(laser), az[i], target_z);
                rt_open(&s->t[s->lasers++], "", laser, cams, scene);
        }
        if (strcmp(shape, "sphere") != 0) {
                struct sim_mesh m;
                CHECK_INT(sim_object_mesh(s->t[0].s, 0, &m), 0);
                md_open(&s->md, m, 2.0);
        }
}

void scan_start(struct scan *s, const struct sec_camera *cam, const double (*p)[3],
                const double (*n)[3])
{
        static const double id[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};

        memcpy(s->T, id, sizeof(id));
        CHECK_INT(sec_init(&s->c, cam), 0);
        for (int i = 0; i < s->lasers; i++)
                CHECK_INT(sec_add_laser(&s->c, p[i], n[i]), i);
}

void scan_open(struct scan *s, const char *shape, double elevation, double target_z,
               const double *az, int n, int angles)
{
        struct sec_camera cam = {.width = SCAN_W, .height = SCAN_H};
        const struct rig_camera_conf *cc;
        double p[SCAN_MAX_LASERS][3], nv[SCAN_MAX_LASERS][3];

        scan_rigs(s, shape, elevation, target_z, az, n, angles);
        cc = &s->t[0].rc->cameras[0];
        cam.k = (struct cal_intrinsics){.fx = cc->fx, .fy = cc->fy, .cx = cc->cx, .cy = cc->cy};
        memcpy(cam.k.dist, cc->dist, sizeof(cam.k.dist));
        riggeom_camera_pose(cc, 0, cam.R, cam.t);
        for (int i = 0; i < n; i++)
                sec_rig_laser_plane(s->t[i].rc->lasers[0].laser_azimuth_deg, p[i], nv[i]);
        scan_start(s, &cam, p, nv);
}

void scan_close(struct scan *s)
{
        free(s->truth);
        md_close(&s->md);
        sec_free(&s->c);
        for (int i = 0; i < s->lasers; i++)
                rt_close(&s->t[i]);
}

/* Renders laser l on and off at turntable angle deg, extracts and triangulates the line. */
static void scan_line(struct scan *s, int l, double deg, uint64_t seq)
{
        struct gn_pose st = {.lasers = 1};
        struct sim_expose ex = {.bits = 8};
        struct laserline_opts o;
        float centre[SCAN_H];
        struct laserline_result r = {.centre = centre, .n = SCAN_H};
        struct gn_frame on, off;

        laserline_opts_default(&o, 0);
        for (int k = 0; k < GN_ROLE_COUNT; k++)
                st.deg[k] = NAN;
        st.deg[GN_ROLE_TURNTABLE] = deg;
        rt_render(&s->t[l], &st, &ex, 2 * seq, &on, 0, NULL);
        st.lasers = 0;
        rt_render(&s->t[l], &st, &ex, 2 * seq + 1, &off, 0, NULL);
        CHECK(laserline_extract(&on, &off, &o, &r) >= 0);
        CHECK(sec_add_line(&s->c, l, deg, &r, false, &on) >= 0);
        gn_frame_free_data(&on);
        gn_frame_free_data(&off);
}

/* Point p moved by T into the renderer's object frame. */
static struct sec_point scan_to_truth(const double T[12], const struct sec_point *p)
{
        struct sec_point q = *p;

        for (int k = 0; k < 3; k++)
                q.x[k] = (float)(T[3 * k] * p->x[0] + T[3 * k + 1] * p->x[1] +
                                 T[3 * k + 2] * p->x[2] + T[9 + k]);
        return q;
}

/* Adds distance d to sc and *sum (the squares); NAN is not scored. */
static void score_add(struct score *sc, double *sum, double d)
{
        if (isnan(d))
                return;
        *sum += d * d;
        sc->bias += d;
        sc->worst = fmax(sc->worst, fabs(d));
        sc->far += fabs(d) > SCAN_FAR_MM;
        sc->scored++;
}

static void score_end(struct score *sc, double sum)
{
        sc->rms = sc->scored ? sqrt(sum / sc->scored) : NAN;
        sc->bias = sc->scored ? sc->bias / sc->scored : NAN;
}

/* Distance of point i (through T) from its kept true plane; NAN when not scored. */
static double truth_dist(const struct scan *s, size_t i)
{
        struct sec_point q = scan_to_truth(s->T, &s->c.pts[i]);
        const double *pl = s->truth[i];

        return pl[0] * q.x[0] + pl[1] * q.x[1] + pl[2] * q.x[2] + pl[3];
}

/* Scans s->angles angles with laser l, keeping each new point's true plane (fn). */
static struct score scan_score(struct scan *s, int l, truth_fn fn)
{
        struct score sc = {0};
        double sum = 0;
        int n = s->angles;

        for (int i = 0; i < n; i++) {
                size_t first = s->c.n_pts;

                scan_line(s, l, 360.0 * i / n, (uint64_t)(l * n + i));
                s->truth = realloc(s->truth, (s->c.n_pts + 1) * sizeof(*s->truth));
                CHECK(s->truth);
                for (size_t j = first; j < s->c.n_pts; j++) {
                        struct sec_point q = scan_to_truth(s->T, &s->c.pts[j]);
                        if (!fn(s, &q, s->truth[j]))
                                s->truth[j][0] = s->truth[j][1] = s->truth[j][2] = s->truth[j][3] =
                                        NAN;
                        score_add(&sc, &sum, truth_dist(s, j));
                }
        }
        score_end(&sc, sum);
        return sc;
}

struct score scan_rescore(const struct scan *s, int l, const char *label)
{
        struct score sc = {0};
        double sum = 0;

        for (size_t i = 0; i < s->c.n_pts; i++)
                if (s->c.pts[i].laser == l)
                        score_add(&sc, &sum, truth_dist(s, i));
        score_end(&sc, sum);
        fprintf(stderr, "%s, laser %d: %d scored, RMS %.4f mm, worst %.4f mm, mean %+.4f mm\n",
                label, l, sc.scored, sc.rms, sc.worst, sc.bias);
        return sc;
}

bool scan_sphere_dist(const struct scan *s, const struct sec_point *p, double pl[4])
{
        double r = hypot(hypot(p->x[0], p->x[1]), p->x[2] - 50.0);

        (void)s;
        pl[0] = p->x[0] / r;
        pl[1] = p->x[1] / r;
        pl[2] = (p->x[2] - 50.0) / r;
        pl[3] = -(pl[2] * 50.0 + 50.0); /* through (0, 0, 50) + 50 n */
        return true;
}

bool scan_mesh_dist(const struct scan *s, const struct sec_point *p, double pl[4])
{
        double x[3] = {p->x[0], p->x[1], p->x[2]}, c[3], n[3], d = md_closest(&s->md, x, c, n);

        if (!isfinite(d))
                return false;
        if (d > 1e-9) { /* off a face's interior (an edge, a vertex): along the way to p */
                double side = (x[0] - c[0]) * n[0] + (x[1] - c[1]) * n[1] + (x[2] - c[2]) * n[2];
                for (int k = 0; k < 3; k++)
                        n[k] = (side < 0 ? -1 : 1) * (x[k] - c[k]) / d;
        }
        memcpy(pl, n, sizeof(n));
        pl[3] = -(n[0] * c[0] + n[1] * c[1] + n[2] * c[2]);
        return true;
}

struct score scan_expect(struct scan *s, int l, const char *shape, truth_fn fn, int min_points,
                         double rms_max)
{
        size_t before = s->c.n_pts;
        struct score sc = scan_score(s, l, fn);

        fprintf(stderr,
                "%s, laser %d: %zu points over %d angles, %d scored, RMS %.4f mm, worst %.4f mm, "
                "%d beyond %.1f mm, mean %+.4f mm; so far %zu rejected rays, %zu centres not "
                "vouched for\n",
                shape, l, s->c.n_pts - before, s->angles, sc.scored, sc.rms, sc.worst, sc.far,
                SCAN_FAR_MM, sc.bias, s->c.rejected, s->c.unvouched);
        CHECK(sc.scored >= min_points);
        CHECK(sc.rms <= rms_max);
        CHECK(sc.worst <= SCAN_WORST_MM);
        CHECK(sc.far <= SCAN_FAR_SHARE * sc.scored);
        return sc;
}
