/* scan.c - reconstruction of a dataset's laser captures into a cloud and a mesh (see
 * scan.h). Frames are loaded one view at a time (on, off, colour) and freed after their
 * line is triangulated, so memory holds the cloud, not the frames. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "calib/laserplane.h"
#include "calib/obj.h"
#include "calib/ply.h"
#include "calib/scan.h"
#include "common/cleanup.h"
#include "common/clock.h"
#include "common/riggeom.h"

#define POSE_TOL_DEG 0.01 /* two rows of one view: turntable and camera arm this close */

/* The image and laser rows of the dataset (all cameras). */
struct rows {
        struct ds_capture *c;
        size_t n;
};

/* A laser row to use, sorted by turntable angle. */
struct todo {
        double deg; /* turntable angle in [0, 360) */
        size_t row;
        int laser; /* the one laser lit (rig-file index) */
};

static void rows_free(struct rows *r)
{
        free(r->c);
}

void scan_opts_default(struct scan_opts *o)
{
        *o = (struct scan_opts){.triangles = SCAN_TRIANGLES_DEFAULT,
                                .max_error_mm = SCAN_MAX_ERROR_MM};
        cal_mesh_opts_default(&o->mesh);
}

int scan_load_rig(struct ds *d, const struct rig_backend *const *backends, struct rig_config **rc,
                  char *err, size_t errlen)
{
        char path[4096];

        snprintf(path, sizeof(path), "%s/rig.yaml", ds_path(d));
        return rigconf_load_stored(path, backends, rc, err, errlen);
}

int scan_nominal_calib(const struct rig_config *rc, const char *camera, double camera_arm_deg,
                       struct scan_calib *out)
{
        const struct rig_camera_conf *cc = NULL;

        memset(out, 0, sizeof(*out));
        for (size_t i = 0; i < rc->n_cameras && !cc; i++)
                if (strcmp(rc->cameras[i].name, camera) == 0)
                        cc = &rc->cameras[i];
        if (!cc)
                return -ENOENT;
        if (!rc->n_lasers)
                return -ENODATA;
        out->cam = (struct sec_camera){
                .k = {.fx = cc->fx, .fy = cc->fy, .cx = cc->cx, .cy = cc->cy},
                .width = cc->width,
                .height = cc->height,
        };
        memcpy(out->cam.k.dist, cc->dist, sizeof(out->cam.k.dist));
        riggeom_camera_pose(cc, isnan(camera_arm_deg) ? 0 : camera_arm_deg, out->cam.R, out->cam.t);
        for (size_t i = 0; i < rc->n_lasers && i < SEC_MAX_LASERS; i++)
                sec_rig_laser_plane(rc->lasers[i].laser_azimuth_deg, out->plane_p[i],
                                    out->plane_n[i]);
        out->n_lasers = (int)MIN(rc->n_lasers, (size_t)SEC_MAX_LASERS);
        return 0;
}

/* Images and laser frames: not darks and flats. */
static bool keep_row(const struct ds_capture *c, void *userdata)
{
        return !c->kind[0] || !strcmp(c->kind, "image") || !strcmp(c->kind, "laser");
}

/* Number of rows of camera in r, or of its laser rows with laser. */
static size_t count_rows(const struct rows *r, const char *camera, bool laser)
{
        size_t n = 0;

        for (size_t i = 0; i < r->n; i++)
                n += (!laser || r->c[i].pose.lasers) && strcmp(r->c[i].camera, camera) == 0;
        return n;
}

/* The camera to scan: o->camera, else the first of the rig's cameras with laser rows. */
static int pick_camera(const struct rig_config *rc, const struct rows *r, const char *camera,
                       const char *dsname, struct scan_result *out, char *err, size_t errlen)
{
        for (size_t i = 0; !camera && i < rc->n_cameras; i++)
                if (count_rows(r, rc->cameras[i].name, true))
                        camera = rc->cameras[i].name;
        if (camera && !count_rows(r, camera, false)) {
                snprintf(err, errlen, "dataset %s has no captures of camera %s", dsname, camera);
                return -ENOENT;
        }
        if (camera && (out->laser_rows = count_rows(r, camera, true))) {
                snprintf(out->camera, sizeof(out->camera), "%s", camera);
                return 0;
        }
        snprintf(err, errlen,
                 "dataset %s has no frames with a laser on%s%s (%zu image rows): capture a "
                 "session with 'laser: each'",
                 dsname, camera ? " of camera " : "", camera ? camera : "", r->n);
        return -ENODATA;
}

/* True when angles a and b (NAN: no such axis) are one. */
static bool same_angle(double a, double b)
{
        return isnan(a) ? isnan(b) : !isnan(b) && gn_angle_distance(a, b) <= POSE_TOL_DEG;
}

/* True when rows a and b are one view: one camera, turntable and camera arm. */
static bool same_view(const struct ds_capture *a, const struct ds_capture *b)
{
        return strcmp(a->camera, b->camera) == 0 &&
               same_angle(a->pose.deg[GN_ROLE_TURNTABLE], b->pose.deg[GN_ROLE_TURNTABLE]) &&
               same_angle(a->pose.deg[GN_ROLE_CAMERA_ARM], b->pose.deg[GN_ROLE_CAMERA_ARM]);
}

/* The laser-off row of the view of row i: with no lamp lit and the same exposure and gain
 * (lit false: to subtract), or a lamp-lit image of the base exposure (lit true: colour);
 * -1 if none. */
static ssize_t partner(const struct rows *r, size_t i, bool lit)
{
        const struct ds_capture *on = &r->c[i];

        for (size_t k = 0; k < r->n; k++) {
                const struct ds_capture *c = &r->c[k];
                if (c->pose.lasers || (c->pose.lamps != 0) != lit || !same_view(c, on))
                        continue;
                if (lit ? c->bracket == 0 && strcmp(c->kind, "laser") != 0
                        : c->exposure_us == on->exposure_us && c->gain == on->gain)
                        return (ssize_t)k;
        }
        return -1;
}

static int cmp_todo(const void *a, const void *b)
{
        const struct todo *x = a, *y = b;

        return x->deg != y->deg ? (x->deg > y->deg) - (x->deg < y->deg)
                                : (x->row > y->row) - (x->row < y->row);
}

/* The laser lit alone in c, if the calibration has its plane (n_planes); else -1. */
static int lone_laser(const struct ds_capture *c, int n_planes)
{
        int l = __builtin_ctz(c->pose.lasers | 1u << 31);

        return l < n_planes && c->pose.lasers == UINT32_C(1) << l ? l : -1;
}

/* The camera's laser rows of the first laser row's camera-arm angle (*arm) lit by one laser
 * of the n_planes calibrated, sorted by turntable angle, into *ret (*n of them); the others
 * are counted in out->other_view and out->shared. */
static int sort_rows(const struct rows *r, int n_planes, struct scan_result *out, struct todo **ret,
                     size_t *n, double *arm)
{
        struct todo *t = calloc(out->laser_rows ? out->laser_rows : 1, sizeof(*t));
        bool first = true;

        if (!t)
                return -ENOMEM;
        *n = 0;
        for (size_t i = 0; i < r->n; i++) {
                const struct ds_capture *c = &r->c[i];
                double a = c->pose.deg[GN_ROLE_TURNTABLE];
                if (!c->pose.lasers || strcmp(c->camera, out->camera))
                        continue;
                if (first)
                        *arm = c->pose.deg[GN_ROLE_CAMERA_ARM];
                first = false;
                if (!same_angle(*arm, c->pose.deg[GN_ROLE_CAMERA_ARM])) {
                        out->other_view++;
                        continue;
                }
                if (lone_laser(c, n_planes) < 0) {
                        out->shared++;
                        continue;
                }
                a = isnan(a) ? 0 : fmod(a, 360);
                t[(*n)++] = (struct todo){a < 0 ? a + 360 : a, i, lone_laser(c, n_planes)};
        }
        qsort(t, *n, sizeof(*t), cmp_todo);
        *ret = t;
        return 0;
}

/* The frames of one view: laser on, off (or none), colour (or none). */
struct view {
        struct gn_frame on, off, tex;
        bool has_off, has_tex;
};

static void view_free(struct view *v)
{
        gn_frame_free_data(&v->on);
        gn_frame_free_data(&v->off);
        gn_frame_free_data(&v->tex);
}

static bool fits(const struct gn_frame *f, const struct sec_camera *cam)
{
        return f->width == cam->width && f->height == cam->height;
}

/* Loads the frames of laser row i into v. Returns 0, or -EIO (a frame that would not load:
 * counted) or -ERANGE (on or off of another size than the camera: counted). */
static int view_load(struct ds *d, const struct rows *r, size_t i, const struct sec_camera *cam,
                     struct view *v, struct scan_result *out)
{
        ssize_t off = partner(r, i, false), tex = partner(r, i, true);

        if (ds_load_image(d, r->c[i].file, &v->on) < 0 ||
            (off >= 0 && ds_load_image(d, r->c[off].file, &v->off) < 0)) {
                out->unreadable++;
                return -EIO;
        }
        v->has_off = off >= 0;
        if (!fits(&v->on, cam) || (v->has_off && !fits(&v->off, cam))) {
                out->wrong_size++;
                return -ERANGE;
        }
        v->has_tex =
                tex >= 0 && ds_load_image(d, r->c[tex].file, &v->tex) >= 0 && fits(&v->tex, cam);
        return 0;
}

/* Extracts and triangulates the line of laser row t->row into c, on its laser's plane. */
static int scan_row(struct ds *d, const struct rig_config *rc, const struct rows *r,
                    const struct todo *t, struct sec_ctx *c, struct scan_result *out)
{
        int channel = (size_t)t->laser < rc->n_lasers ? rc->lasers[t->laser].laser_channel : 0;
        _cleanup_(view_free) struct view v = {0};
        _cleanup_free_ float *centre = malloc((size_t)c->cam.height * sizeof(*centre));
        struct laserline_result res = {.centre = centre, .n = c->cam.height};
        struct laserline_opts o;
        const struct gn_frame *tex;
        int n;

        if (!centre)
                return -ENOMEM;
        if (view_load(d, r, t->row, &c->cam, &v, out) < 0)
                return 0;
        laserline_opts_default(&o, v.on.channels == 3 ? channel : 0);
        n = laserline_extract(&v.on, v.has_off ? &v.off : NULL, &o, &res);
        if (n < 0) {
                out->wrong_size++; /* a shape laserline refuses: on and off differ */
                return 0;
        }
        tex = v.has_tex ? &v.tex : v.has_off ? &v.off : NULL;
        if ((n = sec_add_line(c, t->laser, t->deg, &res, false, tex)) < 0)
                return n;
        out->laser_points[t->laser] += (size_t)n;
        out->used++;
        out->paired += v.has_off;
        out->textured += v.has_tex;
        out->no_line += n == 0;
        return 0;
}

/* Starts c with cal, or the nominal calibration of the camera at camera_arm_deg. */
static int start_ctx(const struct rig_config *rc, const struct scan_calib *cal, const char *camera,
                     double camera_arm_deg, struct sec_ctx *c, char *err, size_t errlen)
{
        struct scan_calib nominal;
        int r;

        if (!cal) {
                r = scan_nominal_calib(rc, camera, camera_arm_deg, &nominal);
                if (r < 0) {
                        snprintf(err, errlen, "the dataset's rig file has %s%s",
                                 r == -ENOENT ? "no camera " : "no laser",
                                 r == -ENOENT ? camera : "");
                        return r;
                }
                cal = &nominal;
        }
        if (cal->n_lasers < 1 || cal->n_lasers > SEC_MAX_LASERS || sec_init(c, &cal->cam) < 0) {
                snprintf(err, errlen, "a calibration without a laser plane or a valid camera");
                return -EINVAL;
        }
        for (int i = 0; i < cal->n_lasers; i++)
                if ((r = sec_add_laser(c, cal->plane_p[i], cal->plane_n[i])) < 0) {
                        snprintf(err, errlen, "laser plane %d has no normal", i);
                        return r;
                }
        return 0;
}

int scan_section(struct ds *d, const struct rig_config *rc, const struct scan_opts *o,
                 const struct scan_calib *cal, struct sec_ctx *c, struct scan_result *out,
                 char *err, size_t errlen)
{
        _cleanup_(rows_free) struct rows r = {0};
        _cleanup_free_ struct todo *t = NULL;
        double arm = NAN;
        size_t n;
        int e;

        memset(out, 0, sizeof(*out));
        out->agree_rms_mm = NAN;
        if ((e = ds_rows_collect(d, keep_row, NULL, &r.c, &r.n)) < 0) {
                snprintf(err, errlen, "cannot read dataset %s: %s", ds_name(d), ds_last_error(d));
                return e;
        }
        if ((e = pick_camera(rc, &r, o->camera, ds_name(d), out, err, errlen)) < 0 ||
            (e = sort_rows(&r, cal ? cal->n_lasers : (int)MIN(rc->n_lasers, SEC_MAX_LASERS), out,
                           &t, &n, &arm)) < 0 ||
            (e = start_ctx(rc, cal, out->camera, arm, c, err, errlen)) < 0)
                return e;
        for (size_t i = 0; i < n; i++)
                if ((e = scan_row(d, rc, &r, &t[i], c, out)) < 0)
                        return e;
        out->points = c->n_pts;
        out->rejected = c->rejected;
        out->unvouched = c->unvouched;
        for (int l = 0; l < SEC_MAX_LASERS; l++)
                out->n_lasers += out->laser_points[l] > 0;
        sec_normals(c);
        if (!c->n_pts) {
                snprintf(err, errlen,
                         "no laser line in any of the %zu laser frames of camera %s (%zu "
                         "unreadable, %zu of another size): is the laser in view and on?",
                         out->laser_rows, out->camera, out->unreadable, out->wrong_size);
                return -ENODATA;
        }
        return 0;
}

/* Fails with -EEXIST when a scan file is in dir_fd already and not force. */
static int check_outputs(int dir_fd, bool force, const char *dsname, char *err, size_t errlen)
{
        static const char *const files[] = {SCAN_FILE_POINTS, SCAN_FILE_MESH_PLY,
                                            SCAN_FILE_MESH_OBJ};

        for (size_t i = 0; !force && i < ELEMENTSOF(files); i++)
                if (faccessat(dir_fd, files[i], F_OK, 0) == 0) {
                        snprintf(err, errlen,
                                 "dataset %s has a scan already (%s): --force replaces it", dsname,
                                 files[i]);
                        return -EEXIST;
                }
        return 0;
}

/* Normals, the cloud, the mesh and its simplification, written into dir_fd. */
static int write_outputs(int dir_fd, struct sec_ctx *c, const struct scan_opts *o,
                         struct scan_result *out, char *err, size_t errlen)
{
        _cleanup_(cal_mesh_free) struct cal_mesh m = {0};
        const char *what = SCAN_FILE_POINTS;
        int r;

        if (out->n_lasers > 1 && cal_lasers_agreement(c, 0, &out->agree_rms_mm, &out->agree_pairs,
                                                      out->agree_offset_mm) < 0)
                out->agree_rms_mm = NAN; /* the clouds do not overlap: nothing to compare */
        r = ply_write_points(dir_fd, SCAN_FILE_POINTS, c->pts, c->n_pts);
        if (r >= 0 && (r = cal_mesh_from_grid(c, &o->mesh, &m)) >= 0) {
                out->triangles = m.n_tri;
                out->seams_closed = m.seams_closed;
                r = cal_mesh_simplify(&m, o->triangles, o->max_error_mm, &out->error_mm);
                out->triangles_simplified = m.n_tri;
                out->folds = m.folds;
        }
        if (r >= 0 && (r = ply_write_mesh(dir_fd, what = SCAN_FILE_MESH_PLY, &m)) >= 0)
                r = obj_write_mesh(dir_fd, what = SCAN_FILE_MESH_OBJ, &m);
        if (r < 0)
                snprintf(err, errlen, "cannot write %s: %s", what, strerror(-r));
        return r;
}

int scan_dataset(struct ds *d, const struct rig_config *rc, const struct scan_opts *o,
                 const struct scan_calib *cal, struct scan_result *out, char *err, size_t errlen)
{
        _cleanup_(sec_free) struct sec_ctx c = {0};
        _cleanup_close_ int dir_fd = -EBADF;
        uint64_t t0 = gn_monotonic_ns();
        int r;

        memset(out, 0, sizeof(*out));
        if (!rc || !o->triangles || !(o->max_error_mm > 0)) {
                snprintf(err, errlen, "no rig, no triangle target or no error limit");
                return -EINVAL;
        }
        dir_fd = open(ds_path(d), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (dir_fd < 0) {
                r = -errno;
                snprintf(err, errlen, "cannot open %s: %s", ds_path(d), strerror(-r));
                return r;
        }
        if ((r = check_outputs(dir_fd, o->force, ds_name(d), err, errlen)) < 0 ||
            (r = scan_section(d, rc, o, cal, &c, out, err, errlen)) < 0 ||
            (r = write_outputs(dir_fd, &c, o, out, err, errlen)) < 0)
                return r;
        out->seconds = (double)(gn_monotonic_ns() - t0) / 1e9;
        return 0;
}
