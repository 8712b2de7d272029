/* brdf_render.c - the view-kind BRDF model relit (brdf_render.h): the views around the output
 * camera's direction from the object's centre (one set of weights a frame), each output pixel's
 * nominal surface point (fit_nominal_point, as the fit placed the views' pixels) projected
 * into each of them, the nearest pixel's parameters evaluated (brdf.c) at that pixel's point
 * for the light and the output camera, and the views' values blended by their weights over the
 * views that have the pixel. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/brdf_render.h"
#include "appearance/fit_internal.h"

int ap_brdf_views_new(const struct ap_brdf_model *m, struct ap_views **ret)
{
        double(*dirs)[3];
        int r;

        if (!m || m->kind != AP_BRDF_KIND_VIEW || m->n_views == 0)
                return -EINVAL;
        if (!(dirs = malloc(m->n_views * sizeof(*dirs))))
                return -ENOMEM;
        for (size_t i = 0; i < m->n_views; i++)
                memcpy(dirs[i], m->views[i].dir, sizeof(dirs[i]));
        r = ap_views_new((const double(*)[3])dirs, m->n_views, ret);
        free(dirs);
        return r;
}

/* The value of view v's pixel nearest object point X, lit by L and seen from C, into out;
 * false where X projects outside v or on a masked pixel. */
static bool shade(const struct ap_brdf_model *m, const struct ap_brdf_view *v, const double X[3],
                  const float C[3], const struct ap_env_light *L, float out[3])
{
        const struct ap_brdf_texel *t;
        const float *P;
        float l[3], w[3], len = 0, e;
        double uv[2];
        long x, y;

        if (!ap_camera_project(&v->cam, X, uv, NULL))
                return false;
        x = lrint(uv[0]), y = lrint(uv[1]);
        if (x < 0 || y < 0 || x >= v->cam.width || y >= v->cam.height)
                return false;
        t = &v->px[(size_t)y * v->cam.width + x];
        P = &v->points[3 * ((size_t)y * v->cam.width + x)];
        if (t->flags & AP_BRDF_MASKED)
                return false;
        for (int k = 0; k < 3; k++)
                w[k] = C[k] - P[k], len += w[k] * w[k];
        for (int k = 0; k < 3; k++)
                w[k] /= sqrtf(len);
        e = ap_env_light_at(L, P, l) * (float)m->response;
        ap_brdf_eval(t, l, w, out);
        for (int k = 0; k < 3; k++)
                out[k] *= e;
        return true;
}

/* The views around cam's direction from m's centre: their count, indices and weights; the
 * camera's centre into C. */
static int frame_views(const struct ap_brdf_model *m, const struct ap_views *vs,
                       const struct ap_camera *cam, float C[3], int idx[3], float w[3])
{
        float d[3], len = 0;

        for (int k = 0; k < 3; k++) {
                C[k] = (float)-(cam->R[k] * cam->t[0] + cam->R[3 + k] * cam->t[1] +
                                cam->R[6 + k] * cam->t[2]);
                d[k] = C[k] - (float)m->centre[k], len += d[k] * d[k];
        }
        for (int k = 0; k < 3; k++)
                d[k] /= sqrtf(len);
        return ap_views_weights(vs, d, idx, w);
}

int ap_brdf_view_render(const struct ap_brdf_model *m, const struct ap_views *vs,
                        const struct ap_camera *cam, const struct ap_env_light *L, float *rgb,
                        uint8_t *mask)
{
        int idx[3], nv;
        float w[3], C[3];

        if (!m || m->kind != AP_BRDF_KIND_VIEW || cam->width <= 0 || cam->height <= 0)
                return -EINVAL;
        nv = frame_views(m, vs, cam, C, idx, w);
        for (size_t p = 0; p < (size_t)cam->width * cam->height; p++) {
                double uv[2] = {(double)(p % cam->width), (double)(p / cam->width)}, X[3];
                float acc[3] = {0}, wsum = 0, f[3];
                fit_nominal_point(cam, m->centre, uv, X);
                for (int j = 0; j < nv; j++)
                        if (w[j] > 0 && shade(m, &m->views[idx[j]], X, C, L, f)) {
                                for (int k = 0; k < 3; k++)
                                        acc[k] += w[j] * f[k];
                                wsum += w[j];
                        }
                mask[p] = wsum > 0;
                for (int k = 0; k < 3; k++)
                        rgb[3 * p + k] = wsum > 0 ? acc[k] / wsum : 0;
        }
        return 0;
}
