/* test-section.c - calib/section.c and calib/ply.c against the renderer's ground truth: a
 * 100 mm sphere, gem and relief plate scanned at 90 turntable angles (laser on minus laser
 * off, noise on, a strong lens), the line extracted by calib/laserline.c and triangulated
 * with the true calibration from the rig file (intrinsics, riggeom_camera_pose, the laser's
 * plane). The RMS distance from the points to the true surface must be <= 0.05 mm (sphere:
 * analytic; gem and relief: the plane of the true object points around the line's pixel),
 * and no point farther than 6 RMS (or 0.1 mm). Also: two lasers in one cloud, undistortion
 * against the renderer's projection, the object frame, normals against the sphere's, colour,
 * and a PLY round trip. */
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <unistd.h>

#include "calib/ply.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "scantest.h"

#define W       SCAN_W
#define H       SCAN_H
#define ANGLES  90
#define RMS_MAX 0.05 /* mm */
#define DEG     (M_PI / 180)

/* Scans laser l of s with the true calibration and checks the distances. */
static struct score expect_score(struct scan *s, int l, const char *shape, truth_fn fn,
                                 int min_points)
{
        return scan_expect(s, l, shape, fn, min_points, RMS_MAX);
}

/* Scans shape with one laser at azimuth 0 and checks the distances; leaves s open. */
static void expect_shape(struct scan *s, const char *shape, double elevation, double target_z,
                         truth_fn fn, int min_points)
{
        scan_open(s, shape, elevation, target_z, (double[]){0}, 1, ANGLES);
        expect_score(s, 0, shape, fn, min_points);
}

/* The sphere's normals from the grid: within 2 degrees of the true ones on average. */
static void expect_sphere_normals(struct sec_ctx *c)
{
        size_t done = sec_normals(c), n = 0;
        double sum = 0;

        for (size_t i = 0; i < c->n_pts; i++) {
                const struct sec_point *p = &c->pts[i];
                double r[3] = {p->x[0], p->x[1], p->x[2] - 50.0};
                double len = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);

                if (p->n[0] == 0 && p->n[1] == 0 && p->n[2] == 0)
                        continue;
                sum += acos(fmin(1, (r[0] * p->n[0] + r[1] * p->n[1] + r[2] * p->n[2]) / len));
                n++;
        }
        fprintf(stderr, "normals: %zu of %zu points, mean error %.3f deg\n", done, c->n_pts,
                sum / n / DEG);
        CHECK(done == n && n > c->n_pts * 9 / 10);
        CHECK(sum / n / DEG < 2.0);
}

/* Reads the PLY written by ply_write_points back and compares it with the points. */
static void expect_ply(const struct sec_point *p, size_t n, const char *path)
{
        _cleanup_free_ char *buf = NULL;
        size_t len, count = 0;
        char *end, *b;

        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 1 << 30, (void **)&buf, &len), 0);
        end = strstr(buf, "end_header\n");
        CHECK(end);
        CHECK_STR_CONTAINS(buf, "format binary_little_endian 1.0\n");
        CHECK(sscanf(strstr(buf, "element vertex "), "element vertex %zu", &count) == 1);
        CHECK(count == n);
        b = end + strlen("end_header\n");
        CHECK(len == (size_t)(b - buf) + n * 27);
        for (size_t i = 0; i < n; i++, b += 27) {
                float f[6];
                memcpy(f, b, sizeof(f)); /* this host is little-endian (x86, arm64) */
                for (int k = 0; k < 3; k++) {
                        CHECK(f[k] == p[i].x[k] && f[3 + k] == p[i].n[k]);
                        CHECK((uint8_t)b[24 + k] == p[i].rgb[k]);
                }
        }
}

static void test_sphere(void)
{
        char dir[] = "/tmp/gonio-section-XXXXXX", path[64];
        struct scan s;
        size_t red = 0;

        expect_shape(&s, "sphere", 20, 50, scan_sphere_dist, ANGLES * 150);
        expect_sphere_normals(&s.c);
        for (size_t i = 0; i < s.c.n_pts; i++) /* the texture is the laser-on frame */
                red += s.c.pts[i].rgb[0] > 2 * s.c.pts[i].rgb[1] + 20;
        CHECK(red > s.c.n_pts * 9 / 10);
        CHECK(mkdtemp(dir));
        snprintf(path, sizeof(path), "%s/scan.ply", dir);
        CHECK_INT(ply_write_points(AT_FDCWD, path, s.c.pts, s.c.n_pts), 0);
        expect_ply(s.c.pts, s.c.n_pts, path);
        CHECK_INT(unlink(path), 0);
        CHECK_INT(rmdir(dir), 0);
        scan_close(&s);
}

static void test_gem(void)
{
        struct scan s;

        expect_shape(&s, "gem", 25, 30, scan_mesh_dist, ANGLES * 40);
        scan_close(&s);
}

static void test_relief(void)
{
        struct scan s;

        expect_shape(&s, "relief", 45, 5, scan_mesh_dist, ANGLES * 30);
        scan_close(&s);
}

/* Two lasers on either side of the camera, merged into one cloud: each within the RMS,
 * their mean distances to the surface within 0.1 mm of each other, and the normals found
 * from each laser's own lines. */
static void test_two_lasers(void)
{
        struct scan s;
        struct score a, b;
        size_t normals;

        scan_open(&s, "gem", 25, 30, (double[]){0, 70}, 2, ANGLES);
        a = expect_score(&s, 0, "gem", scan_mesh_dist, ANGLES * 40);
        b = expect_score(&s, 1, "gem", scan_mesh_dist, ANGLES * 40);
        CHECK(fabs(a.bias - b.bias) <= 0.1);
        normals = sec_normals(&s.c);
        fprintf(stderr, "two lasers: %zu points, %zu with a normal\n", s.c.n_pts, normals);
        CHECK(normals > s.c.n_pts * 8 / 10);
        scan_close(&s);
}

/* Undistortion inverts the forward model (the renderer's, as cv::projectPoints) to 1e-6 px
 * over the whole image of a strong lens. */
static void test_undistort(void)
{
        struct sim_cam_geom g = {.width = W,
                                 .height = H,
                                 .fx = 1100,
                                 .fy = 1105,
                                 .cx = 401,
                                 .cy = 298,
                                 .dist = {-0.25, 0.12, 0.001, -0.0008, -0.02},
                                 .R = {1, 0, 0, 0, 1, 0, 0, 0, 1}};
        struct cal_intrinsics k = {.fx = g.fx, .fy = g.fy, .cx = g.cx, .cy = g.cy};
        double worst = 0;

        memcpy(k.dist, g.dist, sizeof(k.dist));
        for (int v = 0; v <= H; v += 25)
                for (int u = 0; u <= W; u += 25) {
                        double xy[2], uv[2];
                        CHECK_INT(sec_undistort(&k, u, v, xy), 0);
                        CHECK_INT(sim_cam_project(&g, (double[3]){xy[0], xy[1], 1}, uv), 0);
                        worst = fmax(worst, hypot(uv[0] - u, uv[1] - v));
                }
        fprintf(stderr, "undistort: worst %.2e px\n", worst);
        CHECK(worst < 1e-6);
}

/* Bad arguments: -EINVAL, -ENOSPC, and a ray that grazes the plane is no point. */
static void test_args(void)
{
        struct sec_camera cam = {.k = {.fx = 1000, .fy = 1000, .cx = 400, .cy = 300},
                                 .width = W,
                                 .height = H,
                                 .R = {1, 0, 0, 0, 1, 0, 0, 0, 1},
                                 .t = {0, 0, 500}};
        double p[3] = {0, 0, 0}, n0[3] = {0, 0, 0}, nz[3] = {0, 0, 1}, nx[3] = {1, 0, 1e-5},
               px[3] = {1, 0, 0};
        float centre[H];
        struct laserline_result r = {.centre = centre, .n = H};
        struct sec_ctx c;

        for (int i = 0; i < H; i++)
                centre[i] = NAN;
        cam.R[0] = 2;
        CHECK_INT(sec_init(&c, &cam), -EINVAL);
        cam.R[0] = NAN; /* riggeom_camera_pose of a NAN arm angle */
        CHECK_INT(sec_init(&c, &cam), -EINVAL);
        cam.R[0] = 1;
        cam.t[1] = NAN;
        CHECK_INT(sec_init(&c, &cam), -EINVAL);
        cam.t[1] = 0;
        CHECK_INT(sec_init(&c, &cam), 0);
        CHECK_INT(sec_add_laser(&c, p, n0), -EINVAL);
        CHECK_INT(sec_add_laser(&c, p, nz), 0);
        CHECK_INT(sec_add_laser(&c, px, nx), 1);
        CHECK_INT(sec_add_laser(&c, p, nz), 2);
        for (int i = 3; i < SEC_MAX_LASERS; i++)
                CHECK_INT(sec_add_laser(&c, p, nz), i);
        CHECK_INT(sec_add_laser(&c, p, nz), -ENOSPC);
        CHECK_INT(sec_add_line(&c, SEC_MAX_LASERS, 0, &r, false, NULL), -EINVAL);
        r.n = H + 1;
        CHECK_INT(sec_add_line(&c, 0, 0, &r, false, NULL), -EINVAL);
        r.n = H;
        centre[300] = 400; /* alone: no neighbour vouches for it */
        CHECK_INT(sec_add_line(&c, 0, 0, &r, false, NULL), 0);
        CHECK(c.unvouched == 1);
        centre[299] = centre[301] = 400; /* the run's ends are left out, its middle is kept */
        CHECK_INT(sec_add_line(&c, 0, 0, &r, false, NULL), 1);
        CHECK(c.unvouched == 3);
        /* the principal ray: meets z = 0 at the origin */
        CHECK(fabs(c.pts[0].x[0]) < 1e-9 && fabs(c.pts[0].x[2]) < 1e-9 && c.pts[0].row == 300);
        centre[301] = 400 + 1.01 * SEC_MAX_KINK_PX; /* a step at row 300 */
        CHECK_INT(sec_add_line(&c, 0, 0, &r, false, NULL), 0);
        CHECK(c.unvouched == 6);
        centre[301] = 400 + 0.99 * SEC_MAX_KINK_PX;
        CHECK_INT(sec_add_line(&c, 0, 0, &r, false, NULL), 1);
        centre[301] = 400;
        /* nearly along the plane x = 1: a point 100 m away, no point */
        CHECK_INT(sec_add_line(&c, 1, 0, &r, false, NULL), 0);
        CHECK(c.rejected == 1);
        sec_free(&c);
}

/* The object frame (minus the turntable angle about z), a line per column, and colour from a
 * 16-bit mono texture, on a camera looking up at the plane z = 0 from 500 mm below. */
static void test_frames(void)
{
        struct sec_camera cam = {.k = {.fx = 1000, .fy = 1000, .cx = 400, .cy = 300},
                                 .width = W,
                                 .height = H,
                                 .R = {1, 0, 0, 0, 1, 0, 0, 0, 1},
                                 .t = {0, 0, 500}};
        double p[3] = {0, 0, 0}, nz[3] = {0, 0, 1};
        float centre[W];
        struct laserline_result r = {.centre = centre, .n = W};
        struct gn_frame tex = {0};
        struct sec_ctx c;

        for (int i = 0; i < W; i++)
                centre[i] = NAN;
        CHECK_INT(gn_frame_alloc(&tex, W, H, 1, 16), 0);
        for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++)
                        ((uint16_t *)(tex.data + (size_t)y * tex.stride))[x] = 0x4000;
        CHECK_INT(sec_init(&c, &cam), 0);
        CHECK_INT(sec_add_laser(&c, p, nz), 0);
        centre[499] = centre[500] = centre[501] = 300; /* column 500, row 300: (50, 0, 0) */
        CHECK_INT(sec_add_line(&c, 0, 90, &r, true, &tex), 1);
        CHECK(fabs(c.pts[0].x[0]) < 1e-4 && fabs(c.pts[0].x[1] + 50) < 1e-4 &&
              fabs(c.pts[0].x[2]) < 1e-4);
        CHECK(c.pts[0].row == 500 && c.pts[0].line == 0);
        CHECK(c.pts[0].rgb[0] == 64 && c.pts[0].rgb[1] == 64 && c.pts[0].rgb[2] == 64);
        r.n = W + 1;
        CHECK_INT(sec_add_line(&c, 0, 0, &r, true, NULL), -EINVAL);
        r.n = H + 1; /* a per-row result longer than the image */
        CHECK_INT(sec_add_line(&c, 0, 0, &r, false, NULL), -EINVAL);
        tex.width--;
        CHECK_INT(sec_add_line(&c, 0, 0, &r, true, &tex), -EINVAL);
        tex.width++;
        gn_frame_free_data(&tex);
        sec_free(&c);
}

static const struct test_case cases[] = {
        {"sphere", test_sphere},       {"gem", test_gem},
        {"relief", test_relief},       {"two-lasers", test_two_lasers},
        {"undistort", test_undistort}, {"args", test_args},
        {"frames", test_frames},
};

int main(int argc, char **argv)
{
        return TEST_RUN_CASES(cases, argc, argv);
}
