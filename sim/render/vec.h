/* vec.h - small inline 3-vector and 3x3-matrix helpers for the renderer (float for the
 * per-ray paths, double for setup). Header-only; no state. */
#pragma once

#include <math.h>

struct v3 {
        float x, y, z;
};

static inline struct v3 v3(float x, float y, float z)
{
        return (struct v3){x, y, z};
}

static inline struct v3 v3_add(struct v3 a, struct v3 b)
{
        return v3(a.x + b.x, a.y + b.y, a.z + b.z);
}

static inline struct v3 v3_sub(struct v3 a, struct v3 b)
{
        return v3(a.x - b.x, a.y - b.y, a.z - b.z);
}

static inline struct v3 v3_scale(struct v3 a, float s)
{
        return v3(a.x * s, a.y * s, a.z * s);
}

static inline struct v3 v3_madd(struct v3 a, struct v3 b, float s)
{
        return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s);
}

static inline float v3_dot(struct v3 a, struct v3 b)
{
        return a.x * b.x + a.y * b.y + a.z * b.z;
}

static inline struct v3 v3_cross(struct v3 a, struct v3 b)
{
        return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

static inline float v3_len(struct v3 a)
{
        return sqrtf(v3_dot(a, a));
}

static inline struct v3 v3_norm(struct v3 a)
{
        float l = v3_len(a);
        return l > 0.0f ? v3_scale(a, 1.0f / l) : a;
}

/* m is row-major 3x3 (float). */
static inline struct v3 m3_mul(const float m[9], struct v3 a)
{
        return v3(m[0] * a.x + m[1] * a.y + m[2] * a.z, m[3] * a.x + m[4] * a.y + m[5] * a.z,
                  m[6] * a.x + m[7] * a.y + m[8] * a.z);
}

/* Double-precision helpers for setup code: row-major 3x3 product c = a * b. */
static inline void m3d_mul(const double a[9], const double b[9], double c[9])
{
        for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                        c[i * 3 + j] =
                                a[i * 3] * b[j] + a[i * 3 + 1] * b[3 + j] + a[i * 3 + 2] * b[6 + j];
}

static inline void m3d_apply(const double m[9], const double a[3], double out[3])
{
        for (int i = 0; i < 3; i++)
                out[i] = m[i * 3] * a[0] + m[i * 3 + 1] * a[1] + m[i * 3 + 2] * a[2];
}

/* Rotation about z by deg degrees (row-major). */
static inline void m3d_rot_z(double deg, double m[9])
{
        double a = deg * M_PI / 180.0, c = cos(a), s = sin(a);
        double r[9] = {c, -s, 0, s, c, 0, 0, 0, 1};
        for (int i = 0; i < 9; i++)
                m[i] = r[i];
}
