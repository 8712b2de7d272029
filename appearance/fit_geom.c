/* fit_geom.c - the geometry of the fit (fit_internal.h): each view's camera model in the
 * object frame and each light's lamp position, from the calibration file or the rig file's
 * nominal geometry; the scan mesh (read by the simulator's mesh reader) and the surface point of
 * each tile, where the light's direction and distance are taken. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "appearance/fit_internal.h"
#include "common/cleanup.h"
#include "common/riggeom.h"
#include "calib/scan.h"
#include "sim/render/render.h"
#ifdef AP_CALFILE
#include "calib/calfile.h"
#include "common/sortx.h"
#endif

#define DEG          (M_PI / 180)
#define UNDIST_ITERS 20

/* out = Rz(deg) in (out may be in). */
static void rotz(double deg, const double in[3], double out[3])
{
        double a = isnan(deg) ? 0 : deg * DEG, x = in[0], y = in[1];

        out[0] = cos(a) * x - sin(a) * y;
        out[1] = sin(a) * x + cos(a) * y;
        out[2] = in[2];
}

/* R = R Rz(deg): a world-to-camera rotation made object-to-camera at turntable angle deg. */
static void compose_rotz(double R[9], double deg)
{
        for (int r = 0; r < 3; r++) {
                double row[3] = {R[3 * r], R[3 * r + 1], R[3 * r + 2]}, a = deg * DEG;
                /* row * Rz(a): columns of Rz are (cos, sin, 0), (-sin, cos, 0), (0, 0, 1) */
                R[3 * r] = row[0] * cos(a) + row[1] * sin(a);
                R[3 * r + 1] = -row[0] * sin(a) + row[1] * cos(a);
        }
}

/* The centre C = -R^T t of camera g and the point c0 of its optical axis nearest the z
 * axis (the object's centre), both in the object frame. */
static void camera_centre(const struct ap_camera *g, double C[3], double c0[3])
{
        double a[3] = {g->R[6], g->R[7], g->R[8]}, s;

        for (int k = 0; k < 3; k++)
                C[k] = -(g->R[k] * g->t[0] + g->R[3 + k] * g->t[1] + g->R[6 + k] * g->t[2]);
        /* minimise |(C + s a)_xy|: s = -(C_xy . a_xy) / |a_xy|^2; along z for a vertical axis */
        s = a[0] * a[0] + a[1] * a[1] > 1e-12
                    ? -(C[0] * a[0] + C[1] * a[1]) / (a[0] * a[0] + a[1] * a[1])
                    : -C[2] / a[2];
        for (int k = 0; k < 3; k++)
                c0[k] = C[k] + s * a[k];
}

void fit_camera_centre(const struct ap_camera *g, double c0[3])
{
        double C[3];

        camera_centre(g, C, c0);
}

static void view_dir(const struct ap_camera *g, double dir[3])
{
        double C[3], c0[3], n;

        camera_centre(g, C, c0);
        n = hypot(hypot(C[0] - c0[0], C[1] - c0[1]), C[2] - c0[2]);
        for (int k = 0; k < 3; k++)
                dir[k] = (C[k] - c0[k]) / n;
}

/* The nominal camera of rig camera cc at camera-arm angle arm and turntable angle tt. */
static void nominal_camera(const struct rig_camera_conf *cc, double tt, double arm,
                           struct ap_camera *g)
{
        *g = (struct ap_camera){.width = cc->width,
                                .height = cc->height,
                                .fx = cc->fx,
                                .fy = cc->fy,
                                .cx = cc->cx,
                                .cy = cc->cy};
        memcpy(g->dist, cc->dist, sizeof(g->dist));
        riggeom_camera_pose(cc, isnan(arm) ? 0 : arm, g->R, g->t);
        compose_rotz(g->R, isnan(tt) ? 0 : tt);
}

#ifdef AP_CALFILE
/* The calibrated camera (cameras.<name> and turntables.<name>) when the file has both. */
static bool calibrated_camera(const struct cal_file *f, const struct rig_camera_conf *cc, double tt,
                              double arm, struct ap_camera *g)
{
        const struct cal_camera *k = cal_file_camera(f, cc->name);
        const struct cal_file_turntable *t = cal_file_turntable(f, cc->name);

        if (!k || !t)
                return false;
        *g = (struct ap_camera){.width = k->width,
                                .height = k->height,
                                .fx = k->k.fx,
                                .fy = k->k.fy,
                                .cx = k->k.cx,
                                .cy = k->k.cy};
        memcpy(g->dist, k->k.dist, sizeof(g->dist));
        memcpy(g->R, t->tt.R, sizeof(g->R));
        memcpy(g->t, t->tt.t, sizeof(g->t));
        /* x_cam = R Rz(-arm) Rz(tt) x_obj + t: the camera turns with its arm */
        compose_rotz(g->R, (isnan(tt) ? 0 : tt) - (isnan(arm) ? 0 : arm));
        return true;
}

static bool calibrated_lamp(const struct cal_file *f, const char *name, double arm, double p[3])
{
        const struct cal_lamp_pos *l = cal_file_lamp(f, name);

        if (l)
                rotz(arm, l->pos, p);
        return l != NULL;
}
#endif

/* Lamp l's position in the object frame of view v and light arm angle arm. */
static void lamp_position(const struct fit_ctx *c, const void *cal, const struct fit_view *v, int l,
                          double arm, double p[3], size_t *n_cal)
{
        const struct rig_switch_conf *lc = &c->rc->lamps[l];
        bool done = false;

#ifdef AP_CALFILE
        done = cal && calibrated_lamp(cal, lc->name, arm, p);
#endif
        *n_cal += done;
        if (!done)
                riggeom_lamp_position(lc, isnan(arm) ? 0 : arm, p);
        rotz(isnan(v->tt_deg) ? 0 : -v->tt_deg, p, p);
}

/* The median distance and intensity of the lights: the light T is relative to. */
static int reference_light(struct fit_ctx *c, size_t n)
{
        _cleanup_free_ double *d = calloc(n + 1, sizeof(double));
        _cleanup_free_ double *in = calloc(n + 1, sizeof(double));
        size_t j = 0;

        if (!d || !in)
                return -ENOMEM;
        for (size_t i = 0; i < c->n_views; i++)
                for (size_t k = 0; k < c->views[i].n_lights; k++, j++) {
                        const struct fit_light *l = &c->views[i].lights[k];
                        d[j] = hypot(hypot(l->pos[0], l->pos[1]), l->pos[2]);
                        in[j] = c->rc->lamps[l->lamp].intensity > 0
                                        ? c->rc->lamps[l->lamp].intensity
                                        : 1;
                }
        qsort(d, j, sizeof(double), gn_cmp_double);
        qsort(in, j, sizeof(double), gn_cmp_double);
        c->d_ref = d[j / 2];
        c->i_ref = in[j / 2];
        for (size_t i = 0; i < c->n_views; i++)
                for (size_t k = 0; k < c->views[i].n_lights; k++) {
                        struct fit_light *l = &c->views[i].lights[k];
                        l->scale = (c->rc->lamps[l->lamp].intensity > 0
                                            ? c->rc->lamps[l->lamp].intensity
                                            : 1) /
                                   c->i_ref;
                }
        return 0;
}

/* Places every view's camera and lights with cal (a struct cal_file, or NULL: nominal). */
static int place(struct fit_ctx *c, const void *cal, const char *source)
{
        size_t n_lights = 0, n_cal_lamps = 0, n_cal_cams = 0;

        for (size_t i = 0; i < c->n_views; i++) {
                struct fit_view *v = &c->views[i];
                const struct rig_camera_conf *cc = &c->rc->cameras[v->cam];
                bool done = false;
#ifdef AP_CALFILE
                done = cal && calibrated_camera(cal, cc, v->tt_deg, v->arm_deg, &v->geom);
#endif
                n_cal_cams += done;
                if (!done)
                        nominal_camera(cc, v->tt_deg, v->arm_deg, &v->geom);
                view_dir(&v->geom, v->dir);
                for (size_t k = 0; k < v->n_lights; k++, n_lights++)
                        lamp_position(c, cal, v, v->lights[k].lamp, v->lights[k].arm_deg,
                                      v->lights[k].pos, &n_cal_lamps);
        }
        if (n_cal_cams < c->n_views || n_cal_lamps < n_lights)
                fit_note(c,
                         "geometry: %s: %zu of %zu views' cameras and %zu of %zu lights' "
                         "lamps calibrated, the rest nominal (the rig file's)",
                         source, n_cal_cams, c->n_views, n_cal_lamps, n_lights);
        return reference_light(c, n_lights);
}

int fit_geometry(struct fit_ctx *c)
{
        const char *given = c->o->calibration;
        char path[4200];

        if (given && strcmp(given, "nominal") == 0)
                return place(c, NULL, "--calibration nominal");
        snprintf(path, sizeof(path), "%s/calibration.yaml", c->dir);
        if (given)
                snprintf(path, sizeof(path), "%s", given);
#ifdef AP_CALFILE
        _cleanup_free_ struct cal_file *f = calloc(1, sizeof(*f));
        char msg[512];
        int r;

        if (!f)
                return -ENOMEM;
        r = cal_file_read(path, f, msg, sizeof(msg));
        if (r == -ENOENT && !given)
                return place(c, NULL, "no calibration file");
        if (r < 0) {
                snprintf(c->err, sizeof(c->err), "%s: %s", path, r == -ENOENT ? strerror(-r) : msg);
                return r;
        }
        return place(c, f, path);
#else
        if (given) {
                snprintf(c->err, sizeof(c->err), "%s: built without calibration files (OpenCV)",
                         path);
                return -EOPNOTSUPP;
        }
        return place(c, NULL, "built without calibration files");
#endif
}

/* ---- the mesh and the tiles' surface points ---- */

void fit_mesh_free(struct fit_mesh *m)
{
        free(m->v);
        free(m->tri);
        *m = (struct fit_mesh){0};
}

int fit_mesh_read(struct fit_ctx *c)
{
        char path[4200], err[256];
        struct sim_mesh m;
        int r;

        snprintf(path, sizeof(path), "%s/%s", c->dir, SCAN_FILE_MESH_PLY);
        if (c->o->mesh)
                snprintf(path, sizeof(path), "%s", c->o->mesh);
        if (!c->o->mesh && access(path, F_OK) != 0) {
                fit_note(c, "surface: no mesh.ply: the light's direction and distance taken at "
                            "the nominal object point of each tile");
                return 0;
        }
        r = sim_mesh_read(path, &m, err, sizeof(err)); /* the project's one mesh reader */
        if (r == 0 && m.nt == 0) {
                free(m.pos);
                free(m.idx);
                snprintf(err, sizeof(err), "%s: a mesh without faces", path);
                r = -EBADMSG;
        }
        if (r < 0) {
                snprintf(c->err, sizeof(c->err), "%s", err);
                return r;
        }
        c->mesh = (struct fit_mesh){.v = m.pos, .tri = m.idx, .n_v = m.nv, .n_tri = m.nt};
        return 0;
}

bool ap_camera_project(const struct ap_camera *g, const double x[3], double uv[2], double *z)
{
        double p[3], r2, radial, xd, yd, a, b;

        for (int k = 0; k < 3; k++)
                p[k] = g->R[3 * k] * x[0] + g->R[3 * k + 1] * x[1] + g->R[3 * k + 2] * x[2] +
                       g->t[k];
        if (p[2] <= 1e-9)
                return false;
        a = p[0] / p[2], b = p[1] / p[2], r2 = a * a + b * b;
        radial = 1 + r2 * (g->dist[0] + r2 * (g->dist[1] + r2 * g->dist[4]));
        xd = a * radial + 2 * g->dist[2] * a * b + g->dist[3] * (r2 + 2 * a * a);
        yd = b * radial + g->dist[2] * (r2 + 2 * b * b) + 2 * g->dist[3] * a * b;
        uv[0] = g->fx * xd + g->cx;
        uv[1] = g->fy * yd + g->cy;
        if (z)
                *z = p[2];
        return true;
}

/* The tiles of view v: count across and down, and the centre pixel of tile (tx, ty). */
static void tile_centre(const struct fit_ctx *c, const struct fit_view *v, int tx, int ty,
                        double uv[2])
{
        int T = c->o->tile;

        uv[0] = tx * T + (MIN(T, v->geom.width - tx * T) - 1) / 2.0;
        uv[1] = ty * T + (MIN(T, v->geom.height - ty * T) - 1) / 2.0;
}

/* Tests triangle (a, b, c) (pixels p, depths z, object points X) against every tile centre
 * in its bounding box, keeping the nearest hit per tile in depth and v->points. */
static void raster_tri(const struct fit_ctx *c, struct fit_view *v, double (*p)[2], const double *z,
                       const double (*X)[3], float *depth)
{
        int T = c->o->tile, tw = (v->geom.width + T - 1) / T, th = (v->geom.height + T - 1) / T;
        double area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) -
                      (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
        double lo[2] = {fmin(fmin(p[0][0], p[1][0]), p[2][0]),
                        fmin(fmin(p[0][1], p[1][1]), p[2][1])};
        double hi[2] = {fmax(fmax(p[0][0], p[1][0]), p[2][0]),
                        fmax(fmax(p[0][1], p[1][1]), p[2][1])};

        if (fabs(area) < 1e-12)
                return;
        for (int ty = MAX(0, (int)(lo[1] / T) - 1); ty < th && ty * T <= hi[1]; ty++)
                for (int tx = MAX(0, (int)(lo[0] / T) - 1); tx < tw && tx * T <= hi[0]; tx++) {
                        double q[2], w[3], d;
                        tile_centre(c, v, tx, ty, q);
                        for (int i = 0; i < 3; i++) {
                                const double *a = p[(i + 1) % 3], *b = p[(i + 2) % 3];
                                w[i] = ((b[0] - a[0]) * (q[1] - a[1]) -
                                        (q[0] - a[0]) * (b[1] - a[1])) /
                                       area;
                        }
                        if (w[0] < -1e-9 || w[1] < -1e-9 || w[2] < -1e-9)
                                continue;
                        d = w[0] * z[0] + w[1] * z[1] + w[2] * z[2];
                        if (d >= depth[ty * tw + tx])
                                continue;
                        depth[ty * tw + tx] = (float)d;
                        for (int k = 0; k < 3; k++)
                                v->points[3 * (ty * tw + tx) + k] =
                                        (float)(w[0] * X[0][k] + w[1] * X[1][k] + w[2] * X[2][k]);
                }
}

static int mesh_points(const struct fit_ctx *c, struct fit_view *v, size_t n_tiles)
{
        _cleanup_free_ float *depth = malloc(n_tiles * sizeof(float));

        if (!depth)
                return -ENOMEM;
        for (size_t i = 0; i < n_tiles; i++)
                depth[i] = INFINITY;
        for (size_t f = 0; f < c->mesh.n_tri; f++) {
                double p[3][2], z[3], X[3][3];
                bool front = true;
                for (int i = 0; i < 3 && front; i++) {
                        const float *x = &c->mesh.v[3 * c->mesh.tri[3 * f + i]];
                        X[i][0] = x[0], X[i][1] = x[1], X[i][2] = x[2];
                        front = ap_camera_project(&v->geom, X[i], p[i], &z[i]);
                }
                if (front)
                        raster_tri(c, v, p, z, (const double(*)[3])X, depth);
        }
        return 0;
}

/* The object-frame ray of pixel uv of camera g: origin C and direction d (unit). */
static void pixel_ray(const struct ap_camera *g, const double uv[2], double C[3], double d[3])
{
        double xd = (uv[0] - g->cx) / g->fx, yd = (uv[1] - g->cy) / g->fy, x = xd, y = yd, c0[3],
               dc[3], n;

        for (int it = 0; it < UNDIST_ITERS; it++) { /* invert the distortion by fixed point */
                double r2 = x * x + y * y;
                double radial = 1 + r2 * (g->dist[0] + r2 * (g->dist[1] + r2 * g->dist[4]));
                double dx = 2 * g->dist[2] * x * y + g->dist[3] * (r2 + 2 * x * x);
                double dy = g->dist[2] * (r2 + 2 * y * y) + 2 * g->dist[3] * x * y;
                x = (xd - dx) / radial;
                y = (yd - dy) / radial;
        }
        dc[0] = x, dc[1] = y, dc[2] = 1;
        camera_centre(g, C, c0);
        for (int k = 0; k < 3; k++)
                d[k] = g->R[k] * dc[0] + g->R[3 + k] * dc[1] + g->R[6 + k] * dc[2];
        n = hypot(hypot(d[0], d[1]), d[2]);
        for (int k = 0; k < 3; k++)
                d[k] /= n;
}

void fit_nominal_point(const struct ap_camera *g, const double c0[3], const double uv[2],
                       double X[3])
{
        double o[3], d[3], s;

        pixel_ray(g, uv, o, d);
        s = (c0[0] - o[0]) * d[0] + (c0[1] - o[1]) * d[1] + (c0[2] - o[2]) * d[2];
        for (int k = 0; k < 3; k++)
                X[k] = o[k] + s * d[k];
}

/* Where the mesh gave none (or there is no mesh): the point of each tile's centre ray
 * nearest the object's centre. */
static void nominal_points(const struct fit_ctx *c, struct fit_view *v)
{
        int T = c->o->tile, tw = (v->geom.width + T - 1) / T, th = (v->geom.height + T - 1) / T;
        double c0[3];

        fit_camera_centre(&v->geom, c0);
        for (int ty = 0; ty < th; ty++)
                for (int tx = 0; tx < tw; tx++) {
                        double uv[2], X[3];
                        if (!isnan(v->points[3 * (ty * tw + tx)]))
                                continue;
                        tile_centre(c, v, tx, ty, uv);
                        fit_nominal_point(&v->geom, c0, uv, X);
                        for (int k = 0; k < 3; k++)
                                v->points[3 * (ty * tw + tx) + k] = (float)X[k];
                }
}

int fit_tile_points(const struct fit_ctx *c, struct fit_view *v)
{
        int T = c->o->tile;
        size_t n = (size_t)((v->geom.width + T - 1) / T) * ((v->geom.height + T - 1) / T);

        v->points = malloc(n * 3 * sizeof(float));
        if (!v->points)
                return -ENOMEM;
        for (size_t i = 0; i < 3 * n; i++)
                v->points[i] = NAN;
        if (c->mesh.n_tri > 0 && mesh_points(c, v, n) < 0)
                return -ENOMEM;
        nominal_points(c, v);
        return 0;
}
