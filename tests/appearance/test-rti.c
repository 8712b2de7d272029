/* test-rti.c - the RTI export (appearance/export_rti.c) read back by readers written in this
 * file from the formats' public documents: the .lp light file (count, then "path dx dy dz"),
 * Malzbender's PTM 1.2 (PTM_FORMAT_LRGB: header, 6 scales, 6 integer biases, per pixel from
 * the bottom row 6 coefficient bytes, then the RGB bytes; coefficient = (byte - bias) x
 * scale) and relight's web format (info.json, coefficient planes decoding as
 * (byte / 255 - bias) x scale). Datasets from apscene.h (simulated sphere, noise off). */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "appearance/export.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds_png.h"
#include "drivers/registry.h"
#include "sim/render/render.h"
#include "tests/appearance/apscene.h"
#include "tests/dataset/ds-util.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);

#define NB 6 /* the PTM basis: lu^2, lv^2, lu lv, lu, lv, 1 */

static const struct ap_export_opts eo = {.backends = registry_backends};

static void rm_rfp(char **dir)
{
        if (*dir)
                tu_rm_rf(*dir);
        free(*dir);
}

struct lp {
        size_t n;
        char path[64][64];
        double l[64][3];
};

static void lp_read(const char *path, struct lp *lp)
{
        FILE *f = fopen(path, "r");

        CHECK(f);
        CHECK(fscanf(f, "%zu", &lp->n) == 1 && lp->n <= 64);
        for (size_t j = 0; j < lp->n; j++)
                CHECK(fscanf(f, "%63s %lf %lf %lf", lp->path[j], &lp->l[j][0], &lp->l[j][1],
                             &lp->l[j][2]) == 4);
        fclose(f);
}

struct ptm {
        int W, H;
        double scale[NB];
        int bias[NB];
        uint8_t *coef, *rgb; /* as stored: rows bottom to top */
};

static void ptm_read(const char *path, struct ptm *p)
{
        char magic[32], fmt[32];
        FILE *f = fopen(path, "rb");

        CHECK(f);
        CHECK(fscanf(f, "%31s %31s %d %d", magic, fmt, &p->W, &p->H) == 4);
        CHECK_STR(magic, "PTM_1.2");
        CHECK_STR(fmt, "PTM_FORMAT_LRGB");
        for (int k = 0; k < NB; k++)
                CHECK(fscanf(f, "%lf", &p->scale[k]) == 1);
        for (int k = 0; k < NB; k++)
                CHECK(fscanf(f, "%d", &p->bias[k]) == 1);
        CHECK(fgetc(f) == '\n');
        p->coef = malloc((size_t)p->W * p->H * NB);
        p->rgb = malloc((size_t)p->W * p->H * 3);
        CHECK(fread(p->coef, NB, (size_t)p->W * p->H, f) == (size_t)p->W * p->H);
        CHECK(fread(p->rgb, 3, (size_t)p->W * p->H, f) == (size_t)p->W * p->H);
        CHECK(fgetc(f) == EOF);
        fclose(f);
}

/* The PTM file's basis (PTM 1.2: L = a0 lu^2 + a1 lv^2 + a2 lu lv + a3 lu + a4 lv + a5). */
static void basis(const double l[3], double b[NB])
{
        double u = l[0], v = l[1];
        double x[NB] = {u * u, v * v, u * v, u, v, 1};

        memcpy(b, x, sizeof(x));
}

/* relight's "ptm" basis, plane j weighting function j (OpenLIME ShaderRTI's PTM weights). */
static void basis_relight(const double l[3], double b[NB])
{
        double u = l[0], v = l[1];
        double x[NB] = {1, u, v, u * u, u * v, v * v};

        memcpy(b, x, sizeof(x));
}

/* The one view folder of out. */
static void view_dir(const char *out, char *view, size_t len)
{
        DIR *d = opendir(out);
        struct dirent *e;
        int n = 0;

        CHECK(d);
        while ((e = readdir(d)))
                if (e->d_name[0] != '.' && n++ == 0)
                        snprintf(view, len, "%s", e->d_name);
        closedir(d);
        CHECK_INT(n, 1);
}

static void read_png(const char *path, struct gn_frame *f)
{
        _cleanup_free_ void *buf = NULL;
        size_t len;

        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 1 << 26, &buf, &len), 0);
        CHECK_INT(ds_png_decode(buf, len, f), 0);
}

static double px(const struct gn_frame *f, int x, int y, int ch)
{
        const uint8_t *row = f->data + (size_t)y * f->stride;
        size_t i = (size_t)x * f->channels + (f->channels == 3 ? ch : 0);

        return f->bits == 8 ? row[i] / 255.0 : ((const uint16_t *)row)[i] / 65535.0;
}

/* World direction from the object's centre to p, in the RTI frame of camera geometry g. */
static void rti_dir(const struct sim_cam_geom *g, const double p[3], double l[3])
{
        double d[3] = {p[0], p[1], p[2] - APS_SIZE_MM / 2}, n = hypot(hypot(d[0], d[1]), d[2]);

        for (int i = 0; i < 3; i++) {
                double x =
                        (g->R[3 * i] * d[0] + g->R[3 * i + 1] * d[1] + g->R[3 * i + 2] * d[2]) / n;
                l[i] = i == 0 ? x : -x;
        }
}

struct fixture {
        struct apscene s;
        char *dir;
        char out[512], view[256];
        struct sim_cam_geom g;
};

/* Builds a dataset of one 64x48 camera at turntable 0, the first n_lamps of lamps at 10,
 * 35, 60, 85, 22.5 degrees on arm_angles arm angles, and exports it. Returns the export's. */
static int fixture_export(struct fixture *fx, int arm_angles, int n_lamps, char *err, size_t len)
{
        char path[600];
        struct aps_opts o;
        int r;

        aps_opts_default(&o, APS_DIFFUSE);
        o.width = 64;
        o.height = 48;
        o.turntable_angles = 1;
        o.arm_angles = arm_angles;
        o.n_lamps = n_lamps;
        memcpy(o.lamp_elevation_deg, (double[]){10, 35, 60, 85, 22.5}, 5 * sizeof(double));
        o.mesh = false;
        aps_open(&fx->s, &o);
        fx->dir = tu_tmpdir();
        snprintf(path, sizeof(path), "%s/ds", fx->dir);
        snprintf(fx->out, sizeof(fx->out), "%s/out", fx->dir);
        CHECK(mkdir(fx->out, 0755) == 0);
        _cleanup_(ds_closep) struct ds *d = aps_make_dataset(&fx->s, path);
        r = ap_export_rti(d, path, fx->out, &eo, err, len);
        fprintf(stderr, "export: %d %s\n", r, err);
        return r;
}

/* fixture_export of 4 lamps on 6 arm angles (24 lights, some behind the object). */
static void fixture_open(struct fixture *fx)
{
        struct gn_pose pose = {{0, 0, NAN}, 0, false};
        char err[512] = "";

        CHECK_INT(fixture_export(fx, 6, 4, err, sizeof(err)), 0);
        view_dir(fx->out, fx->view, sizeof(fx->view));
        CHECK_INT(sim_camera_geom(fx->s.t.s, &pose, 0, &fx->g), 0);
}

static void fixture_close(struct fixture *fx)
{
        aps_close(&fx->s);
        rm_rfp(&fx->dir);
}

/* The .lp directions are the rig's lamps on the camera's side seen from the object's centre
 * in the camera's frame, in the fit's order (lamp, then arm angle); each names an image. */
static void test_lp(void)
{
        struct fixture fx;
        struct lp lp;
        char path[1200];
        size_t j = 0;

        fixture_open(&fx);
        snprintf(path, sizeof(path), "%s/%s/%s.lp", fx.out, fx.view, fx.view);
        lp_read(path, &lp);
        for (int lamp = 0; lamp < 4; lamp++)
                for (int a = 0; a < 6; a++) {
                        double p[3], l[3];
                        struct stat st;
                        aps_lamp_position(&fx.s, lamp, a * 60, p);
                        rti_dir(&fx.g, p, l);
                        if (l[2] <= 0)
                                continue;
                        CHECK(j < lp.n);
                        for (int i = 0; i < 3; i++)
                                CHECK_NEAR(lp.l[j][i], l[i], 1e-5);
                        snprintf(path, sizeof(path), "%s/%s/%s", fx.out, fx.view, lp.path[j++]);
                        CHECK(stat(path, &st) == 0);
                }
        fprintf(stderr, "%zu lights on the camera's side\n", lp.n);
        CHECK_INT(lp.n, j);
        CHECK(j >= 12);
        fixture_close(&fx);
}

/* The PTM relit at a light between the captured ones (azimuth 28.6, elevation 34.4 degrees)
 * against the simulator's image, over the lit pixels: rms within 0.05 of full scale (0.032
 * measured: a biquadratic in the light direction against a Lambertian sphere's shadow edge). */
static void test_ptm(void)
{
        struct fixture fx;
        struct ptm p;
        struct gn_frame fr;
        char path[1200];
        double pos[3] = {500 * cos(0.6) * cos(0.5), 500 * cos(0.6) * sin(0.5), 500 * sin(0.6)};
        double l[3], b[NB], sse = 0, ref = 0;
        size_t n = 0;

        fixture_open(&fx);
        snprintf(path, sizeof(path), "%s/%s/%s.ptm", fx.out, fx.view, fx.view);
        ptm_read(path, &p);
        CHECK(p.W == 64 && p.H == 48);
        rti_dir(&fx.g, pos, l);
        basis(l, b);
        aps_render_light(&fx.s, 0, 0, pos, &fr, 0, NULL);
        for (int y = 0; y < p.H; y++)
                for (int x = 0; x < p.W; x++) {
                        size_t i = (size_t)(p.H - 1 - y) * p.W + x;
                        double L = 0;
                        for (int k = 0; k < NB; k++)
                                L += (p.coef[i * NB + k] - p.bias[k]) * p.scale[k] * b[k];
                        for (int ch = 0; ch < 3; ch++) {
                                double v = px(&fr, x, y, ch);
                                if (v < 0.02)
                                        continue;
                                sse += pow(L * p.rgb[i * 3 + ch] / 255.0 - v, 2);
                                ref += v * v;
                                n++;
                        }
                }
        fprintf(stderr, "PTM relit: rms %.4f over %zu samples, image rms %.4f\n", sqrt(sse / n), n,
                sqrt(ref / n));
        CHECK(n > 1000);
        CHECK(sqrt(sse / n) < 0.05); /* full scale 1; the image rms is 0.41 */
        gn_frame_free_data(&fr);
        free(p.coef);
        free(p.rgb);
        fixture_close(&fx);
}

/* Solves the 6 x 6 system M x = y (Gaussian elimination, partial pivoting). */
static void solve6(double M[NB][NB], double y[NB], double x[NB])
{
        for (int c = 0; c < NB; c++) {
                int piv = c;
                for (int r = c + 1; r < NB; r++)
                        piv = fabs(M[r][c]) > fabs(M[piv][c]) ? r : piv;
                for (int k = 0; k < NB; k++) {
                        double t = M[c][k];
                        M[c][k] = M[piv][k];
                        M[piv][k] = t;
                }
                double t = y[c];
                y[c] = y[piv];
                y[piv] = t;
                for (int r = c + 1; r < NB; r++) {
                        double f = M[r][c] / M[c][c];
                        for (int k = c; k < NB; k++)
                                M[r][k] -= f * M[c][k];
                        y[r] -= f * y[c];
                }
        }
        for (int c = NB - 1; c >= 0; c--) {
                x[c] = y[c];
                for (int k = c + 1; k < NB; k++)
                        x[c] -= M[c][k] * x[k];
                x[c] /= M[c][c];
        }
}

/* The least-squares coefficients of relight's basis for channel ch at (x, y) from the .lp
 * and its images. */
static void ls_coef(const struct lp *lp, struct gn_frame *img, int x, int y, int ch, double a[NB])
{
        double M[NB][NB] = {{0}}, v[NB] = {0}, b[NB];

        for (size_t j = 0; j < lp->n; j++) {
                basis_relight(lp->l[j], b);
                for (int r = 0; r < NB; r++) {
                        v[r] += b[r] * px(&img[j], x, y, ch);
                        for (int k = 0; k < NB; k++)
                                M[r][k] += b[r] * b[k];
                }
        }
        solve6(M, v, a);
}

/* The relight folder's info.json and planes decode to the least-squares coefficients of the
 * view's images within the quantisation step. */
static void test_relight(void)
{
        struct fixture fx;
        struct lp lp;
        struct gn_frame img[64], plane[NB];
        json_error_t je;
        char path[1200];
        double worst = 0;

        fixture_open(&fx);
        snprintf(path, sizeof(path), "%s/%s/%s.lp", fx.out, fx.view, fx.view);
        lp_read(path, &lp);
        for (size_t j = 0; j < lp.n; j++) {
                snprintf(path, sizeof(path), "%s/%s/%s", fx.out, fx.view, lp.path[j]);
                read_png(path, &img[j]);
        }
        snprintf(path, sizeof(path), "%s/%s/relight/info.json", fx.out, fx.view);
        json_t *info = json_load_file(path, 0, &je);
        CHECK(info);
        CHECK_STR(json_string_value(json_object_get(info, "type")), "ptm");
        CHECK_STR(json_string_value(json_object_get(info, "colorspace")), "rgb");
        CHECK_INT(json_integer_value(json_object_get(info, "nplanes")), 18);
        CHECK_INT(json_integer_value(json_object_get(info, "width")), 64);
        json_t *mat = json_array_get(json_object_get(info, "materials"), 0);
        json_t *scale = json_object_get(mat, "scale"), *bias = json_object_get(mat, "bias");
        CHECK(json_array_size(scale) == 18 && json_array_size(bias) == 18);
        for (int k = 0; k < NB; k++) {
                snprintf(path, sizeof(path), "%s/%s/relight/plane_%d.%s", fx.out, fx.view, k,
                         json_string_value(json_object_get(info, "format")));
                read_png(path, &plane[k]);
                CHECK(plane[k].width == 64 && plane[k].height == 48 && plane[k].bits == 8);
        }
        for (int y = 0; y < 48; y += 3)
                for (int x = 0; x < 64; x += 3)
                        for (int ch = 0; ch < 3; ch++) {
                                double a[NB];
                                ls_coef(&lp, img, x, y, ch, a);
                                for (int k = 0; k < NB; k++) {
                                        int i = 3 * k + ch;
                                        double s = json_real_value(json_array_get(scale, i));
                                        double bi = json_real_value(json_array_get(bias, i));
                                        double c = (px(&plane[k], x, y, ch) - bi) * s;
                                        worst = fmax(worst, fabs(c - a[k]) / (s / 255));
                                }
                        }
        fprintf(stderr, "relight planes: worst error %.3f quantisation steps\n", worst);
        CHECK(worst <= 0.6);
        json_decref(info);
        for (size_t j = 0; j < lp.n; j++)
                gn_frame_free_data(&img[j]);
        for (int k = 0; k < NB; k++)
                gn_frame_free_data(&plane[k]);
        fixture_close(&fx);
}

/* A view with fewer than 6 lights: refused, with the view and the count named. */
static void test_few_lights(void)
{
        struct fixture fx;
        char err[512] = "";

        CHECK_INT(fixture_export(&fx, 1, 5, err, sizeof(err)), -ENODATA);
        CHECK_STR_CONTAINS(err, "has 5 lights on the camera's side");
        CHECK_STR_CONTAINS(err, "at least 6");
        fixture_close(&fx);
}

/* The same bytes of one file at paths a and b. */
static bool same_file(const char *a, const char *b)
{
        _cleanup_free_ void *x = NULL, *y = NULL;
        size_t nx, ny;

        CHECK_INT(gn_read_file_at(AT_FDCWD, a, 1 << 26, &x, &nx), 0);
        CHECK_INT(gn_read_file_at(AT_FDCWD, b, 1 << 26, &y, &ny), 0);
        return nx == ny && memcmp(x, y, nx) == 0;
}

/* gonioctl dataset export --format rti: the same PTM as the writer's; into a non-empty
 * folder refused. */
static void test_gonioctl(void)
{
        struct fixture fx;
        char args[1400], out[8192], a[1400], b[1400];

        if (!getenv("GONIOCTL"))
                exit(TEST_SKIP);
        fixture_open(&fx);
        snprintf(args, sizeof(args), "dataset export %s/ds --format rti -o %s/cli", fx.dir, fx.dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        snprintf(a, sizeof(a), "%s/%s/%s.ptm", fx.out, fx.view, fx.view);
        snprintf(b, sizeof(b), "%s/cli/%s/%s.ptm", fx.dir, fx.view, fx.view);
        CHECK(same_file(a, b));
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "not an empty folder");
        fixture_close(&fx);
}

#define KILLS 5

/* Every view folder of the RTI export out reads back: its .lp, each image it names, its PTM
 * and relight's info.json. Returns the number of views. */
static int check_complete(const char *out)
{
        DIR *d = opendir(out);
        struct dirent *e;
        int n = 0;

        CHECK(d);
        while ((e = readdir(d))) {
                char path[1200];
                struct lp lp;
                struct ptm p;
                json_error_t je;
                json_t *info;
                if (e->d_name[0] == '.')
                        continue;
                snprintf(path, sizeof(path), "%s/%s/%s.lp", out, e->d_name, e->d_name);
                lp_read(path, &lp);
                for (size_t j = 0; j < lp.n; j++) {
                        snprintf(path, sizeof(path), "%s/%s/%s", out, e->d_name, lp.path[j]);
                        CHECK(access(path, R_OK) == 0);
                }
                snprintf(path, sizeof(path), "%s/%s/%s.ptm", out, e->d_name, e->d_name);
                ptm_read(path, &p);
                free(p.coef);
                free(p.rgb);
                snprintf(path, sizeof(path), "%s/%s/relight/info.json", out, e->d_name);
                CHECK((info = json_load_file(path, 0, &je)) != NULL);
                json_decref(info);
                n++;
        }
        closedir(d);
        return n;
}

/* The entries of dir whose names start with prefix. */
static int count_prefix(const char *dir, const char *prefix)
{
        DIR *d = opendir(dir);
        struct dirent *e;
        int n = 0;

        CHECK(d);
        while ((e = readdir(d)))
                n += strncmp(e->d_name, prefix, strlen(prefix)) == 0;
        closedir(d);
        return n;
}

static double now_s(void)
{
        struct timespec t;

        clock_gettime(CLOCK_MONOTONIC, &t);
        return (double)t.tv_sec + t.tv_nsec * 1e-9;
}

/* Starts gonioctl dataset export ds --format rti -o out (output to /dev/null); kills it with
 * SIGKILL after delay_s unless delay_s < 0. Returns its wait status. */
static int export_run(const char *ds, const char *out, double delay_s)
{
        char *argv[] = {
                getenv("GONIOCTL"), "dataset", "export", (char *)ds, "--format", "rti", "-o",
                (char *)out,        NULL};
        posix_spawn_file_actions_t fa;
        extern char **environ;
        pid_t pid;
        int st;

        CHECK_INT(posix_spawn_file_actions_init(&fa), 0);
        CHECK_INT(posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0), 0);
        CHECK_INT(posix_spawn_file_actions_adddup2(&fa, 1, 2), 0);
        CHECK_INT(posix_spawn(&pid, argv[0], &fa, NULL, argv, environ), 0);
        posix_spawn_file_actions_destroy(&fa);
        if (delay_s >= 0) {
                struct timespec t = {(time_t)delay_s, (long)((delay_s - (time_t)delay_s) * 1e9)};
                nanosleep(&t, NULL);
                kill(pid, SIGKILL);
        }
        CHECK(waitpid(pid, &st, 0) == pid);
        return st;
}

/* gonioctl dataset export --format rti SIGKILLed at KILLS seeded moments of its run (each a
 * fresh run into its own folder): the folder is then absent or complete, never partial; a
 * rerun succeeds, removes the killed run's temporary folder and says so. */
static void test_kill(void)
{
        unsigned seed = getenv("GONIO_TEST_SEED") ? (unsigned)atoi(getenv("GONIO_TEST_SEED")) : 11;
        _cleanup_(rm_rfp) char *dir = NULL;
        char ds[600], out[700], args[1600], text[8192], prefix[64];
        struct apscene s;
        struct aps_opts o;
        int views, stale = 0;
        double t0, full;

        if (!getenv("GONIOCTL"))
                exit(TEST_SKIP);
        aps_opts_default(&o, APS_DIFFUSE);
        o.width = 96, o.height = 72, o.n_cameras = 2, o.turntable_angles = 3, o.arm_angles = 6;
        o.n_lamps = 4, o.mesh = false;
        memcpy(o.lamp_elevation_deg, (double[]){10, 35, 60, 85}, 4 * sizeof(double));
        aps_open(&s, &o);
        dir = tu_tmpdir();
        snprintf(ds, sizeof(ds), "%s/ds", dir);
        ds_close(aps_make_dataset(&s, ds));
        aps_close(&s);
        snprintf(out, sizeof(out), "%s/cold", dir); /* the files cached: a run's usual time */
        CHECK_INT(export_run(ds, out, -1), 0);
        snprintf(out, sizeof(out), "%s/full", dir);
        t0 = now_s();
        CHECK_INT(export_run(ds, out, -1), 0);
        full = now_s() - t0;
        views = check_complete(out);
        fprintf(stderr, "seed %u; a whole export: %.3f s, %d views\n", seed, full, views);
        srand(seed);
        for (int i = 0; i < KILLS; i++) {
                double at = full * (0.05 + 0.9 * rand() / RAND_MAX);
                int st, left;
                snprintf(out, sizeof(out), "%s/k%d", dir, i);
                snprintf(prefix, sizeof(prefix), ".k%d.export-", i);
                st = export_run(ds, out, at);
                left = count_prefix(dir, prefix);
                fprintf(stderr, "kill %d at %.3f s: %s, output %s, %d temporary folder(s)\n", i, at,
                        WIFSIGNALED(st) ? "killed" : "had ended",
                        access(out, F_OK) == 0 ? "present" : "absent", left);
                CHECK(left <= 1);
                stale += left;
                if (access(out, F_OK) == 0) { /* renamed before the kill: whole */
                        CHECK_INT(check_complete(out), views);
                        continue;
                }
                snprintf(args, sizeof(args), "dataset export %s --format rti -o %s", ds, out);
                CHECK_INT(test_run_gonioctl(args, text, sizeof(text)), 0);
                if (left)
                        CHECK_STR_CONTAINS(text, "removed 1 temporary folder of an interrupted");
                CHECK_INT(count_prefix(dir, prefix), 0);
                CHECK_INT(check_complete(out), views);
        }
        CHECK(stale >= 1); /* some kill landed while the export was writing */
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"lp", test_lp},
                {"ptm", test_ptm},
                {"relight", test_relight},
                {"few-lights", test_few_lights},
                {"gonioctl", test_gonioctl},
                {"kill", test_kill},
        };

        /* the datasets' fsyncs cost seconds on a disk: memory where there is one */
        if (!getenv("TMPDIR") && access("/dev/shm", W_OK) == 0)
                setenv("TMPDIR", "/dev/shm", 0);
        return TEST_RUN_CASES(cases, argc, argv);
}
