/* riggeom.c - the rig's geometry from the rig file (see riggeom.h). */
#include <math.h>

#include "riggeom.h"

#define DEG (M_PI / 180)

/* The role's angle in p, 0 where NAN (no such axis). */
static double pose_angle(const struct gn_pose *p, enum gn_role role)
{
        return p && gn_pose_has(p, role) ? p->deg[role] : 0.0;
}

void riggeom_lamp_position(const struct rig_switch_conf *l, double light_arm_deg, double p[3])
{
        double a = (light_arm_deg + l->azimuth_deg) * DEG;
        double e = l->elevation_deg * DEG;

        p[0] = l->radius_mm * cos(e) * cos(a);
        p[1] = l->radius_mm * cos(e) * sin(a);
        p[2] = l->radius_mm * sin(e);
}

void riggeom_camera_center(const struct rig_camera_conf *c, double camera_arm_deg, double p[3])
{
        double a = (camera_arm_deg + c->azimuth_deg) * DEG;
        double e = c->elevation_deg * DEG;

        p[0] = c->target[0] + c->distance_mm * cos(e) * cos(a);
        p[1] = c->target[1] + c->distance_mm * cos(e) * sin(a);
        p[2] = c->target[2] + c->distance_mm * sin(e);
}

void riggeom_camera_pose(const struct rig_camera_conf *c, double camera_arm_deg, double R[9],
                         double t[3])
{
        double a = (camera_arm_deg + c->azimuth_deg) * DEG;
        double e = c->elevation_deg * DEG;
        double C[3], f[3] = {-cos(e) * cos(a), -cos(e) * sin(a), -sin(e)};
        double r[3] = {f[1], -f[0], 0}; /* f x z */
        double rl = hypot(r[0], r[1]);

        riggeom_camera_center(c, camera_arm_deg, C);
        if (rl < 1e-9) { /* looking straight up or down: keep the arm's azimuth as right */
                r[0] = sin(a);
                r[1] = -cos(a);
                rl = 1;
        }
        r[0] /= rl;
        r[1] /= rl;
        double dn[3] = {f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2],
                        f[0] * r[1] - f[1] * r[0]}; /* f x r: image down */
        for (int i = 0; i < 3; i++) {
                R[i] = r[i];
                R[3 + i] = dn[i];
                R[6 + i] = f[i];
        }
        for (int i = 0; i < 3; i++)
                t[i] = -(R[i * 3] * C[0] + R[i * 3 + 1] * C[1] + R[i * 3 + 2] * C[2]);
}

void riggeom_lamp_dir_object(const struct rig_config *rc, int lamp, const struct gn_pose *p,
                             double dir[3])
{
        double w[3], tt = -pose_angle(p, GN_ROLE_TURNTABLE) * DEG;
        double len;

        riggeom_lamp_position(&rc->lamps[lamp], pose_angle(p, GN_ROLE_LIGHT_ARM), w);
        len = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        dir[0] = (cos(tt) * w[0] - sin(tt) * w[1]) / len;
        dir[1] = (sin(tt) * w[0] + cos(tt) * w[1]) / len;
        dir[2] = w[2] / len;
}

double riggeom_angle_deg(const double a[3], const double b[3])
{
        double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                       a[0] * b[1] - a[1] * b[0]};
        double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

        /* atan2 of |a x b| and a.b: accurate for small and for near-opposite angles */
        return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), dot) / DEG;
}

bool riggeom_in_view(const struct rig_camera_conf *c, double camera_arm_deg, const double x[3],
                     double *off_axis_deg)
{
        double R[9], t[3], q[3], axis[3] = {0, 0, 1}, u, v;

        riggeom_camera_pose(c, camera_arm_deg, R, t);
        for (int i = 0; i < 3; i++)
                q[i] = R[3 * i] * x[0] + R[3 * i + 1] * x[1] + R[3 * i + 2] * x[2] + t[i];
        if (off_axis_deg)
                *off_axis_deg = riggeom_angle_deg(q, axis);
        if (q[2] <= 0)
                return false;
        u = c->fx * q[0] / q[2] + c->cx;
        v = c->fy * q[1] / q[2] + c->cy;
        return u >= -0.5 && u <= c->width - 0.5 && v >= -0.5 && v <= c->height - 0.5;
}
