/* test-render-scene.c - scenes from the rig file: schema errors name file, line and key;
 * PLY (ascii, binary) and OBJ meshes load where the file puts them; textures map through
 * the uvs; the built-in shapes are where their definitions say (ground truth points and
 * normals); the mirror sphere shows the lamp where the reflection law puts it; area lamps
 * soften the shadow edge into a penumbra of the right width. */
#include <errno.h>
#include <math.h>
#include <spng.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "rtest.h"

static const char lamp[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 60, "
        "radius: 400, azimuth: 20, intensity: 1.0e5 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 55, distance: 350, azimuth: 0,\n"
        "      target: [0, 0, 20], width: 160, height: 120, fx: 330, fy: 330, exposure_us: 20000 "
        "}\n";
static const char zoom[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 55, distance: 350, azimuth: 0,\n"
        "      target: [0, 0, 20], width: 160, height: 120, fx: 900, fy: 900, exposure_us: 20000 "
        "}\n";

static void expect_error(const char *scene, const char *msg)
{
        struct rtest t;
        char err[512] = "";

        CHECK(rt_try_open(&t, lamp, "", cams, scene, err, sizeof(err)) == -EINVAL);
        CHECK_STR_CONTAINS(err, t.path);
        CHECK_STR_CONTAINS(err, msg);
        rt_close(&t);
}

static void test_schema_errors(void)
{
        expect_error("scene:\n  object: { shape: sphere, size: 10, colour: red }\n", "colour");
        expect_error("scene:\n  object: { shape: torus, size: 10 }\n", "shape");
        expect_error("scene:\n  object: { shape: sphere }\n", "size");
        expect_error("scene:\n  object: { shape: mesh, path: nothere.ply }\n", "nothere.ply");
        expect_error("scene:\n  object: { shape: sphere, size: 10,\n"
                     "    material: { specular: { model: phong } } }\n",
                     "model");
        expect_error(
                "scene:\n  object: { shape: sphere, size: 10, material: { albedo: [1, 2] } }\n",
                "albedo");
        expect_error("scene:\n  targets:\n    - { type: charuco, squares: [20, 20] }\n", "squares");
        expect_error("scene:\n  sensor: { format: cmyk }\n", "format");
        expect_error("scene:\n  lamps: { samples: 1000 }\n", "samples");
        expect_error("scene:\n  bogus: 1\n", "bogus");
}

static void write_file(const char *path, const void *data, size_t n)
{
        FILE *f = fopen(path, "wb");

        CHECK(f && fwrite(data, 1, n, f) == n);
        fclose(f);
}

/* Renders the scene and checks every object pixel lies on the plane z = h inside the
 * square |x|, |y| <= 40; returns the number of such pixels. */
static int plate_pixels(const char *scene, double h, struct gn_frame *keep)
{
        struct rtest t;
        struct gn_pose st = {.lamps = 1};
        struct sim_expose ex = {.bits = 8, .no_noise = true};
        struct gn_frame f;
        struct sim_truth tr;
        int n = 0;

        rt_open(&t, lamp, "", cams, scene);
        rt_render(&t, &st, &ex, 0, &f, SIM_TRUTH_POINT | SIM_TRUTH_NORMAL, &tr);
        for (int i = 0; i < f.width * f.height; i++) {
                const float *p = tr.point + 3 * i, *nv = tr.normal + 3 * i;
                if (isnan(p[0]))
                        continue;
                CHECK_NEAR(p[2], h, 1e-3);
                CHECK(fabsf(p[0]) <= 40.01f && fabsf(p[1]) <= 40.01f);
                CHECK_NEAR(nv[2], 1, 1e-5);
                n++;
        }
        if (keep)
                *keep = f;
        else
                gn_frame_free_data(&f);
        sim_truth_free(&tr);
        rt_close(&t);
        return n;
}

/* A scene with the mesh file dir/name as object; extra goes into the object mapping. */
static const char *mesh_scene(char *buf, size_t len, const char *dir, const char *name,
                              const char *extra)
{
        snprintf(buf, len,
                 "scene:\n  object: { shape: mesh, path: %s/%s%s }\n  turntable: { radius: 0 }\n",
                 dir, name, extra);
        return buf;
}

static void put(const char *dir, const char *name, const void *data, size_t n)
{
        char path[256];

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        write_file(path, data, n);
}

static void test_meshes(const char *dir)
{
        static const char obj[] = "# a square plate of 80 mm at z = 12, one quad\n"
                                  "v -40 -40 12\nv 40 -40 12\nv 40 40 12\nv -40 40 12\n"
                                  "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
                                  "f 1/1/1 2/2/1 3/3/1 4/4/1\n";
        static const char ply_ascii[] = "ply\nformat ascii 1.0\ncomment plate\n"
                                        "element vertex 4\nproperty float x\nproperty float y\n"
                                        "property float z\nelement face 1\n"
                                        "property list uchar int vertex_indices\nend_header\n"
                                        "-40 -40 7\n40 -40 7\n40 40 7\n-40 40 7\n4 0 1 2 3\n";
        char hdr[] = "ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
                     "property float x\nproperty float y\nproperty float z\n"
                     "property float nx\nproperty float ny\nproperty float nz\n"
                     "element face 2\nproperty list uchar uint vertex_indices\nend_header\n";
        const float verts[4][6] = {{-40, -40, 3, 0, 0, 1},
                                   {40, -40, 3, 0, 0, 1},
                                   {40, 40, 3, 0, 0, 1},
                                   {-40, 40, 3, 0, 0, 1}};
        const uint8_t faces[] = {3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0,
                                 3, 0, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0};
        uint8_t bin[1024];
        size_t nb = 0;

        memcpy(bin, hdr, strlen(hdr));
        nb += strlen(hdr);
        memcpy(bin + nb, verts, sizeof(verts));
        nb += sizeof(verts);
        memcpy(bin + nb, faces, sizeof(faces));
        nb += sizeof(faces);
        char sc[512];

        put(dir, "plate.obj", obj, strlen(obj));
        put(dir, "plate-a.ply", ply_ascii, strlen(ply_ascii));
        put(dir, "plate-b.ply", bin, nb);
        CHECK(plate_pixels(mesh_scene(sc, sizeof(sc), dir, "plate.obj", ""), 12, NULL) > 3000);
        CHECK(plate_pixels(mesh_scene(sc, sizeof(sc), dir, "plate-a.ply", ""), 7, NULL) > 3000);
        CHECK(plate_pixels(mesh_scene(sc, sizeof(sc), dir, "plate-b.ply", ""), 3, NULL) > 3000);
        /* size: fitted to 40 mm, bottom on z = 0 (a flat plate: z = 0) */
        CHECK(plate_pixels(mesh_scene(sc, sizeof(sc), dir, "plate-b.ply", ", size: 40"), 0, NULL) >
              500);
}

/* A 2x2 PNG: red, green / blue, white (top row first). */
static void write_png(const char *path)
{
        const uint8_t px[12] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
        struct spng_ihdr ih = {2, 2, 8, SPNG_COLOR_TYPE_TRUECOLOR, 0, 0, 0};
        spng_ctx *c = spng_ctx_new(SPNG_CTX_ENCODER);
        FILE *f = fopen(path, "wb");

        CHECK(c && f);
        spng_set_png_file(c, f);
        spng_set_ihdr(c, &ih);
        CHECK(spng_encode_image(c, px, sizeof(px), SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE) == 0);
        spng_ctx_free(c);
        fclose(f);
}

static void test_texture(const char *dir)
{
        char sc[512], extra[300], png[256];
        struct gn_frame f;
        struct sim_cam_geom g;
        struct rtest t;
        struct gn_pose st = {.lamps = 1};
        /* uv (0,0) is the bottom-left of the image: the blue texel at x, y < 0; the points
         * are at texel centres, where bilinear filtering returns the texel itself */
        const double pts[4][3] = {{-20, 20, 12}, {20, 20, 12}, {-20, -20, 12}, {20, -20, 12}};
        const int dominant[4] = {0, 1, 2, -1}; /* red, green, blue, white */

        snprintf(png, sizeof(png), "%s/tex.png", dir);
        write_png(png);
        snprintf(extra, sizeof(extra), ",\n    material: { albedo: 1, albedo_map: %s }", png);
        CHECK(plate_pixels(mesh_scene(sc, sizeof(sc), dir, "plate.obj", extra), 12, &f) > 3000);
        rt_open(&t, lamp, "", cams, "scene:\n  turntable: { radius: 0 }\n");
        CHECK_INT(sim_camera_geom(t.s, &st, 0, &g), 0);
        for (int k = 0; k < 4; k++) {
                double uv[2], c[3];
                CHECK_INT(sim_cam_project(&g, pts[k], uv), 0);
                for (int ch = 0; ch < 3; ch++)
                        c[ch] = rt_px(&f, (int)lround(uv[0]), (int)lround(uv[1]), ch);
                for (int ch = 0; ch < 3; ch++)
                        if (dominant[k] < 0)
                                CHECK(c[ch] > 20);
                        else if (ch != dominant[k])
                                CHECK(c[ch] < 0.05 * c[dominant[k]]);
        }
        rt_close(&t);
        gn_frame_free_data(&f);
}

/* Ground truth of the built-in shapes: points on their surfaces, unit normals. */
static void test_shapes(void)
{
        static const char *const scenes[] = {
                "scene:\n  object: { shape: cylinder, size: 60 }\n  turntable: { radius: 0 }\n",
                "scene:\n  object: { shape: sphere, size: 60, resolution: 64 }\n"
                "  turntable: { radius: 0 }\n",
                "scene:\n  object: { shape: gem, size: 60 }\n  turntable: { radius: 0 }\n",
                "scene:\n  object: { shape: relief, size: 100 }\n  turntable: { radius: 0 }\n",
        };
        struct gn_pose st = {.deg[GN_ROLE_TURNTABLE] = 40, .lamps = 1};

        for (size_t k = 0; k < ELEMENTSOF(scenes); k++) {
                struct rtest t;
                struct gn_frame f;
                struct sim_truth tr;
                int n = 0;

                rt_open(&t, lamp, "", cams, scenes[k]);
                rt_render(&t, &st, NULL, 0, &f,
                          SIM_TRUTH_POINT | SIM_TRUTH_NORMAL | SIM_TRUTH_DEPTH, &tr);
                for (int i = 0; i < f.width * f.height; i++) {
                        const float *p = tr.point + 3 * i, *nv = tr.normal + 3 * i;
                        if (isnan(p[0]))
                                continue;
                        n++;
                        CHECK_NEAR(sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]), 1, 1e-5);
                        CHECK(tr.depth[i] > 200 && tr.depth[i] < 500);
                        double r = hypot(p[0], p[1]);
                        if (k == 0 && p[2] > 0.01 && p[2] < 59.99) /* cylinder side */
                                CHECK_NEAR(r, 30, 0.01);
                        if (k == 1) /* tessellated sphere: within the chord sag */
                                CHECK_NEAR(hypot(r, p[2] - 30), 30, 0.04);
                        CHECK(p[2] >= -1e-3 && p[2] <= 60.01 && r <= 50.01);
                }
                CHECK(n > 1000);
                gn_frame_free_data(&f);
                sim_truth_free(&tr);
                rt_close(&t);
        }
}

/* The lamp's image in a mirror sphere sits where the normal bisects camera and lamp. */
static void test_mirror_sphere(void)
{
        struct rtest t;
        struct gn_pose st = {.deg[GN_ROLE_LIGHT_ARM] = 30, .lamps = 1};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct sim_cam_geom g;
        struct gn_frame f;
        double c[3] = {0, 0, 30}, L[3], C[3], n[3] = {0, 0, 1}, p[3], uv[2];
        double su = 0, sv = 0, sw = 0;

        rt_open(&t, lamp, "", zoom,
                "scene:\n  targets:\n    - { type: mirror_sphere, size: 60 }\n"
                "  turntable: { radius: 0 }\n  lamps: { radius: 30 }\n"
                "  sensor: { response: 1.0e3, full_well: 1.0e5 }\n");
        rt_render(&t, &st, &ex, 0, &f, 0, NULL);
        CHECK_INT(sim_camera_geom(t.s, &st, 0, &g), 0);
        CHECK_INT(sim_lamp_position(t.s, &st, 0, L), 0);
        for (int i = 0; i < 3; i++)
                C[i] = -(g.R[i] * g.t[0] + g.R[3 + i] * g.t[1] + g.R[6 + i] * g.t[2]);
        for (int it = 0; it < 100; it++) { /* fixed point: n = unit(unit(C-p) + unit(L-p)) */
                double a[3], b[3], la = 0, lb = 0, ln = 0;
                for (int i = 0; i < 3; i++) {
                        p[i] = c[i] + 30 * n[i];
                        a[i] = C[i] - p[i];
                        b[i] = L[i] - p[i];
                        la += a[i] * a[i];
                        lb += b[i] * b[i];
                }
                for (int i = 0; i < 3; i++) {
                        n[i] = a[i] / sqrt(la) + b[i] / sqrt(lb);
                        ln += n[i] * n[i];
                }
                for (int i = 0; i < 3; i++)
                        n[i] /= sqrt(ln);
        }
        CHECK_INT(sim_cam_project(&g, p, uv), 0);
        for (int v = 0; v < f.height; v++)
                for (int u = 0; u < f.width; u++) {
                        double w = rt_px(&f, u, v, 0);
                        su += w * u;
                        sv += w * v;
                        sw += w;
                }
        fprintf(stderr, "mirror: highlight at (%.2f, %.2f), law of reflection (%.2f, %.2f)\n",
                su / sw, sv / sw, uv[0], uv[1]);
        CHECK(sw > 0);
        CHECK_NEAR(su / sw, uv[0], 0.3);
        CHECK_NEAR(sv / sw, uv[1], 0.3);
        gn_frame_free_data(&f);
        rt_close(&t);
}

/* Area lamp: umbra and full light where a point lamp puts them +- the penumbra. */
static void test_soft_shadow(void)
{
        static const char top[] = "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, "
                                  "elevation: 90, radius: 400, intensity: 1.0e5 }\n";
        const char *sc = "scene:\n  object: { shape: sphere, size: 60 }\n"
                         "  turntable: { radius: 150, albedo: 0.5 }\n"
                         "  lamps: { radius: 30, samples: 32 }\n";
        struct rtest t;
        struct gn_pose st = {.lamps = 1};
        struct sim_expose ex = {.bits = 16, .no_noise = true};
        struct gn_frame f;
        struct sim_truth tr;
        double rho_s = 400 * tan(asin(30.0 / 370)), half = 30.0 * 45 / 355 + 1;
        int partial = 0;

        rt_open(&t, top, "", cams, sc);
        rt_render(&t, &st, &ex, 0, &f, SIM_TRUTH_POINT, &tr);
        for (int i = 0; i < f.width * f.height; i++) {
                const float *p = tr.point + 3 * i;
                double rho, unshadowed, got;
                if (isnan(p[0]) || fabsf(p[2]) > 1e-3f)
                        continue;
                rho = hypot(p[0], p[1]);
                unshadowed = 0.5 / M_PI * 1e5 * 400 / pow(rho * rho + 400 * 400, 1.5) * 0.02 * 5e5 /
                             1e4 * 65535;
                got = rt_px(&f, i % f.width, i / f.width, 0);
                if (rho < rho_s - half)
                        CHECK(got == 0);
                else if (rho > rho_s + half)
                        CHECK_NEAR(got, unshadowed, 0.01 * unshadowed + 1);
                else if (got > 0.1 * unshadowed && got < 0.9 * unshadowed)
                        partial++;
        }
        fprintf(stderr, "soft shadow: %d penumbra pixels\n", partial);
        CHECK(partial > 30);
        sim_truth_free(&tr);
        gn_frame_free_data(&f);
        rt_close(&t);
}

/* Meshes and textures from files in a scratch directory. */
static void test_mesh_files(void)
{
        char dir[] = "/tmp/gonio-rtest-mesh-XXXXXX", cmd[64];

        CHECK(mkdtemp(dir));
        test_meshes(dir);
        test_texture(dir);
        snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
        CHECK(system(cmd) == 0);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"schema", test_schema_errors},    {"meshes", test_mesh_files},
                {"shapes", test_shapes},           {"mirror", test_mirror_sphere},
                {"soft-shadow", test_soft_shadow},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
