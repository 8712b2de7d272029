/* test-scan.c - calib/scan.c and gonioctl scan --from against datasets of frames rendered
 * in-process: a 100 mm sphere at 60 turntable angles, each with a laser frame (lamps off),
 * a lamp frame and, at every other angle, a laser-off frame with no lamp; one laser frame
 * unreadable, one at another camera-arm angle, one laser-off frame of another exposure. The
 * reconstruction's counts, its cloud and mesh against the true sphere, its colours, its files, the
 * calibration it is given, and its errors: no laser frames, no such camera, a scan there already.
 */
#include <fcntl.h>
#include <jansson.h>
#include <stdio.h>
#include <sys/wait.h>
#include <unistd.h>

#include "calib/scan.h"
#include "common/cleanup.h"
#include "drivers/registry.h"
#include "meshread.h"
#include "scanrig.h"
#include "tests/dataset/ds-util.h"

#define ANGLES   60
#define BROKEN   3    /* the laser frame of this angle is lost */
#define RMS_MAX  0.05 /* mm, the cloud to the true sphere */
#define WORST    0.1  /* mm */
#define NO_LASER 1    /* make_dataset: no laser frames at all */

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);

/* Renders and stores one capture of camera c0 at turntable angle deg (camera arm arm_deg),
 * recorded as exposed exposure_us. */
static void store(struct ds *d, struct rtest *t, double deg, double arm_deg, bool laser,
                  uint32_t lamps, int exposure_us, uint64_t seq, char *file, size_t len)
{
        struct ds_capture c = {.camera = "c0", .exposure_us = exposure_us, .gain = 1};
        struct gn_frame f;

        c.pose = (struct gn_pose){.deg = {deg, NAN, arm_deg}, .lamps = lamps, .lasers = laser};
        snprintf(c.kind, sizeof(c.kind), "%s", laser ? "laser" : "image");
        snprintf(c.lamps, sizeof(c.lamps), "%s", lamps ? "l0" : "");
        st_render(t, deg, laser, lamps, seq, &f);
        CHECK_INT(ds_store(d, &f, &c), 0);
        if (file)
                snprintf(file, len, "%s", c.file);
        gn_frame_free_data(&f);
}

/* A new dataset in dir/name of the sphere at n angles (see the top of the file); returns
 * its path (freed by the caller). */
static char *make_dataset(const char *dir, const char *name, struct rtest *t, int n, int flags)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        char *path, lost[256] = "", file[600];

        CHECK(asprintf(&path, "%s/%s", dir, name) > 0);
        CHECK_INT(ds_create(path, name, t->rc->text, &d), 0);
        for (int i = 0; i < n; i++) {
                double deg = 360.0 * i / n;
                if (!(flags & NO_LASER))
                        store(d, t, deg, NAN, true, 0, 20000, 3 * (uint64_t)i,
                              i == BROKEN ? lost : NULL, sizeof(lost));
                store(d, t, deg, NAN, false, 1, 20000, 3 * (uint64_t)i + 1, NULL, 0);
                if (i % 2 == 0) /* laser off, lamps off */
                        store(d, t, deg, NAN, false, 0, 20000, 3 * (uint64_t)i + 2, NULL, 0);
        }
        if (!(flags & NO_LASER)) { /* at another camera-arm angle: not this scan's view */
                store(d, t, 0, 10, true, 0, 20000, 9999, NULL, 0);
                /* of another exposure: not to subtract from the laser frame */
                store(d, t, 360.0 / n, NAN, false, 0, 10000, 9998, NULL, 0);
        }
        if (lost[0]) {
                snprintf(file, sizeof(file), "%s/%s", path, lost);
                CHECK_INT(unlink(file), 0);
        }
        return path;
}

/* RMS and worst distance of the n points p from the sphere. */
static void sphere_score(const struct sec_point *p, size_t n, double *rms, double *worst)
{
        double sum = 0;

        *worst = 0;
        for (size_t i = 0; i < n; i++) {
                double d = st_sphere_dist(p[i].x);
                sum += d * d;
                *worst = fmax(*worst, fabs(d));
        }
        *rms = sqrt(sum / (double)n);
}

/* The files of a scan in path: the cloud on the sphere, lit by the white lamp (not the red
 * laser), the mesh within the target, the OBJ the same mesh as the PLY. */
static void expect_files(const char *path, const struct scan_result *r, size_t target)
{
        _cleanup_close_ int fd = open(path, O_RDONLY | O_DIRECTORY);
        struct cal_mesh cloud, mesh;
        double rms, worst, red = 0, green = 0;

        CHECK(fd >= 0);
        mr_read_ply(fd, SCAN_FILE_POINTS, &cloud);
        CHECK(cloud.n_v == r->points && !cloud.tri);
        sphere_score(cloud.v, cloud.n_v, &rms, &worst);
        for (size_t i = 0; i < cloud.n_v; i++) {
                red += cloud.v[i].rgb[0];
                green += cloud.v[i].rgb[1];
        }
        fprintf(stderr,
                "scan.ply: %zu points, RMS %.4f mm, worst %.4f mm, mean green %.1f, red/green "
                "%.2f\n",
                cloud.n_v, rms, worst, green / (double)cloud.n_v, red / green);
        CHECK(rms <= RMS_MAX && worst <= WORST);
        CHECK(green > 40.0 * (double)cloud.n_v && red < 1.3 * green);
        mr_read_ply(fd, SCAN_FILE_MESH_PLY, &mesh);
        CHECK(mesh.n_tri == r->triangles_simplified && mesh.n_tri <= target && mesh.n_tri > 0);
        sphere_score(mesh.v, mesh.n_v, &rms, &worst);
        CHECK(rms <= RMS_MAX && worst <= WORST);
        mr_expect_obj(fd, SCAN_FILE_MESH_OBJ, &mesh);
        cal_mesh_free(&cloud);
        cal_mesh_free(&mesh);
}

static void test_dataset(void)
{
        _cleanup_free_ char *dir = tu_tmpdir(), *path = NULL;
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        struct scan_opts o;
        struct scan_result r;
        struct rtest t;
        char err[512];

        st_open(&t, "{ shape: sphere, size: 100, material: { albedo: 0.6 } }", 20, 50);
        path = make_dataset(dir, "sphere", &t, ANGLES, 0);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(scan_load_rig(d, registry_backends, &rc, err, sizeof(err)), 0);
        scan_opts_default(&o);
        o.triangles = 20000;
        CHECK_INT(scan_dataset(d, rc, &o, NULL, &r, err, sizeof(err)), 0);
        fprintf(stderr,
                "camera %s: %zu laser rows, %zu used (%zu paired, %zu textured, %zu no line), "
                "skipped %zu unreadable, %zu size, %zu view; %zu points, %zu -> %zu faces, "
                "error %.4f mm, %.2f s\n",
                r.camera, r.laser_rows, r.used, r.paired, r.textured, r.no_line, r.unreadable,
                r.wrong_size, r.other_view, r.points, r.triangles, r.triangles_simplified,
                r.error_mm, r.seconds);
        CHECK_STR(r.camera, "c0");
        CHECK(r.laser_rows == ANGLES + 1 && r.other_view == 1 && r.unreadable == 1);
        CHECK(r.used == ANGLES - 1 && r.paired == ANGLES / 2 && r.textured == ANGLES - 1);
        CHECK(r.no_line == 0 && r.wrong_size == 0 && r.seams_closed == 1);
        CHECK(r.points > 250 * r.used && r.triangles > r.points);
        expect_files(path, &r, o.triangles);
        /* a scan there already: only with force */
        CHECK_INT(scan_dataset(d, rc, &o, NULL, &r, err, sizeof(err)), -EEXIST);
        CHECK_STR_CONTAINS(err, "--force replaces it");
        o.force = true;
        CHECK_INT(scan_dataset(d, rc, &o, NULL, &r, err, sizeof(err)), 0);
        CHECK_INT(tu_count(path, ".tmp"), 0);
        rt_close(&t);
        tu_rm_rf(dir);
}

/* The calibration given is the one used: the laser plane 1 mm off moves the cloud off the
 * sphere, the nominal one given explicitly reproduces the default. */
static void test_calib(void)
{
        _cleanup_free_ char *dir = tu_tmpdir(), *path = NULL;
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        _cleanup_close_ int fd = -EBADF;
        struct scan_opts o;
        struct scan_result r, r0;
        struct scan_calib cal;
        struct cal_mesh cloud;
        struct rtest t;
        double rms, worst;
        char err[512];

        st_open(&t, "{ shape: sphere, size: 100, material: { albedo: 0.6 } }", 20, 50);
        path = make_dataset(dir, "sphere", &t, 12, 0);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(scan_load_rig(d, registry_backends, &rc, err, sizeof(err)), 0);
        CHECK((fd = open(path, O_RDONLY | O_DIRECTORY)) >= 0);
        scan_opts_default(&o);
        o.force = true;
        CHECK_INT(scan_dataset(d, rc, &o, NULL, &r0, err, sizeof(err)), 0);
        CHECK_INT(scan_nominal_calib(rc, "c0", NAN, &cal), 0);
        CHECK_INT(scan_dataset(d, rc, &o, &cal, &r, err, sizeof(err)), 0);
        CHECK(r.points == r0.points && r.triangles == r0.triangles);
        for (int k = 0; k < 3; k++)
                cal.plane_p[0][k] += cal.plane_n[0][k];
        CHECK_INT(scan_dataset(d, rc, &o, &cal, &r, err, sizeof(err)), 0);
        mr_read_ply(fd, SCAN_FILE_POINTS, &cloud);
        sphere_score(cloud.v, cloud.n_v, &rms, &worst);
        fprintf(stderr, "laser plane 1 mm off: RMS %.3f mm\n", rms);
        CHECK(rms > 0.5);
        cal_mesh_free(&cloud);
        cal.n_lasers = 0;
        CHECK_INT(scan_dataset(d, rc, &o, &cal, &r, err, sizeof(err)), -EINVAL);
        CHECK_INT(scan_nominal_calib(rc, "c7", NAN, &cal), -ENOENT);
        rt_close(&t);
        tu_rm_rf(dir);
}

/* No laser frames, no such camera: clear errors, nothing written. */
static void test_bad(void)
{
        _cleanup_free_ char *dir = tu_tmpdir(), *path = NULL;
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        struct scan_opts o;
        struct scan_result r;
        struct rtest t;
        char err[512];

        st_open(&t, "{ shape: sphere, size: 100, material: { albedo: 0.6 } }", 20, 50);
        path = make_dataset(dir, "lamps", &t, 4, NO_LASER);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(scan_load_rig(d, registry_backends, &rc, err, sizeof(err)), 0);
        scan_opts_default(&o);
        CHECK_INT(scan_dataset(d, rc, &o, NULL, &r, err, sizeof(err)), -ENODATA);
        fprintf(stderr, "%s\n", err);
        CHECK_STR_CONTAINS(err, "has no frames with a laser on (6 image rows)");
        o.camera = "c7";
        CHECK_INT(scan_dataset(d, rc, &o, NULL, &r, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, "no captures of camera c7");
        CHECK_INT(tu_count(path, ".ply"), 0);
        rt_close(&t);
        tu_rm_rf(dir);
}

/* gonioctl scan --from: the summary (text and JSON), the exit codes of its errors. */
static void test_gonioctl(void)
{
        _cleanup_free_ char *dir = NULL, *path = NULL, *lamps = NULL;
        char args[1024], out[8192];
        json_t *j, *rows;
        struct rtest t;

        if (!getenv("GONIOCTL")) {
                fprintf(stderr, "GONIOCTL not set: skipped\n");
                exit(TEST_SKIP);
        }
        dir = tu_tmpdir();
        st_open(&t, "{ shape: sphere, size: 100, material: { albedo: 0.6 } }", 20, 50);
        path = make_dataset(dir, "sphere", &t, 24, 0);
        lamps = make_dataset(dir, "lamps", &t, 2, NO_LASER);
        snprintf(args, sizeof(args), "scan --from %s", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "scan of camera c0: ");
        CHECK_STR_CONTAINS(out, "from 23 of 25 laser frames");
        CHECK_STR_CONTAINS(out, "skipped: 1 unreadable, 0 of another size, 1 at another");
        CHECK_STR_CONTAINS(out, "/mesh.obj\n");
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "gonioctl: scan: dataset sphere has a scan already (scan.ply)");
        snprintf(args, sizeof(args), "--json scan --from %s --force --triangles 9000", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        CHECK(j = json_loads(strstr(out, "{\"dataset\""), JSON_DISABLE_EOF_CHECK, NULL));
        rows = json_object_get(j, "rows");
        CHECK_INT(json_integer_value(json_object_get(rows, "used")), 23);
        CHECK_INT(json_integer_value(json_object_get(rows, "paired")), 12);
        CHECK_INT(json_integer_value(json_object_get(j, "target")), 9000);
        CHECK(json_integer_value(json_object_get(j, "triangles_simplified")) <= 9000);
        json_decref(j);
        snprintf(args, sizeof(args), "scan --from %s", lamps);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "dataset lamps has no frames with a laser on");
        snprintf(args, sizeof(args), "scan --from %s --camera c7 --force", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_STR_CONTAINS(out, "no captures of camera c7");
        snprintf(args, sizeof(args), "scan --from %s/none", dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 6);
        CHECK_INT(test_run_gonioctl("scan", out, sizeof(out)), 2);
        snprintf(args, sizeof(args), "scan --from %s --triangles 0", path);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 2);
        rt_close(&t);
        tu_rm_rf(dir);
}

static const struct test_case cases[] = {
        {"dataset", test_dataset},
        {"calib", test_calib},
        {"bad", test_bad},
        {"gonioctl", test_gonioctl},
};

int main(int argc, char **argv)
{
        return TEST_RUN_CASES(cases, argc, argv);
}
