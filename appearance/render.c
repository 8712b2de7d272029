/* render.c - the renderer's setup (render.h): the views in single precision with their depth
 * maps, the mesh's face planes, the cube map of the light term L(l, k, c); and the light
 * terms of a frame. The per-pixel work is in render_px.c.
 *
 * DESIGN: everything that does not depend on the frame (triangulation, depth maps of the
 * sampled views, the L table) is built once in ap_renderer_new; a frame rasterises the mesh
 * once from its camera, then threads take bands of rows. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/cube.h"
#include "appearance/render_internal.h"
#include "appearance/sh.h"
#include "appearance/views.h"

/* L(l, k, c) of the model at unit direction l into out[(K + 1) * 3] (row 0 the mean). */
static void light_term(const struct ap_model *m, const double *y, int stride, float *out)
{
        int mm = m->n_coef;

        for (int k = 0; k <= m->k; k++) {
                const float *row = k ? &m->basis[(size_t)(k - 1) * 3 * mm] : m->mean;
                for (int c = 0; c < 3; c++) {
                        double s = 0;
                        for (int i = 0; i < mm; i++)
                                s += row[i * 3 + c] * y[i * stride + (stride == 3 ? c : 0)];
                        out[k * 3 + c] = (float)s;
                }
        }
}

void ap_render_light_dir(const struct ap_model *m, const double l[3], float *out)
{
        double y[AP_ORDER_MAX * AP_ORDER_MAX];

        ap_sh_eval(m->order, l, y);
        light_term(m, y, 1, out);
}

static int build_light_cube(struct ap_renderer *r)
{
        const int n = AP_RENDER_CUBE;
        size_t row = (size_t)(r->m->k + 1) * 3;

        r->cube = malloc(6 * (size_t)n * n * row * sizeof(float));
        if (!r->cube)
                return -ENOMEM;
        for (int face = 0; face < 6; face++)
                for (int it = 0; it < n; it++)
                        for (int is = 0; is < n; is++) {
                                float d[3];
                                double l[3], len;
                                ap_cube_dir(face, 2 * (is + 0.5f) / n - 1, 2 * (it + 0.5f) / n - 1,
                                            d);
                                len = sqrt((double)d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                                for (int j = 0; j < 3; j++)
                                        l[j] = d[j] / len;
                                ap_render_light_dir(
                                        r->m, l,
                                        &r->cube[(((size_t)face * n + it) * n + is) * row]);
                        }
        return 0;
}

static int build_planes(struct ap_renderer *r)
{
        const struct ap_mesh *me = r->mesh;
        double lo[3], hi[3];

        r->planes = malloc(4 * me->nt * sizeof(float));
        if (!r->planes)
                return -ENOMEM;
        for (size_t t = 0; t < me->nt; t++) {
                const float *a = &me->pos[3 * me->idx[3 * t]],
                            *b = &me->pos[3 * me->idx[3 * t + 1]],
                            *c = &me->pos[3 * me->idx[3 * t + 2]];
                double u[3], v[3], n[3], len;
                for (int j = 0; j < 3; j++)
                        u[j] = b[j] - a[j], v[j] = c[j] - a[j];
                n[0] = u[1] * v[2] - u[2] * v[1];
                n[1] = u[2] * v[0] - u[0] * v[2];
                n[2] = u[0] * v[1] - u[1] * v[0];
                len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                len = len > 0 ? len : 1;
                for (int j = 0; j < 3; j++)
                        r->planes[4 * t + j] = (float)(n[j] / len);
                r->planes[4 * t + 3] = (float)((n[0] * a[0] + n[1] * a[1] + n[2] * a[2]) / len);
        }
        ap_mesh_bounds(me, lo, hi);
        for (int j = 0; j < 3; j++)
                r->centre[j] = (lo[j] + hi[j]) / 2;
        return 0;
}

/* The vertex normals of a closed mesh (its winding says out: ap_mesh_vertex_normals), so that
 * what depends on the normal varies smoothly across faces. An open mesh keeps the faces'
 * normals (vnormals NULL). */
static int build_vertex_normals(struct ap_renderer *r)
{
        if (!r->mesh->front)
                return 0;
        r->vnormals = calloc(3 * r->mesh->nv, sizeof(float));
        if (!r->vnormals)
                return -ENOMEM;
        ap_mesh_vertex_normals(r->mesh, r->vnormals);
        return 0;
}

static int build_view(struct ap_renderer *r, size_t i)
{
        const struct ap_camera *c = &r->m->views[i].cam;
        struct rview *v = &r->rv[i];
        int mx = c->width / AP_RENDER_MARGIN, my = c->height / AP_RENDER_MARGIN;
        struct ap_pinhole ph = {c->width + 2 * mx, c->height + 2 * my, c->fx, c->fy,
                                c->cx + mx,        c->cy + my};

        if (!r->m->views[i].weights || !r->m->views[i].mask || c->width < 1 || c->height < 1 ||
            c->width > AP_RENDER_MAX_SIDE || c->height > AP_RENDER_MAX_SIDE)
                return -EINVAL;
        memcpy(ph.R, c->R, sizeof(ph.R));
        memcpy(ph.t, c->t, sizeof(ph.t));
        *v = (struct rview){.fx = (float)c->fx,
                            .fy = (float)c->fy,
                            .cx = (float)c->cx,
                            .cy = (float)c->cy,
                            .width = c->width,
                            .height = c->height,
                            .dw = ph.width,
                            .dh = ph.height,
                            .mx = (float)mx,
                            .my = (float)my,
                            .weights = r->m->views[i].weights,
                            .mask = r->m->views[i].mask};
        for (int j = 0; j < 9; j++)
                v->R[j] = (float)c->R[j];
        for (int j = 0; j < 3; j++)
                v->t[j] = (float)c->t[j];
        v->tol = (float)fmax(AP_RENDER_BIAS, AP_RENDER_SLOPE / c->fx);
        for (int j = 0; j < 5; j++) {
                v->dist[j] = (float)c->dist[j];
                v->distorted |= c->dist[j] != 0;
        }
        v->depth = malloc((size_t)ph.width * ph.height * sizeof(float));
        if (!v->depth)
                return -ENOMEM;
        return ap_raster(r->mesh, &ph, v->depth, NULL);
}

static int renderer_build(struct ap_renderer *r)
{
        const struct ap_model *m = r->m;
        double(*dirs)[3] = malloc(m->n_views * sizeof(*dirs));
        int ret;

        if (!dirs)
                return -ENOMEM;
        for (size_t i = 0; i < m->n_views; i++)
                memcpy(dirs[i], m->views[i].dir, sizeof(dirs[i]));
        ret = ap_views_new((const double(*)[3])dirs, m->n_views, &r->views);
        free(dirs);
        if (ret < 0)
                return ret;
        r->rv = calloc(m->n_views, sizeof(*r->rv));
        if (!r->rv)
                return -ENOMEM;
        for (size_t i = 0; i < m->n_views; i++)
                if ((ret = build_view(r, i)) < 0)
                        return ret;
        if ((ret = build_planes(r)) < 0 || (ret = build_vertex_normals(r)) < 0)
                return ret;
        return build_light_cube(r);
}

int ap_renderer_new(const struct ap_model *m, const struct ap_mesh *mesh, struct ap_renderer **ret)
{
        struct ap_renderer *r;
        int e;

        if (!m || !mesh || !ret || m->n_views == 0 || !m->views || mesh->nt == 0 || m->k < 0 ||
            m->k > AP_K_MAX || m->order < 1 || m->order > AP_ORDER_MAX)
                return -EINVAL;
        r = calloc(1, sizeof(*r));
        if (!r)
                return -ENOMEM;
        r->m = m;
        r->mesh = mesh;
        if ((e = renderer_build(r)) < 0) {
                ap_renderer_free(r);
                return e;
        }
        *ret = r;
        return 0;
}

struct ap_renderer *ap_renderer_free(struct ap_renderer *r)
{
        if (!r)
                return NULL;
        for (size_t i = 0; r->rv && i < r->m->n_views; i++)
                free(r->rv[i].depth);
        free(r->rv);
        ap_views_free(r->views);
        free(r->cube);
        free(r->planes);
        free(r->vnormals);
        free(r->ras_depth);
        free(r->ras_tri);
        free(r->rays);
        free(r);
        return NULL;
}

void ap_renderer_centre(const struct ap_renderer *r, double c[3])
{
        memcpy(c, r->centre, sizeof(r->centre));
}

const struct ap_views *ap_renderer_views(const struct ap_renderer *r)
{
        return r->views;
}

/* The frame's light: constant terms for directional and environment lights, the point
 * light's position and its (I / I0) d0^2 for the per-pixel falloff. */
static int frame_light(struct frame *f, const struct ap_light *l)
{
        const struct ap_model *m = f->r->m;
        double i0 = m->light_intensity > 0 ? m->light_intensity : 1;
        double s = (l->intensity > 0 ? l->intensity : i0) / i0, len;
        double d[3] = {l->v[0], l->v[1], l->v[2]};

        f->kind = l->kind;
        f->scale = (float)s;
        switch (l->kind) {
        case AP_LIGHT_POINT: {
                double d0 = m->light_distance_mm, dc[3];
                for (int j = 0; j < 3; j++)
                        dc[j] = d[j] - f->r->centre[j];
                if (!(d0 > 0)) /* no reference distance: the light's at the centre */
                        d0 = sqrt(dc[0] * dc[0] + dc[1] * dc[1] + dc[2] * dc[2]);
                f->scale = (float)(s * d0 * d0);
                for (int j = 0; j < 3; j++)
                        f->lpos[j] = (float)d[j];
                return isfinite(f->scale) ? 0 : -EINVAL;
        }
        case AP_LIGHT_DIRECTIONAL:
                len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                if (!(len > 0) || !isfinite(len))
                        return -EINVAL;
                for (int j = 0; j < 3; j++)
                        d[j] /= len;
                ap_render_light_dir(m, d, f->lconst);
                return 0;
        case AP_LIGHT_ENV:
                if (!l->env)
                        return -EINVAL;
                light_term(m, l->env, 3, f->lconst);
                f->scale = 1;
                return 0;
        }
        return -EINVAL;
}

/* The frame's camera: its centre and rotation to the object frame, the view weights of the
 * per-object mode. */
static int frame_camera(struct frame *f, const struct ap_camera *cam, enum ap_view_mode mode)
{
        float v[3];
        double len = 0;

        if (cam->width < 1 || cam->height < 1 || cam->width > AP_RENDER_MAX_SIDE ||
            cam->height > AP_RENDER_MAX_SIDE || !(cam->fx > 0) || !(cam->fy > 0))
                return -EINVAL;
        f->cam = cam;
        f->mode = mode;
        f->ifxy[0] = (float)(1 / cam->fx), f->ifxy[1] = (float)(1 / cam->fy);
        f->cxy[0] = (float)cam->cx, f->cxy[1] = (float)cam->cy;
        for (int i = 0; i < 3; i++) {
                double c = 0;
                for (int j = 0; j < 3; j++) {
                        f->Rt[i * 3 + j] = (float)cam->R[j * 3 + i];
                        c -= cam->R[j * 3 + i] * cam->t[j];
                }
                f->C[i] = (float)c;
                v[i] = (float)(c - f->r->centre[i]);
                len += (double)v[i] * v[i];
        }
        if (!(len > 0))
                return -EINVAL;
        for (int i = 0; i < 3; i++)
                v[i] /= (float)sqrt(len);
        f->on = ap_views_weights(f->r->views, v, f->oidx, f->ow);
        return 0;
}

int ap_render(struct ap_renderer *r, const struct ap_camera *cam, const struct ap_light *l,
              enum ap_view_mode mode, int threads, float *rgb, uint8_t *mask)
{
        struct frame f = {.r = r, .rgb = rgb, .mask = mask};
        int e;

        if (!r || !cam || !l || !rgb || !mask || threads < 1)
                return -EINVAL;
        if ((e = frame_camera(&f, cam, mode)) < 0 || (e = frame_light(&f, l)) < 0)
                return e;
        if ((e = render_prepare_raster(r, cam)) < 0)
                return e;
        return render_run(&f, threads);
}

int ap_camera_look_at(const struct ap_camera *intr, const double eye[3], const double target[3],
                      struct ap_camera *out)
{
        double f[3], up[3] = {0, 0, 1}, rt[3], dn[3], len;

        for (int i = 0; i < 3; i++)
                f[i] = target[i] - eye[i];
        len = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        if (!(len > 0))
                return -EINVAL;
        for (int i = 0; i < 3; i++)
                f[i] /= len;
        if (fabs(f[2]) > 1 - 1e-12)
                up[1] = 1, up[2] = 0;
        rt[0] = f[1] * up[2] - f[2] * up[1];
        rt[1] = f[2] * up[0] - f[0] * up[2];
        rt[2] = f[0] * up[1] - f[1] * up[0];
        len = sqrt(rt[0] * rt[0] + rt[1] * rt[1] + rt[2] * rt[2]);
        for (int i = 0; i < 3; i++)
                rt[i] /= len;
        dn[0] = f[1] * rt[2] - f[2] * rt[1];
        dn[1] = f[2] * rt[0] - f[0] * rt[2];
        dn[2] = f[0] * rt[1] - f[1] * rt[0];
        *out = *intr;
        for (int i = 0; i < 3; i++) {
                out->R[i] = rt[i], out->R[3 + i] = dn[i], out->R[6 + i] = f[i];
        }
        for (int i = 0; i < 3; i++)
                out->t[i] = -(out->R[3 * i] * eye[0] + out->R[3 * i + 1] * eye[1] +
                              out->R[3 * i + 2] * eye[2]);
        return 0;
}
