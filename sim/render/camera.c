/* camera.c - the camera model of the renderer: pose on the camera arm, Brown-Conrady
 * projection (OpenCV convention) and its inverse, tabulated as one unit ray direction
 * per pixel centre. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "internal.h"

static void distort(const double dist[5], double x, double y, double *xd, double *yd)
{
        double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
        double r2 = x * x + y * y;
        double rad = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));

        *xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
        *yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
}

/* Newton iteration on the distortion map from the distorted normalised point. */
static void undistort(const double dist[5], double xd, double yd, double *x, double *y)
{
        double k1 = dist[0], k2 = dist[1], p1 = dist[2], p2 = dist[3], k3 = dist[4];
        double cx = xd, cy = yd;

        for (int it = 0; it < 50; it++) {
                double fx, fy, r2 = cx * cx + cy * cy;
                double rad = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
                double dr = k1 + r2 * (2 * k2 + 3 * k3 * r2);

                distort(dist, cx, cy, &fx, &fy);
                fx -= xd;
                fy -= yd;
                if (fabs(fx) + fabs(fy) < 1e-15)
                        break;
                double a = rad + 2 * cx * cx * dr + 2 * p1 * cy + 6 * p2 * cx;
                double b = 2 * cx * cy * dr + 2 * p1 * cx + 2 * p2 * cy;
                double d = rad + 2 * cy * cy * dr + 6 * p1 * cy + 2 * p2 * cx;
                double det = a * d - b * b;
                if (fabs(det) < 1e-12)
                        break;
                cx -= (d * fx - b * fy) / det;
                cy -= (a * fy - b * fx) / det;
        }
        *x = cx;
        *y = cy;
}

int camera_build(struct camera *c, const struct rig_camera_conf *cc)
{
        size_t n = (size_t)cc->width * cc->height;

        if (cc->width <= 0 || cc->height <= 0 || cc->fx <= 0 || cc->fy <= 0)
                return -EINVAL;
        c->dirs = malloc(n * 3 * sizeof(float));
        if (!c->dirs)
                return -ENOMEM;
        for (int v = 0; v < cc->height; v++)
                for (int u = 0; u < cc->width; u++) {
                        double x, y, l;
                        float *d = c->dirs + 3 * ((size_t)v * cc->width + u);

                        undistort(cc->dist, (u - cc->cx) / cc->fx, (v - cc->cy) / cc->fy, &x, &y);
                        l = sqrt(x * x + y * y + 1);
                        d[0] = (float)(x / l);
                        d[1] = (float)(y / l);
                        d[2] = (float)(1 / l);
                }
        return 0;
}

void camera_free(struct camera *c)
{
        free(c->dirs);
        c->dirs = NULL;
}

double pose_deg(const struct gn_pose *p, enum gn_role role)
{
        return gn_pose_has(p, role) ? p->deg[role] : 0.0;
}

int sim_cam_project(const struct sim_cam_geom *g, const double p[3], double uv[2])
{
        double c[3], xd, yd;

        m3d_apply(g->R, p, c);
        for (int i = 0; i < 3; i++)
                c[i] += g->t[i];
        if (c[2] <= 0)
                return -EDOM;
        distort(g->dist, c[0] / c[2], c[1] / c[2], &xd, &yd);
        uv[0] = g->fx * xd + g->cx;
        uv[1] = g->fy * yd + g->cy;
        return 0;
}

int sim_camera_geom(const struct sim_scene *s, const struct gn_pose *st, int cam,
                    struct sim_cam_geom *out)
{
        const struct rig_camera_conf *cc;

        if (!s || !st || !out || cam < 0 || (size_t)cam >= s->rc->n_cameras)
                return -EINVAL;
        cc = &s->rc->cameras[cam];
        out->width = cc->width;
        out->height = cc->height;
        out->fx = cc->fx;
        out->fy = cc->fy;
        out->cx = cc->cx;
        out->cy = cc->cy;
        for (int i = 0; i < 5; i++)
                out->dist[i] = cc->dist[i];
        riggeom_camera_pose(cc, pose_deg(st, GN_ROLE_CAMERA_ARM), out->R, out->t);
        return 0;
}
