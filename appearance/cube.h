/* cube.h - the cube-map addressing shared by the view table (views.c) and the light table
 * (render.c): a direction's face by its major axis (0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z) and
 * its coordinates s, t in [-1, 1] on that face; and back. Header-only. */
#pragma once

#include <math.h>

/* Face and (s, t) of the non-zero direction d. */
static inline int ap_cube_face(const float d[3], float *s, float *t)
{
        float ax = fabsf(d[0]), ay = fabsf(d[1]), az = fabsf(d[2]);

        if (ax >= ay && ax >= az) {
                *s = d[1] / ax, *t = d[2] / ax;
                return d[0] > 0 ? 0 : 1;
        }
        if (ay >= az) {
                *s = d[0] / ay, *t = d[2] / ay;
                return d[1] > 0 ? 2 : 3;
        }
        *s = d[0] / az, *t = d[1] / az;
        return d[2] > 0 ? 4 : 5;
}

/* The (unnormalised) direction of point (s, t) of face. */
static inline void ap_cube_dir(int face, float s, float t, float d[3])
{
        int ax = face / 2;

        d[ax] = face % 2 ? -1.f : 1.f;
        d[ax == 0 ? 1 : 0] = s;
        d[ax == 2 ? 1 : 2] = t;
}
