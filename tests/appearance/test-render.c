/* test-render.c - the renderer (appearance/render.h) on models built by hand: a ground square
 * with a floating plate over it (so that views see the ground hidden), weight images
 * ray-cast here from known functions of the surface point (and of the view direction), and
 * every rendered pixel compared with the same functions evaluated at the point its camera
 * sees: views blended, hidden views dropped, distortion on both sides, point, directional
 * and environment lights, per-pixel and per-object view modes, bad arguments. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/model.h"
#include "appearance/render.h"
#include "appearance/sh.h"
#include "appearance/views.h"
#include "common/cleanup.h"
#include "tests/test.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_renderer *, ap_renderer_free);

#define ORDER      3
#define K          2
#define GROUND     60.0 /* half side, z = 0 */
#define PLATE      15.0 /* half side, z = PLATE_Z */
#define PLATE_Z    30.0
#define VIEW_DEP_X 0.10 /* W_0 += c . dir of the view (view-dependent models) */
#define VIEW_DEP_Y 0.05
#define VIEW_DEP_Z 0.08

static const struct ap_camera view_intr = {80, 60, 90, 90, 39.5, 29.5, {-0.05, 0.01, 0, 0, 0}};
static const struct ap_camera out_intr = {96, 72, 100, 100, 47.5, 35.5, {0}};

/* The undistorted normalised ray of pixel (u, v) of c, by Newton's method on the distortion. */
static void pixel_ray(const struct ap_camera *c, double u, double v, double r[2])
{
        double xd = (u - c->cx) / c->fx, yd = (v - c->cy) / c->fy, x = xd, y = yd;

        for (int it = 0; it < 50; it++) {
                double r2 = x * x + y * y, k = 1 + c->dist[0] * r2 + c->dist[1] * r2 * r2;
                double dk = 2 * c->dist[0] + 4 * c->dist[1] * r2; /* d k / d r2 */
                double fx = x * k - xd, fy = y * k - yd;
                double a = k + 2 * x * x * dk, b = 2 * x * y * dk, d = k + 2 * y * y * dk;
                double det = a * d - b * b;
                x -= (d * fx - b * fy) / det;
                y -= (a * fy - b * fx) / det;
        }
        r[0] = x, r[1] = y;
}

/* Ray-casts pixel (u, v) of c on the ground and (with plate) the plate: the point in p. */
static bool cast(const struct ap_camera *c, double u, double v, bool plate, double p[3])
{
        double n[2], d[3], o[3], best = INFINITY;

        pixel_ray(c, u, v, n);
        for (int i = 0; i < 3; i++) {
                d[i] = c->R[i] * n[0] + c->R[3 + i] * n[1] + c->R[6 + i];
                o[i] = -(c->R[i] * c->t[0] + c->R[3 + i] * c->t[1] + c->R[6 + i] * c->t[2]);
        }
        for (int s = 0; s < (plate ? 2 : 1); s++) {
                double z = s ? PLATE_Z : 0, h = s ? PLATE : GROUND, t = (z - o[2]) / d[2];
                double x = o[0] + t * d[0], y = o[1] + t * d[1];
                if (t > 0 && t < best && fabs(x) <= h && fabs(y) <= h) {
                        best = t;
                        p[0] = x, p[1] = y, p[2] = z;
                }
        }
        return isfinite(best);
}

/* The weights' surface functions. */
static void g_of(const double p[3], float *w)
{
        w[0] = (float)(0.3 + 0.004 * p[0]);
        w[1] = (float)(-0.2 + 0.003 * p[1] + 0.01 * p[2]);
}

static void view_camera(double az, double el, const struct ap_camera *intr, struct ap_camera *c)
{
        double a = az * M_PI / 180, e = el * M_PI / 180, eye[3], o[3] = {0, 0, 0};

        eye[0] = 400 * cos(e) * cos(a), eye[1] = 400 * cos(e) * sin(a), eye[2] = 400 * sin(e);
        CHECK_INT(ap_camera_look_at(intr, eye, o, c), 0);
}

/* 6 azimuths x 3 elevations, weights ray-cast; view_dep adds the view's direction term. */
static struct ap_model *hand_model(bool plate, bool view_dep)
{
        static const double els[] = {35, 60, 82};
        struct ap_model *m = NULL;
        size_t n = 0;

        CHECK_INT(ap_model_new(ORDER, K, 18, &m), 0);
        for (int i = 0; i < 3 * ORDER * ORDER; i++) {
                m->mean[i] = (float)(0.5 / (1 + i));
                m->basis[i] = (float)(0.2 * sin(i + 1.0));
                m->basis[3 * ORDER * ORDER + i] = (float)(0.3 * cos(2.0 * i));
        }
        m->light_distance_mm = 500, m->light_intensity = 2;
        for (int e = 0; e < 3; e++)
                for (int a = 0; a < 6; a++, n++) {
                        struct ap_view *v = &m->views[n];
                        double len;
                        view_camera(60.0 * a + 11 * e, els[e], &view_intr, &v->cam);
                        for (int i = 0; i < 3; i++)
                                v->dir[i] = -(v->cam.R[i] * v->cam.t[0] +
                                              v->cam.R[3 + i] * v->cam.t[1] +
                                              v->cam.R[6 + i] * v->cam.t[2]);
                        len = sqrt(v->dir[0] * v->dir[0] + v->dir[1] * v->dir[1] +
                                   v->dir[2] * v->dir[2]);
                        for (int i = 0; i < 3; i++)
                                v->dir[i] /= len;
                        CHECK_INT(ap_view_alloc(v, K), 0);
                        for (int y = 0; y < v->cam.height; y++)
                                for (int x = 0; x < v->cam.width; x++) {
                                        size_t i = (size_t)y * v->cam.width + x;
                                        double p[3];
                                        if (!cast(&v->cam, x, y, plate, p))
                                                continue;
                                        v->mask[i] = 1;
                                        g_of(p, &v->weights[i * K]);
                                        if (view_dep)
                                                v->weights[i * K] +=
                                                        (float)(VIEW_DEP_X * v->dir[0] +
                                                                VIEW_DEP_Y * v->dir[1] +
                                                                VIEW_DEP_Z * v->dir[2]);
                                }
                }
        return m;
}

static struct ap_mesh hand_mesh(bool plate)
{
        static const float q[2][4] = {{GROUND, 0}, {PLATE, PLATE_Z}};
        struct ap_mesh me = {plate ? 8 : 4, plate ? 4 : 2, malloc(3 * 8 * sizeof(float)),
                             malloc(3 * 4 * sizeof(uint32_t))};

        CHECK(me.pos && me.idx);
        for (int s = 0; s < (plate ? 2 : 1); s++) {
                for (int c = 0; c < 4; c++) {
                        me.pos[3 * (4 * s + c)] = (c == 1 || c == 2) ? q[s][0] : -q[s][0];
                        me.pos[3 * (4 * s + c) + 1] = c >= 2 ? q[s][0] : -q[s][0];
                        me.pos[3 * (4 * s + c) + 2] = q[s][1];
                }
                uint32_t t[6] = {0, 1, 2, 0, 2, 3};
                for (int i = 0; i < 6; i++)
                        me.idx[6 * s + i] = (uint32_t)(4 * s) + t[i];
        }
        return me;
}

/* L(l, k, c) computed here: the model's rows against Y(l), or against env coefficients. */
static void light_rows(const struct ap_model *m, const double *y, bool env, double *out)
{
        int mm = m->n_coef;

        for (int k = 0; k <= K; k++)
                for (int c = 0; c < 3; c++) {
                        const float *row = k ? &m->basis[(k - 1) * 3 * mm] : m->mean;
                        double s = 0;
                        for (int i = 0; i < mm; i++)
                                s += row[i * 3 + c] * y[env ? i * 3 + c : i];
                        out[k * 3 + c] = s;
                }
}

struct expect {
        const struct ap_model *m;
        const struct ap_views *views;
        const struct ap_light *light;
        enum ap_view_mode mode;
        bool plate, view_dep;
        double centre[3];
};

/* The expected value of output pixel (x, y) of cam; false where the camera sees nothing. */
static bool expected(const struct expect *e, const struct ap_camera *cam, int x, int y,
                     double rgb[3])
{
        double p[3], eye[3], v[3], Lr[(K + 1) * 3], yl[ORDER * ORDER], s = 1, l[3], len = 0;
        float w[K], vf[3], vw[3];
        int idx[3];

        if (!cast(cam, x, y, e->plate, p))
                return false;
        g_of(p, w);
        for (int i = 0; i < 3; i++)
                eye[i] = -(cam->R[i] * cam->t[0] + cam->R[3 + i] * cam->t[1] +
                           cam->R[6 + i] * cam->t[2]);
        for (int i = 0; i < 3; i++)
                v[i] = eye[i] - (e->mode == AP_VIEW_PIXEL ? p[i] : e->centre[i]),
                len += v[i] * v[i];
        for (int i = 0; i < 3; i++)
                vf[i] = (float)(v[i] / sqrt(len));
        if (e->view_dep) {
                int n = ap_views_weights(e->views, vf, idx, vw);
                for (int j = 0; j < n; j++)
                        w[0] += vw[j] * (float)(VIEW_DEP_X * e->m->views[idx[j]].dir[0] +
                                                VIEW_DEP_Y * e->m->views[idx[j]].dir[1] +
                                                VIEW_DEP_Z * e->m->views[idx[j]].dir[2]);
        }
        if (e->light->kind == AP_LIGHT_ENV) {
                light_rows(e->m, e->light->env, true, Lr);
        } else {
                double r2 = 0;
                for (int i = 0; i < 3; i++) {
                        l[i] = e->light->kind == AP_LIGHT_POINT ? e->light->v[i] - p[i]
                                                                : e->light->v[i];
                        r2 += l[i] * l[i];
                }
                for (int i = 0; i < 3; i++)
                        l[i] /= sqrt(r2);
                ap_sh_eval(ORDER, l, yl);
                light_rows(e->m, yl, false, Lr);
                s = e->light->intensity / e->m->light_intensity;
                if (e->light->kind == AP_LIGHT_POINT)
                        s *= e->m->light_distance_mm * e->m->light_distance_mm / r2;
        }
        for (int c = 0; c < 3; c++)
                rgb[c] = s * (Lr[c] + w[0] * Lr[3 + c] + w[1] * Lr[6 + c]);
        return true;
}

/* Renders at (az, el) and compares with expected() away from the output's silhouettes: the
 * rendered mask covers the object; no pixel is off by more than 10 tol and at most 5% by more
 * than tol (relative to the image's largest value: the views' bilinear taps are fewer where
 * the surface is cut by an occlusion edge in a view). Returns the largest error. */
static double compare(struct ap_renderer *r, const struct expect *e, const struct ap_camera *intr,
                      double az, double el, double tol)
{
        struct ap_camera cam;
        size_t n = (size_t)intr->width * intr->height, inner = 0, covered = 0, over = 0;
        _cleanup_free_ float *rgb = malloc(3 * n * sizeof(float));
        _cleanup_free_ uint8_t *mask = malloc(n);
        _cleanup_free_ double *err = calloc(n, sizeof(double));
        double worst = 0, peak = 1e-9;

        view_camera(az, el, intr, &cam);
        CHECK(rgb && mask && err);
        CHECK_INT(ap_render(r, &cam, e->light, e->mode, 2, rgb, mask), 0);
        for (int y = 1; y + 1 < cam.height; y++)
                for (int x = 1; x + 1 < cam.width; x++) {
                        double want[3], p[3], q[3];
                        size_t i = (size_t)y * cam.width + x;
                        bool edge = !cast(&cam, x, y, e->plate, p);
                        for (int j = 0; j < 9 && !edge; j++) /* neighbours see the same face */
                                edge = !cast(&cam, x + j % 3 - 1, y + j / 3 - 1, e->plate, q) ||
                                       q[2] != p[2];
                        if (edge || !expected(e, &cam, x, y, want))
                                continue;
                        inner++;
                        covered += mask[i];
                        for (int c = 0; c < 3 && mask[i]; c++) {
                                err[i] = fmax(err[i], fabs(rgb[3 * i + c] - want[c]));
                                peak = fmax(peak, fabs(want[c]));
                        }
                }
        for (size_t i = 0; i < n; i++) {
                worst = fmax(worst, err[i] / peak);
                over += err[i] / peak > tol;
        }
        fprintf(stderr, "view %g,%g: %zu pixels, %zu covered, %zu over %g, worst %.2e\n", az, el,
                inner, covered, over, tol, worst);
        CHECK(inner > 200);
        CHECK(covered >= inner * 0.97);
        CHECK(over <= inner / 20);
        CHECK(worst <= 10 * tol);
        return worst;
}

static void run_case(bool plate, bool view_dep, enum ap_view_mode mode, const struct ap_light *l,
                     const struct ap_camera *intr, double tol)
{
        _cleanup_(ap_model_freep) struct ap_model *m = hand_model(plate, view_dep);
        _cleanup_(ap_renderer_freep) struct ap_renderer *r = NULL;
        struct ap_mesh me = hand_mesh(plate);
        struct expect e = {m, NULL, l, mode, plate, view_dep, {0}};
        static const double poses[][2] = {{25, 50}, {150, 40}, {260, 70}, {60.0 * 2 + 11, 60}};

        CHECK_INT(ap_renderer_new(m, &me, &r), 0);
        e.views = ap_renderer_views(r);
        ap_renderer_centre(r, e.centre);
        for (size_t i = 0; i < ELEMENTSOF(poses); i++)
                compare(r, &e, intr, poses[i][0], poses[i][1], tol);
        ap_renderer_free(TAKE_PTR(r));
        ap_mesh_free(&me);
}

static const struct ap_light dir_light = {AP_LIGHT_DIRECTIONAL, {0.3, -0.2, 0.9}, 3, NULL};

/* Views hidden by the plate are dropped: the ground under it still gets its own values. */
static void test_occlusion(void)
{
        run_case(true, false, AP_VIEW_PIXEL, &dir_light, &out_intr, 4e-3);
}

/* Per-pixel and per-object view modes against a view-dependent model; distorted output. */
static void test_modes(void)
{
        struct ap_camera dist = out_intr;

        dist.dist[0] = 0.08, dist.dist[2] = 0.002;
        run_case(false, true, AP_VIEW_PIXEL, &dir_light, &out_intr, 2e-3);
        run_case(false, true, AP_VIEW_OBJECT, &dir_light, &out_intr, 2e-3);
        run_case(false, true, AP_VIEW_PIXEL, &dir_light, &dist, 2e-3);
}

/* A point light (falloff and l per pixel, through the cube map) and an environment map. */
static void test_lights(void)
{
        struct ap_light pt = {AP_LIGHT_POINT, {120, -80, 260}, 2.5, NULL};
        double env[3 * ORDER * ORDER];
        struct ap_light el = {AP_LIGHT_ENV, {0}, 0, env};

        for (int i = 0; i < 3 * ORDER * ORDER; i++)
                env[i] = 0.4 * cos(1.7 * i);
        run_case(true, false, AP_VIEW_PIXEL, &pt, &out_intr, 1e-2);
        run_case(true, false, AP_VIEW_PIXEL, &el, &out_intr, 4e-3);
}

static void test_args(void)
{
        _cleanup_(ap_model_freep) struct ap_model *m = hand_model(false, false);
        _cleanup_(ap_renderer_freep) struct ap_renderer *r = NULL;
        struct ap_mesh me = hand_mesh(false), empty = {0};
        struct ap_camera cam, bad = out_intr;
        struct ap_light nodir = {AP_LIGHT_DIRECTIONAL, {0, 0, 0}, 1, NULL};
        struct ap_light noenv = {AP_LIGHT_ENV, {0}, 0, NULL};
        float rgb[3 * 96 * 72];
        uint8_t mask[96 * 72];

        CHECK_INT(ap_renderer_new(m, &empty, &r), -EINVAL);
        CHECK_INT(ap_renderer_new(m, &me, &r), 0);
        view_camera(10, 40, &out_intr, &cam);
        CHECK_INT(ap_render(r, &cam, &nodir, AP_VIEW_PIXEL, 1, rgb, mask), -EINVAL);
        CHECK_INT(ap_render(r, &cam, &noenv, AP_VIEW_PIXEL, 1, rgb, mask), -EINVAL);
        CHECK_INT(ap_render(r, &cam, &dir_light, AP_VIEW_PIXEL, 0, rgb, mask), -EINVAL);
        bad.fx = 0;
        CHECK_INT(ap_render(r, &bad, &dir_light, AP_VIEW_PIXEL, 1, rgb, mask), -EINVAL);
        CHECK_INT(ap_render(r, &cam, &dir_light, AP_VIEW_OBJECT, 1, rgb, mask), 0);
        ap_mesh_free(&me);
        free(m->views[3].weights);
        m->views[3].weights = NULL;
        ap_renderer_free(TAKE_PTR(r));
        me = hand_mesh(false);
        CHECK_INT(ap_renderer_new(m, &me, &r), -EINVAL);
        ap_mesh_free(&me);
}

/* A cube of side 2h about c, each face's corners its own vertices (welded by position),
 * wound counter-clockwise seen from outside; with open, one face left out. */
static struct ap_mesh cube(double h, const double c[3], bool open)
{
        struct ap_mesh m = {24, open ? 10 : 12, malloc(72 * sizeof(float)),
                            malloc(36 * sizeof(uint32_t))};

        CHECK(m.pos && m.idx);
        for (int f = 0; f < 6; f++) { /* axis f / 2, side +-1 */
                int ax = f / 2, u = (ax + 1) % 3, v = (ax + 2) % 3;
                double sg = f % 2 ? -1 : 1;
                for (int k = 0; k < 4; k++) {
                        double q[3];
                        q[ax] = sg;
                        q[u] = (k == 1 || k == 2) ? 1 : -1;
                        q[v] = (k >= 2 ? 1 : -1) * sg; /* counter-clockwise about +-axis */
                        for (int j = 0; j < 3; j++)
                                m.pos[3 * (4 * f + k) + j] = (float)(c[j] + h * q[j]);
                }
                if (open && f == 5)
                        break;
                uint32_t t[6] = {0, 1, 2, 0, 2, 3};
                for (int i = 0; i < 6; i++)
                        m.idx[6 * f + i] = (uint32_t)(4 * f) + t[i];
        }
        return m;
}

/* Closed surfaces are oriented and their back faces skipped with the same image; open ones
 * and inside-out ones are told apart. */
/* Rasterises m from 8 cameras around it with m->front as set and with 0 (both sides): the
 * same depth and triangles. Returns the pixels seen. */
static size_t cull_same(struct ap_mesh *m)
{
        size_t n = (size_t)out_intr.width * out_intr.height, seen = 0;
        _cleanup_free_ float *d0 = malloc(n * sizeof(float)), *d1 = malloc(n * sizeof(float));
        _cleanup_free_ int32_t *t0 = malloc(n * sizeof(int32_t)), *t1 = malloc(n * sizeof(int32_t));
        int front = m->front;

        CHECK(d0 && d1 && t0 && t1);
        for (int v = 0; v < 8; v++) {
                struct ap_camera cam;
                struct ap_pinhole ph = {out_intr.width, out_intr.height, out_intr.fx,
                                        out_intr.fy,    out_intr.cx,     out_intr.cy};
                view_camera(45.0 * v + 10, v % 2 ? 50 : -30, &out_intr, &cam);
                memcpy(ph.R, cam.R, sizeof(ph.R));
                memcpy(ph.t, cam.t, sizeof(ph.t));
                m->front = 0;
                CHECK_INT(ap_raster(m, &ph, d0, t0), 0);
                m->front = front;
                CHECK_INT(ap_raster(m, &ph, d1, t1), 0);
                for (size_t i = 0; i < n; i++) {
                        CHECK(t0[i] == t1[i] && (d0[i] == d1[i] || isinf(d0[i])));
                        seen += t0[i] >= 0;
                }
        }
        return seen;
}

/* Closed surfaces are oriented (either winding) and their back faces skipped with the same
 * image; open ones are left two-sided. */
static void test_cull(void)
{
        static const double c[3] = {10, -5, 20};
        struct ap_mesh m = cube(30, c, false), open = cube(30, c, true);

        CHECK_INT(ap_mesh_orient(&open), 0);
        CHECK_INT(open.front, 0);
        CHECK_INT(ap_mesh_orient(&m), 0);
        CHECK_INT(m.front, 1);
        CHECK(cull_same(&m) > 1000);        /* the cube is in the images */
        for (size_t t = 0; t < m.nt; t++) { /* inside out */
                uint32_t i = m.idx[3 * t + 1];
                m.idx[3 * t + 1] = m.idx[3 * t + 2];
                m.idx[3 * t + 2] = i;
        }
        CHECK_INT(ap_mesh_orient(&m), 0);
        CHECK_INT(m.front, -1);
        CHECK(cull_same(&m) > 1000);
        ap_mesh_free(&m);
        ap_mesh_free(&open);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"occlusion", test_occlusion}, {"modes", test_modes}, {"lights", test_lights},
                {"args", test_args},           {"cull", test_cull},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
