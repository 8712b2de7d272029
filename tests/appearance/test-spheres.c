/* test-spheres.c - the sphere set and its SSDF (appearance/spheres.h) on meshes of known
 * shape: one tessellated sphere fitted by one sphere; the visible fraction of SG lobes at
 * points near two separate spheres against Monte Carlo rays cast on the mesh itself. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>

#include "appearance/spheres.h"
#include "tests/test.h"

/* Appends a UV sphere (rows x 2 rows quads) of radius r at c to m (arrays grown). */
static void add_sphere(struct ap_mesh *m, const float c[3], float r, int rows)
{
        int cols = 2 * rows, v0 = (int)m->nv;

        m->pos = realloc(m->pos, 3 * sizeof(float) * (m->nv + (size_t)(rows + 1) * cols));
        m->idx = realloc(m->idx, 3 * sizeof(uint32_t) * (m->nt + 2 * (size_t)rows * cols));
        CHECK(m->pos && m->idx);
        for (int i = 0; i <= rows; i++)
                for (int j = 0; j < cols; j++) {
                        double th = M_PI * i / rows, ph = 2 * M_PI * j / cols;
                        float *p = m->pos + 3 * m->nv++;
                        p[0] = c[0] + r * (float)(sin(th) * cos(ph));
                        p[1] = c[1] + r * (float)(sin(th) * sin(ph));
                        p[2] = c[2] + r * (float)cos(th);
                }
        for (int i = 0; i < rows; i++)
                for (int j = 0; j < cols; j++) {
                        uint32_t a = v0 + i * cols + j, b = v0 + i * cols + (j + 1) % cols;
                        uint32_t q[6] = {a, a + cols, b, b, a + cols, b + cols};
                        for (int k = 0; k < 6; k++)
                                m->idx[3 * m->nt + k] = q[k];
                        m->nt += 2;
                }
}

static void test_fit_sphere(void)
{
        struct ap_mesh m = {0};
        struct ap_spheres s;
        float c[3] = {5, -3, 30};

        add_sphere(&m, c, 30, 24);
        CHECK_INT(ap_spheres_fit(&m, 1, 24, &s), 0);
        CHECK_INT(s.n, 1);
        fprintf(stderr, "one sphere: (%.2f %.2f %.2f) r %.2f, cell %.2f\n", s.s[0], s.s[1], s.s[2],
                s.s[3], s.cell);
        for (int k = 0; k < 3; k++)
                CHECK_NEAR(s.s[k], c[k], s.cell);
        CHECK_NEAR(s.s[3], 30, 1.5 * s.cell);
        ap_spheres_free(&s);
        CHECK_INT(ap_spheres_fit(&m, 12, 24, &s), 0);
        CHECK_INT(s.n, 12);
        for (int j = 0; j < s.n; j++) { /* every sphere inside the object */
                float *q = s.s + 4 * j;
                float d = sqrtf(powf(q[0] - c[0], 2) + powf(q[1] - c[1], 2) + powf(q[2] - c[2], 2));
                CHECK(d + q[3] <= 30 + s.cell);
        }
        ap_spheres_free(&s);
        CHECK_INT(ap_spheres_fit(&m, 0, 32, &s), -EINVAL);
        ap_mesh_free(&m);
}

static bool ray_hits(const struct ap_mesh *m, const float o[3], const float d[3])
{
        for (size_t t = 0; t < m->nt; t++) {
                const float *a = m->pos + 3 * m->idx[3 * t], *b = m->pos + 3 * m->idx[3 * t + 1];
                const float *c = m->pos + 3 * m->idx[3 * t + 2];
                float e1[3], e2[3], s[3];
                for (int k = 0; k < 3; k++) {
                        e1[k] = b[k] - a[k];
                        e2[k] = c[k] - a[k];
                        s[k] = o[k] - a[k];
                }
                float p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                              d[0] * e2[1] - d[1] * e2[0]};
                float det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
                if (fabsf(det) < 1e-9f)
                        continue;
                float u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
                float q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                              s[0] * e1[1] - s[1] * e1[0]};
                float v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
                float tt = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
                if (u >= 0 && v >= 0 && u + v <= 1 && tt > 1e-3f)
                        return true;
        }
        return false;
}

/* A frame (t, b) around unit z. */
static void frame_of(const float z[3], float t[3], float b[3])
{
        float a[3] = {fabsf(z[0]) < 0.9f ? 1.f : 0.f, fabsf(z[0]) < 0.9f ? 0.f : 1.f, 0};
        float d = a[0] * z[0] + a[1] * z[1] + a[2] * z[2], l;

        for (int k = 0; k < 3; k++)
                t[k] = a[k] - d * z[k];
        l = sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        for (int k = 0; k < 3; k++)
                t[k] /= l;
        b[0] = z[1] * t[2] - z[2] * t[1];
        b[1] = z[2] * t[0] - z[0] * t[2];
        b[2] = z[0] * t[1] - z[1] * t[0];
}

/* The fraction of the SG (zeta, eta) not blocked by m from o, by n importance samples. */
static double ray_visible(const struct ap_mesh *m, const float o[3], const float zeta[3],
                          double eta, int n)
{
        float t[3], b[3];
        int vis = 0;

        frame_of(zeta, t, b);
        for (int i = 0; i < n; i++) {
                double u = (i + 0.5) / n, ph = 2 * M_PI * fmod(i * 0.618034, 1.0);
                double ct = 1 + log(1 - u * (1 - exp(-2 * eta))) / eta,
                       st = sqrt(fmax(0, 1 - ct * ct));
                float d[3];
                for (int k = 0; k < 3; k++)
                        d[k] = (float)(st * cos(ph) * t[k] + st * sin(ph) * b[k] + ct * zeta[k]);
                vis += !ray_hits(m, o, d);
        }
        return (double)vis / n;
}

static void test_visibility(void)
{
        struct ap_mesh m = {0};
        struct ap_spheres s;
        float ca[3] = {0, 0, 20}, cb[3] = {45, 0, 25}, up[3] = {0, 0, 1};
        double etas[2] = {5, 60}, sum = 0, worst = 0;
        int n = 0;

        add_sphere(&m, ca, 20, 16);
        add_sphere(&m, cb, 12, 12);
        CHECK_INT(ap_spheres_fit(&m, 8, 40, &s), 0);
        for (int p = 0; p < 12; p++) { /* ground points around the two */
                float o[3] = {(float)(-30 + 8 * p),
                              (float)(p % 3 == 0   ? 14
                                      : p % 3 == 1 ? -9
                                                   : 3),
                              0.01f};
                for (int a = 0; a < 6; a++) {
                        double el = 0.15 + 0.25 * a, az = M_PI * (0.3 + 0.7 * a);
                        float z[3] = {(float)(cos(el) * cos(az)), (float)(cos(el) * sin(az)),
                                      (float)sin(el)};
                        float td = ap_ssdf(&s, o, up, z);
                        for (int e = 0; e < 2; e++) {
                                double want = ray_visible(&m, o, z, etas[e], 96);
                                double got = ap_sg_visible(&s, td, (float)etas[e]);
                                sum += fabs(got - want);
                                worst = fmax(worst, fabs(got - want));
                                n++;
                        }
                }
        }
        fprintf(stderr, "SSDF visibility of %d lobes against rays: mean error %.4f, worst %.4f\n",
                n, sum / n, worst);
        CHECK(sum / n < 0.06);
        CHECK(worst < 0.4);
        /* an unoccluded lobe is fully visible; a lobe into a sphere is dark */
        CHECK_NEAR(ap_sg_visible(&s, (float)M_PI_2, 20), 1, 1e-3);
        CHECK(ap_sg_visible(&s, -0.5f, 50) < 0.01f);
        ap_spheres_free(&s);
        ap_mesh_free(&m);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"fit-sphere", test_fit_sphere},
                {"visibility", test_visibility},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
