/* test-export.c - the exports (appearance/export.h, docs/exports.md) of a small synthetic
 * dataset (apscene.h) with a scan, read back by readers written from each format's
 * documentation and by the real consumers: COLMAP's model_converter, Open3D. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "appearance/export.h"
#include "appearance/fit.h"
#ifdef AP_CALFILE
#include "calib/calfile.h"
#endif
#include "calib/ply.h"
#include "calib/scan.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/riggeom.h"
#include "drivers/registry.h"
#include "tests/appearance/apscene.h"
#include "tests/dataset/ds-util.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_geometry *, ap_geometry_free);

#define N_SCAN   200  /* scan points on the sphere */
#define TOL_PX   0.01 /* the reprojection agreement the issue asks */
#define MAX_SHOT 64

/* The OpenCV distortion of the rig's cameras: c0 with k3 (COLMAP's FULL_OPENCV), c1 without. */
static const char *const distortion[] = {"distortion: [-0.12, 0.05, 0.002, -0.0015, 0.02], ",
                                         "distortion: [0.08, -0.03, -0.001, 0.0025, 0], "};

static void rm_rfp(char **dir)
{
        if (*dir)
                tu_rm_rf(*dir);
        free(*dir);
}

/* Adds each camera's distortion to the dataset's rig.yaml (geometry only: the images do not
 * change, the exports do not read them). */
static void distort_rig(const char *path)
{
        _cleanup_free_ char *text = NULL;
        char file[600], out[16384];
        size_t len, n = 0;
        const char *p;

        snprintf(file, sizeof(file), "%s/rig.yaml", path);
        CHECK_INT(gn_read_file_at(AT_FDCWD, file, 1 << 20, (void **)&text, &len), 0);
        p = text;
        for (int i = 0; i < 2; i++) {
                char key[32];
                const char *at;
                snprintf(key, sizeof(key), "name: c%d, ", i);
                CHECK((at = strstr(p, key)) != NULL);
                at += strlen(key);
                n += (size_t)snprintf(out + n, sizeof(out) - n, "%.*s%s", (int)(at - p), p,
                                      distortion[i]);
                p = at;
        }
        n += (size_t)snprintf(out + n, sizeof(out) - n, "%s", p);
        CHECK(n < sizeof(out));
        CHECK_INT(gn_write_atomic(AT_FDCWD, file, out, n, NULL), 0);
}

/* Adds a third camera that took no image to the dataset's rig.yaml, after c1. */
static void add_idle_camera(const char *path)
{
        static const char cam[] = "  - { name: c9, sim: { bus: frames }, elevation: 70, distance: "
                                  "400, azimuth: 0, target: [0, 0, 30], width: 48, height: 36, "
                                  "fx: 192, fy: 192, exposure_us: 20000 }\n";
        _cleanup_free_ char *text = NULL;
        char file[600], out[16384];
        const char *at;
        size_t len;
        int n;

        snprintf(file, sizeof(file), "%s/rig.yaml", path);
        CHECK_INT(gn_read_file_at(AT_FDCWD, file, 1 << 20, (void **)&text, &len), 0);
        CHECK((at = strstr(text, "name: c1, ")) != NULL);
        CHECK((at = strchr(at, '\n')) != NULL);
        n = snprintf(out, sizeof(out), "%.*s%s%s", (int)(at + 1 - text), text, cam, at + 1);
        CHECK(n > 0 && (size_t)n < sizeof(out));
        CHECK_INT(gn_write_atomic(AT_FDCWD, file, out, (size_t)n, NULL), 0);
}

/* The count in cameras.txt's "# Number of cameras: N" line. */
static int header_cameras(const char *dir)
{
        char path[600], line[512];
        FILE *f;
        int n = -1;

        snprintf(path, sizeof(path), "%s/cameras.txt", dir);
        CHECK((f = fopen(path, "re")) != NULL);
        while (fgets(line, sizeof(line), f))
                if (sscanf(line, "# Number of cameras: %d", &n) == 1)
                        break;
        fclose(f);
        return n;
}

/* The scan: N_SCAN points of the sphere (centre (0, 0, 30), radius 30) with outward normals
 * and colours, as the dataset's scan.ply. */
static void write_scan(const char *path)
{
        struct sec_point p[N_SCAN];

        for (int i = 0; i < N_SCAN; i++) {
                double z = 1 - 2 * (i + 0.5) / N_SCAN, a = i * 2.399963, r = sqrt(1 - z * z);
                double n[3] = {r * cos(a), r * sin(a), z};
                p[i] = (struct sec_point){.rgb = {(uint8_t)i, (uint8_t)(255 - i), 7}};
                for (int k = 0; k < 3; k++) {
                        p[i].n[k] = (float)n[k];
                        p[i].x[k] = (float)(APS_SIZE_MM / 2 * n[k] + (k == 2) * APS_SIZE_MM / 2);
                }
        }
        CHECK_INT(ply_write_points(AT_FDCWD, path, p, N_SCAN), 0);
}

/* A dataset at dir/name: 2 cameras (distorted), 2 turntable angles, 3 arm angles, 2 lamps
 * (24 images), its mesh, and with scan its cloud. */
static const char *make(const char *dir, const char *name, bool scan)
{
        static char path[512];
        char file[600];
        struct aps_opts o;
        struct apscene s;

        aps_opts_default(&o, APS_DIFFUSE);
        o.n_cameras = 2, o.arm_angles = 3, o.n_lamps = 2, o.width = 48, o.height = 36;
        aps_open(&s, &o);
        snprintf(path, sizeof(path), "%s/%s", dir, name);
        ds_close(aps_make_dataset(&s, path));
        aps_close(&s);
        distort_rig(path);
        snprintf(file, sizeof(file), "%s/%s", path, SCAN_FILE_POINTS);
        if (scan)
                write_scan(file);
        return path;
}

/* The dataset's geometry as gonio places it (the exports' source). */
static struct ap_geometry *geometry(const char *path)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct ap_geometry *g = NULL;
        char err[512];

        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ap_geometry_read(d, NULL, registry_backends, &g, err, sizeof(err)), 0);
        return g;
}

static int export(const char *path, const char *format, const char *out, char *err, size_t errlen)
{
        struct ap_export_opts o = {.backends = registry_backends};

        return ap_export(path, format, out, &o, err, errlen);
}

/* Pixel of normalised camera point (a, b) with OpenCV's k1 k2 p1 p2 k3 (k[0..4]). */
static void distort(const double k[5], double a, double b, double *x, double *y)
{
        double r2 = a * a + b * b, radial = 1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));

        *x = a * radial + 2 * k[2] * a * b + k[3] * (r2 + 2 * a * a);
        *y = b * radial + k[2] * (r2 + 2 * b * b) + 2 * k[3] * a * b;
}

/* ---- COLMAP: a reader of the text model written from COLMAP's documentation
 * (https://colmap.github.io/format.html#text-format) ---- */

struct cm_camera {
        int id, w, h;
        char model[32];
        double p[12]; /* fx fy cx cy k1 k2 p1 p2 [k3 k4 k5 k6] */
};

struct cm_image {
        int id, cam;
        double q[4], t[3];
        char name[256];
};

/* Reads the data lines of dir/name (comments skipped) into lines (at most max). */
static int data_lines(const char *dir, const char *name, char lines[][512], int max)
{
        char path[600], line[512];
        FILE *f;
        int n = 0;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        CHECK((f = fopen(path, "re")) != NULL);
        while (fgets(line, sizeof(line), f))
                if (line[0] != '#' && n < max)
                        snprintf(lines[n++], 512, "%s", line);
        fclose(f);
        return n;
}

static int read_cameras(const char *dir, struct cm_camera *c, int max)
{
        static char lines[8][512];
        int n = data_lines(dir, "cameras.txt", lines, 8);

        CHECK(n <= max);
        for (int i = 0; i < n; i++) {
                int used = 0, k = 0;
                const char *s = lines[i];
                CHECK_INT(
                        sscanf(s, "%d %31s %d %d%n", &c[i].id, c[i].model, &c[i].w, &c[i].h, &used),
                        4);
                for (s += used; k < 12 && sscanf(s, "%lf%n", &c[i].p[k], &used) == 1; k++)
                        s += used;
                CHECK_INT(k, strcmp(c[i].model, "OPENCV") == 0 ? 8 : 12);
        }
        return n;
}

/* images.txt: two lines an image (the second, its 2D points, empty here). */
static int read_images(const char *dir, struct cm_image *im, int max)
{
        static char lines[2 * MAX_SHOT + 2][512];
        int n = data_lines(dir, "images.txt", lines, 2 * MAX_SHOT + 2), m = 0;

        for (int i = 0; i + 1 < n + 1 && i < n; i += 2, m++) {
                struct cm_image *x = &im[m];
                CHECK(m < max);
                CHECK_INT(sscanf(lines[i], "%d %lf %lf %lf %lf %lf %lf %lf %d %255s", &x->id,
                                 &x->q[0], &x->q[1], &x->q[2], &x->q[3], &x->t[0], &x->t[1],
                                 &x->t[2], &x->cam, x->name),
                          10);
                CHECK_STR(lines[i + 1], "\n");
        }
        return m;
}

/* Projects world point X with COLMAP camera c and image im into gonio's pixel convention. */
static bool cm_project(const struct cm_camera *c, const struct cm_image *im, const double X[3],
                       double uv[2])
{
        double w = im->q[0], x = im->q[1], y = im->q[2], z = im->q[3], p[3], k[5] = {0};
        double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                       2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                       2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};

        for (int r = 0; r < 3; r++)
                p[r] = R[3 * r] * X[0] + R[3 * r + 1] * X[1] + R[3 * r + 2] * X[2] + im->t[r];
        if (p[2] <= 0)
                return false;
        memcpy(k, c->p + 4, 4 * sizeof(double));
        if (strcmp(c->model, "FULL_OPENCV") == 0) /* k4..k6 0: the rational part is 1 */
                k[4] = c->p[8];
        distort(k, p[0] / p[2], p[1] / p[2], &uv[0], &uv[1]);
        uv[0] = c->p[0] * uv[0] + c->p[2] - 0.5; /* COLMAP's pixel centres are at +0.5 */
        uv[1] = c->p[1] * uv[1] + c->p[3] - 0.5;
        return true;
}

/* The COLMAP model: every scan point of every image lands where gonio's camera puts it; a rig
 * camera without images has no line, and the header counts the lines written. */
static void test_colmap(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path = make(dir, "ds", true);
        _cleanup_(ap_geometry_freep) struct ap_geometry *g = geometry(path);
        struct cm_camera cams[4];
        struct cm_image im[MAX_SHOT];
        static char pts[N_SCAN + 2][512];
        char out[600], err[512], img[900];
        double worst = 0;
        int nc, ni, seen = 0;

        add_idle_camera(path);
        snprintf(out, sizeof(out), "%s/colmap", dir);
        CHECK_INT(export(path, "colmap", out, err, sizeof(err)), 0);
        nc = read_cameras(out, cams, 4);
        ni = read_images(out, im, MAX_SHOT);
        CHECK_INT(nc, 2);
        CHECK_INT(header_cameras(out), 2);
        CHECK_STR(cams[0].model, "FULL_OPENCV");
        CHECK_STR(cams[1].model, "OPENCV");
        CHECK_INT((int)g->n_shots, 24);
        CHECK_INT(ni, 24);
        CHECK_INT(data_lines(out, "points3D.txt", pts, N_SCAN + 2), N_SCAN);
        for (int i = 0; i < ni; i++) {
                const struct ap_shot *s = &g->shots[i];
                const struct cm_camera *c = &cams[im[i].cam - 1];
                CHECK_INT(im[i].cam, s->cam + 1);
                snprintf(img, sizeof(img), "%s/images/%s", out, im[i].name);
                CHECK(access(img, R_OK) == 0);
                for (int j = 0; j < N_SCAN; j++) {
                        double X[3], a[2], b[2];
                        int rgb[3];
                        CHECK_INT(sscanf(pts[j], "%*d %lf %lf %lf %d %d %d", &X[0], &X[1], &X[2],
                                         &rgb[0], &rgb[1], &rgb[2]),
                                  6);
                        CHECK_INT(rgb[0], j);
                        if (!ap_camera_project(&g->cameras[s->view], X, a, NULL) || a[0] < 0 ||
                            a[1] < 0 || a[0] > c->w || a[1] > c->h)
                                continue;
                        CHECK(cm_project(c, &im[i], X, b));
                        worst = fmax(worst, hypot(a[0] - b[0], a[1] - b[1]));
                        seen++;
                }
        }
        fprintf(stderr, "%d projections, worst difference %.2g px\n", seen, worst);
        CHECK(seen > 24 * N_SCAN / 4);
        CHECK(worst <= TOL_PX);
}

/* Runs a shell command line quietly. Returns its exit status. */
static int run(const char *cmd)
{
        int r = system(cmd);

        return WIFEXITED(r) ? WEXITSTATUS(r) : -1;
}

static int cmp_id(const void *a, const void *b)
{
        return atoi(a) - atoi(b);
}

/* The data lines of dir/name sorted by their leading id (COLMAP writes them in hash order);
 * images.txt's second lines (empty: no 2D points) counted and dropped. */
static int sorted_records(const char *dir, const char *name, char lines[][512], int max)
{
        int n = data_lines(dir, name, lines, max), m = 0, blank = 0;

        for (int i = 0; i < n; i++)
                if (strcmp(lines[i], "\n") == 0)
                        blank++;
                else
                        memmove(lines[m++], lines[i], 512);
        CHECK_INT(blank, strcmp(name, "images.txt") == 0 ? m : 0);
        qsort(lines, (size_t)m, 512, cmp_id);
        return m;
}

/* The numbers and words of the records of a/name and b/name agree (numbers to 1e-12). */
static void same_model_file(const char *a, const char *b, const char *name)
{
        static char la[2 * MAX_SHOT + N_SCAN][512], lb[2 * MAX_SHOT + N_SCAN][512];
        int na = sorted_records(a, name, la, 2 * MAX_SHOT + N_SCAN);

        CHECK_INT(sorted_records(b, name, lb, 2 * MAX_SHOT + N_SCAN), na);
        for (int i = 0; i < na; i++) {
                char *sa, *sb, *pa = la[i], *pb = lb[i];
                for (;;) {
                        char *ta = strtok_r(pa, " \n", &sa), *tb = strtok_r(pb, " \n", &sb), *e;
                        double x, y;
                        pa = pb = NULL;
                        CHECK((ta == NULL) == (tb == NULL));
                        if (!ta)
                                break;
                        x = strtod(ta, &e);
                        if (*e) {
                                CHECK_STR(ta, tb);
                                continue;
                        }
                        y = strtod(tb, NULL);
                        CHECK_NEAR(x, y, 1e-12 * fmax(1, fabs(x)));
                }
        }
        fprintf(stderr, "%s: %d records the same after COLMAP's round trip\n", name, na);
}

/* COLMAP itself reads the model, converts it to binary and back without loss. */
static void test_colmap_converter(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path;
        char out[600], bin[600], txt[600], cmd[2400], err[512];

        if (run("colmap help >/dev/null 2>&1") != 0) {
                fprintf(stderr, "colmap not installed (scripts/install-deps installs it)\n");
                exit(TEST_SKIP);
        }
        path = make(dir, "ds", true);
        snprintf(out, sizeof(out), "%s/colmap", dir);
        snprintf(bin, sizeof(bin), "%s/bin", dir);
        snprintf(txt, sizeof(txt), "%s/txt", dir);
        CHECK_INT(export(path, "colmap", out, err, sizeof(err)), 0);
        CHECK_INT(mkdir(bin, 0755), 0);
        CHECK_INT(mkdir(txt, 0755), 0);
        snprintf(cmd, sizeof(cmd),
                 "QT_QPA_PLATFORM=offscreen colmap model_converter --input_path %s "
                 "--output_path %s --output_type BIN >&2 && "
                 "QT_QPA_PLATFORM=offscreen colmap model_converter --input_path %s "
                 "--output_path %s --output_type TXT >&2",
                 out, bin, bin, txt);
        CHECK_INT(run(cmd), 0);
        same_model_file(out, txt, "cameras.txt");
        same_model_file(out, txt, "images.txt");
        same_model_file(out, txt, "points3D.txt");
}

/* ---- nerfstudio: a reader of transforms.json written from nerfstudio's documentation
 * (docs.nerf.studio, "Data conventions": OpenGL camera axes, c2w transform_matrix, fl_x fl_y
 * cx cy w h, OpenCV k1 k2 p1 p2 k3; pixel centres at +0.5) ---- */

static double num(const json_t *frame, const json_t *top, const char *key)
{
        const json_t *v = json_object_get(frame, key);

        return json_number_value(v ? v : json_object_get(top, key));
}

/* Projects world point X through frame f (top: the file's header) into gonio's pixels. */
static bool ns_project(const json_t *f, const json_t *top, const double X[3], double uv[2])
{
        const json_t *m = json_object_get(f, "transform_matrix");
        double c2w[3][4], d[3], p[3] = {0}, k[5];
        static const char *const dk[] = {"k1", "k2", "p1", "p2", "k3"};

        for (int r = 0; r < 3; r++)
                for (int c = 0; c < 4; c++)
                        c2w[r][c] = json_number_value(json_array_get(json_array_get(m, r), c));
        for (int r = 0; r < 3; r++)
                d[r] = X[r] - c2w[r][3];
        for (int c = 0; c < 3; c++) /* the camera's axes are c2w's columns */
                for (int r = 0; r < 3; r++)
                        p[c] += c2w[r][c] * d[r];
        if (p[2] >= 0) /* OpenGL: the camera looks down -z */
                return false;
        for (int i = 0; i < 5; i++)
                k[i] = num(f, top, dk[i]);
        distort(k, p[0] / -p[2], -p[1] / -p[2], &uv[0], &uv[1]); /* y up: image rows down */
        uv[0] = num(f, top, "fl_x") * uv[0] + num(f, top, "cx") - 0.5;
        uv[1] = num(f, top, "fl_y") * uv[1] + num(f, top, "cy") - 0.5;
        return true;
}

static json_t *load_json(const char *dir, const char *name)
{
        char path[600];
        json_error_t je;
        json_t *t;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        t = json_load_file(path, 0, &je);
        if (!t)
                fprintf(stderr, "%s: %s\n", path, je.text);
        CHECK(t != NULL);
        return t;
}

/* The split files: every frame in exactly one split, each split's file agreeing. */
static void check_splits(const char *out, const json_t *t)
{
        size_t total = 0;

        for (int s = 0; s < 3; s++) {
                static const char *const names[] = {"train", "val", "test"};
                char key[64];
                json_auto_t *p = NULL;
                snprintf(key, sizeof(key), "transforms_%s.json", names[s]);
                p = load_json(out, key);
                snprintf(key, sizeof(key), "%s_filenames", names[s]);
                CHECK_INT(json_array_size(json_object_get(t, key)),
                          json_array_size(json_object_get(p, "frames")));
                CHECK(json_array_size(json_object_get(p, "frames")) > 0);
                total += json_array_size(json_object_get(p, "frames"));
        }
        CHECK_INT(total, json_array_size(json_object_get(t, "frames")));
}

/* transforms.json: a known point (every scan point) projects to the same pixel through
 * gonio's camera and the exported one; each frame's light is the shot's lamp. */
static void test_nerfstudio(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path = make(dir, "ds", false);
        _cleanup_(ap_geometry_freep) struct ap_geometry *g = geometry(path);
        json_auto_t *t = NULL;
        json_t *frames;
        char out[600], err[512], img[900];
        double worst = 0;
        int seen = 0;

        snprintf(out, sizeof(out), "%s/ns", dir);
        CHECK_INT(export(path, "nerfstudio", out, err, sizeof(err)), 0);
        t = load_json(out, "transforms.json");
        frames = json_object_get(t, "frames");
        CHECK_INT(json_array_size(frames), g->n_shots);
        CHECK_STR(json_string_value(json_object_get(t, "camera_model")), "OPENCV");
        for (size_t i = 0; i < g->n_shots; i++) {
                const json_t *f = json_array_get(frames, i), *lp;
                const struct ap_shot *s = &g->shots[i];
                snprintf(img, sizeof(img), "%s/%s", out,
                         json_string_value(json_object_get(f, "file_path")));
                CHECK(access(img, R_OK) == 0);
                lp = json_object_get(f, "light_position");
                for (int k = 0; k < 3; k++)
                        CHECK_NEAR(json_number_value(json_array_get(lp, k)), s->lamp[k], 1e-9);
                CHECK_NEAR(num(f, t, "light_intensity"), s->intensity, 1e-9);
                for (int j = 0; j < N_SCAN; j++) {
                        double z = 1 - 2 * (j + 0.5) / N_SCAN, a = j * 2.399963,
                               r = sqrt(1 - z * z), X[3], u[2], v[2];
                        X[0] = 30 * r * cos(a), X[1] = 30 * r * sin(a), X[2] = 30 + 30 * z;
                        if (!ap_camera_project(&g->cameras[s->view], X, u, NULL) || u[0] < 0 ||
                            u[1] < 0 || u[0] > num(f, t, "w") || u[1] > num(f, t, "h"))
                                continue;
                        CHECK(ns_project(f, t, X, v));
                        worst = fmax(worst, hypot(u[0] - v[0], u[1] - v[1]));
                        seen++;
                }
        }
        fprintf(stderr, "%d projections, worst difference %.2g px\n", seen, worst);
        CHECK(seen > 24 * N_SCAN / 4);
        CHECK(worst <= TOL_PX);
        check_splits(out, t);
}

#ifdef AP_CALFILE
/* A calibration file's lamp position reaches the export (the dataset's calibration.yaml),
 * and --calibration nominal ignores it: lamp l0 calibrated 100 mm higher than nominal. */
static void test_calibration(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path = make(dir, "ds", false);
        _cleanup_(ap_geometry_freep) struct ap_geometry *g = geometry(path);
        struct cal_lamp_pos lp = {.name = "l0", .rms_mm = 0.1, .n_obs = 10};
        struct ap_export_opts o = {.backends = registry_backends, .calibration = "nominal"};
        char cal[600], out[600], err[512];
        json_auto_t *cal_t = NULL, *nom_t = NULL;
        size_t n0 = 0;

        riggeom_lamp_position(&g->rc->lamps[0], 0, lp.pos);
        lp.pos[2] += 100;
        snprintf(cal, sizeof(cal), "%s/calibration.yaml", path);
        CHECK_INT(cal_lamp_write(cal, &lp, true, err, sizeof(err)), 0);
        snprintf(out, sizeof(out), "%s/cal", dir);
        CHECK_INT(export(path, "nerfstudio", out, err, sizeof(err)), 0);
        cal_t = load_json(out, "transforms.json");
        snprintf(out, sizeof(out), "%s/nominal", dir);
        CHECK_INT(ap_export(path, "nerfstudio", out, &o, err, sizeof(err)), 0);
        nom_t = load_json(out, "transforms.json");
        for (size_t i = 0; i < g->n_shots; i++) {
                const json_t *c = json_object_get(
                                     json_array_get(json_object_get(cal_t, "frames"), i),
                                     "light_position"),
                             *n = json_object_get(
                                     json_array_get(json_object_get(nom_t, "frames"), i),
                                     "light_position");
                bool l0 = g->shots[i].row->pose.lamps == 1;
                n0 += l0;
                for (int k = 0; k < 3; k++) {
                        CHECK_NEAR(json_number_value(json_array_get(n, k)), g->shots[i].lamp[k],
                                   1e-9);
                        CHECK_NEAR(json_number_value(json_array_get(c, k)),
                                   g->shots[i].lamp[k] + (l0 && k == 2) * 100, 1e-6);
                }
        }
        CHECK_INT(n0, g->n_shots / 2);
}
#endif

/* ---- PLY: Open3D (Debian's python3-open3d) reads the cloud and the mesh ---- */

static const char open3d_script[] =
        "import sys\n"
        "try:\n"
        "    import open3d as o3d\n"
        "except ImportError:\n"
        "    sys.exit(77)\n"
        "d, n = sys.argv[1], int(sys.argv[2])\n"
        "pc = o3d.io.read_point_cloud(d + '/points.ply')\n"
        "assert len(pc.points) == n, len(pc.points)\n"
        "assert pc.has_normals() and pc.has_colors()\n"
        "c = pc.colors[5]\n"
        "assert abs(c[0] - 5 / 255) < 1e-6 and abs(c[1] - 250 / 255) < 1e-6, c\n"
        "assert abs(sum(x * x for x in pc.normals[7]) - 1) < 1e-5\n"
        "m = o3d.io.read_triangle_mesh(d + '/mesh.ply')\n"
        "assert len(m.triangles) > 100 and len(m.vertices) > 50\n"
        "assert m.has_vertex_normals() and m.has_vertex_colors()\n"
        "print('open3d:', len(pc.points), 'points,', len(m.vertices), 'vertices,',\n"
        "      len(m.triangles), 'triangles', file=sys.stderr)\n";

static void test_ply(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path = make(dir, "ds", true);
        char out[600], err[512], script[600], cmd[1600];
        FILE *f;
        int r;

        snprintf(out, sizeof(out), "%s/ply", dir);
        CHECK_INT(export(path, "ply", out, err, sizeof(err)), 0);
        snprintf(script, sizeof(script), "%s/check.py", dir);
        CHECK((f = fopen(script, "we")) != NULL);
        fputs(open3d_script, f);
        CHECK_INT(fclose(f), 0);
        snprintf(cmd, sizeof(cmd), "/usr/bin/python3 %s %s %d", script, out, N_SCAN);
        r = run(cmd);
        if (r == 77)
                fprintf(stderr, "python3-open3d not installed (scripts/install-deps has it)\n");
        if (r == 77)
                exit(TEST_SKIP);
        CHECK_INT(r, 0);
}

/* ---- bad input ---- */

/* Entries of dir whose name starts with prefix. */
static int count_prefix(const char *dir, const char *prefix)
{
        char cmd[1200];

        snprintf(cmd, sizeof(cmd), "test $(ls -A %s | grep -c '^%s') = 0", dir, prefix);
        return run(cmd) != 0;
}

/* A non-empty destination, an unknown format, no scan for ply, an empty destination taken,
 * a writer failing half way (an image missing): a clear error, nothing half written. */
static void test_bad(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path = make(dir, "ds", false);
        char out[600], file[700], err[512];
        _cleanup_(ap_geometry_freep) struct ap_geometry *g = geometry(path);

        snprintf(out, sizeof(out), "%s/out", dir);
        CHECK_INT(mkdir(out, 0755), 0);
        snprintf(file, sizeof(file), "%s/keep", out);
        CHECK_INT(gn_write_atomic(AT_FDCWD, file, "x", 1, NULL), 0);
        CHECK_INT(export(path, "colmap", out, err, sizeof(err)), -EEXIST);
        CHECK_STR_CONTAINS(err, "not an empty folder");
        CHECK_INT(tu_count(out, ""), 1);
        CHECK_INT(export(path, "obj", out, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, "colmap, nerfstudio, ply, rti, gltf");
        CHECK_INT(unlink(file), 0);
        CHECK_INT(export(path, "ply", out, err, sizeof(err)), 0); /* mesh.ply only */
        CHECK_INT(tu_count(out, ".ply"), 1);
        snprintf(out, sizeof(out), "%s/out2", dir);
        snprintf(file, sizeof(file), "%s/%s", path, SCAN_FILE_MESH_PLY);
        CHECK_INT(unlink(file), 0);
        CHECK_INT(export(path, "ply", out, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, "has no scan");
        CHECK(access(out, F_OK) < 0);
        CHECK_INT(export(path, "colmap", out, err, sizeof(err)), 0); /* no points3D */
        snprintf(file, sizeof(file), "%s/%s", path, g->shots[5].row->file);
        CHECK_INT(unlink(file), 0);
        snprintf(out, sizeof(out), "%s/out3", dir);
        CHECK(export(path, "nerfstudio", out, err, sizeof(err)) < 0);
        CHECK_STR_CONTAINS(err, "cannot link");
        CHECK(access(out, F_OK) < 0);
        CHECK_INT(count_prefix(dir, "\\.out"), 0); /* no temporary folder left */
}

/* gonioctl dataset export: written, refused into a non-empty folder, usage checked. */
static void test_gonioctl(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        const char *path;
        char args[1400], out[8192];

        if (!getenv("GONIOCTL"))
                exit(TEST_SKIP);
        path = make(dir, "ds", true);
        snprintf(args, sizeof(args),
                 "--json dataset export %s --format nerfstudio -o %s/ns "
                 "--calibration nominal",
                 path, dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "\"format\":\"nerfstudio\"");
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "exists and is not an empty folder");
        snprintf(args, sizeof(args), "dataset export %s --format ply -o %s/ply", path, dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "ply written into");
        snprintf(args, sizeof(args), "dataset export %s --format ply", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        snprintf(args, sizeof(args), "dataset export %s --format gif -o %s/x", path, dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "unknown format 'gif'");
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"colmap", test_colmap},
                {"colmap-converter", test_colmap_converter},
                {"nerfstudio", test_nerfstudio},
                {"ply", test_ply},
                {"bad", test_bad},
                {"gonioctl", test_gonioctl},
#ifdef AP_CALFILE
                {"calibration", test_calibration},
#endif
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
