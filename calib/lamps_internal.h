/* lamps_internal.h - what lamps.c and lamps_ba.c share (see lamps.h). */
#pragma once

#include <math.h>

#include "calib/lamps.h"

#define CAL_LAMPS_DEG (M_PI / 180)

/* Rotates v about z by deg into out (may be v). */
static inline void cal_lamps_rot_z(const double v[3], double deg, double out[3])
{
        double c = cos(deg * CAL_LAMPS_DEG), s = sin(deg * CAL_LAMPS_DEG), x = v[0], y = v[1];

        out[0] = c * x - s * y;
        out[1] = s * x + c * y;
        out[2] = v[2];
}

/* An angle of a view: NAN (no such axis) counts as 0. */
static inline double cal_lamps_angle(double deg)
{
        return isnan(deg) ? 0 : deg;
}

/* The centre c of camera cam in the world: -R^T t. */
static inline void cal_lamps_camera_centre(const struct sec_camera *cam, double c[3])
{
        for (int i = 0; i < 3; i++)
                c[i] = -(cam->R[i] * cam->t[0] + cam->R[3 + i] * cam->t[1] +
                         cam->R[6 + i] * cam->t[2]);
}

/* Refines the sphere's centre and the solved lamps' positions of out jointly (Levenberg-
 * Marquardt): each used view's highlight against the specular point of its lamp on the
 * sphere (plus the offset of a lamp's reflection's centroid, set in v->offset), each view's
 * silhouette axis (sphere_used) against the sphere's centre. Returns 0,
 * -ENOMEM, or -EDOM (it diverged: out unchanged). */
int cal_lamps_refine(struct cal_lamp_view *v, size_t n, const struct cal_lamps_opts *o,
                     struct cal_lamps *out);
