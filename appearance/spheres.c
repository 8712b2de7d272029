/* spheres.c - the sphere set of an object (spheres.h): interior cells by the parity of
 * vertical rays through the mesh, distances to dense surface samples, greedy inscribed spheres; the
 * SSDF of Algorithm 1 (seed 000) and the tabulated visible fraction of an SG lobe (eq. 12). */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/spheres.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define SURFACE_SAMPLES 6000

/* Interior cell centres and their distance to the surface. */
struct cloud {
        float *p, *d; /* 3 per point, 1 per point */
        size_t n;
        float lo[3], step;
        int dim[3];
};

/* The heights where the vertical line through (x, y) crosses m, sorted, into z; their count. */
static size_t column_hits(const struct ap_mesh *m, float x, float y, float *z)
{
        size_t n = 0;

        for (size_t t = 0; t < m->nt; t++) {
                const float *a = m->pos + 3 * m->idx[3 * t], *b = m->pos + 3 * m->idx[3 * t + 1];
                const float *c = m->pos + 3 * m->idx[3 * t + 2];
                float d = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                if (fabsf(d) < 1e-12f)
                        continue;
                float u = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / d;
                float v = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / d;
                if (u < 0 || v < 0 || u + v > 1)
                        continue;
                z[n++] = a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]);
        }
        qsort(z, n, sizeof(*z), gn_cmp_float);
        return n;
}

static void bounds(const struct ap_mesh *m, float lo[3], float hi[3])
{
        for (int k = 0; k < 3; k++) {
                lo[k] = FLT_MAX;
                hi[k] = -FLT_MAX;
        }
        for (size_t i = 0; i < m->nv; i++)
                for (int k = 0; k < 3; k++) {
                        lo[k] = fminf(lo[k], m->pos[3 * i + k]);
                        hi[k] = fmaxf(hi[k], m->pos[3 * i + k]);
                }
}

/* The grid's cells inside m (their centres into cl->p). */
static int interior(const struct ap_mesh *m, int grid, struct cloud *cl)
{
        float hi[3];
        _cleanup_free_ float *z = malloc(m->nt * sizeof(float));

        bounds(m, cl->lo, hi);
        cl->step = fmaxf(fmaxf(hi[0] - cl->lo[0], hi[1] - cl->lo[1]), hi[2] - cl->lo[2]) / grid;
        if (!z || !(cl->step > 0))
                return z ? -EINVAL : -ENOMEM;
        for (int k = 0; k < 3; k++)
                cl->dim[k] = (int)ceilf((hi[k] - cl->lo[k]) / cl->step);
        cl->p = malloc(3 * sizeof(float) * cl->dim[0] * cl->dim[1] * cl->dim[2]);
        if (!cl->p)
                return -ENOMEM;
        for (int i = 0; i < cl->dim[0]; i++)
                for (int j = 0; j < cl->dim[1]; j++) {
                        /* off the cell centre a little: no line through a vertex or an edge */
                        float x = cl->lo[0] + (i + 0.5f + 1.3e-3f) * cl->step;
                        float y = cl->lo[1] + (j + 0.5f + 0.7e-3f) * cl->step;
                        size_t nh = column_hits(m, x, y, z), h = 0;
                        for (int k = 0; k < cl->dim[2]; k++) {
                                float zc = cl->lo[2] + (k + 0.5f) * cl->step;
                                while (h < nh && z[h] < zc)
                                        h++;
                                if (!(h & 1))
                                        continue;
                                float *p = cl->p + 3 * cl->n++;
                                p[0] = x;
                                p[1] = y;
                                p[2] = zc;
                        }
                }
        return cl->n ? 0 : -EINVAL;
}

static float dist2(const float *a, const float *b)
{
        float dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
        return dx * dx + dy * dy + dz * dz;
}

static float tri_area(const struct ap_mesh *m, size_t t)
{
        const float *a = m->pos + 3 * m->idx[3 * t], *b = m->pos + 3 * m->idx[3 * t + 1];
        const float *c = m->pos + 3 * m->idx[3 * t + 2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2];
        float cz = e1[0] * e2[1] - e1[1] * e2[0];

        return 0.5f * sqrtf(cx * cx + cy * cy + cz * cz);
}

/* About SURFACE_SAMPLES points spread over m's surface by area (error diffusion of the
 * triangles' shares), each triangle's at golden-ratio barycentric positions. */
static int surface(const struct ap_mesh *m, float **ret, size_t *n_ret)
{
        double area = 0, carry = 0;
        size_t cap = SURFACE_SAMPLES + m->nt + 1, n = 0;
        float *s = malloc(3 * cap * sizeof(float));

        if (!s)
                return -ENOMEM;
        for (size_t t = 0; t < m->nt; t++)
                area += tri_area(m, t);
        for (size_t t = 0; t < m->nt && area > 0; t++) {
                const float *c[3];
                carry += tri_area(m, t) / area * SURFACE_SAMPLES;
                int k = (int)carry;
                carry -= k;
                for (int q = 0; q < 3; q++)
                        c[q] = m->pos + 3 * m->idx[3 * t + q];
                for (int i = 0; i < k && n < cap; i++, n++) {
                        float r1 = sqrtf((i + 0.5f) / k), r2 = fmodf(i * 0.618034f + 0.3f, 1.f);
                        for (int q = 0; q < 3; q++)
                                s[3 * n + q] = (1 - r1) * c[0][q] + r1 * (1 - r2) * c[1][q] +
                                               r1 * r2 * c[2][q];
                }
        }
        *ret = s;
        *n_ret = n;
        return 0;
}

static int depths(const struct ap_mesh *m, struct cloud *cl)
{
        _cleanup_free_ float *s = NULL;
        size_t ns;
        int r = surface(m, &s, &ns);

        if (r < 0)
                return r;
        cl->d = malloc(cl->n * sizeof(float));
        if (!cl->d)
                return -ENOMEM;
        for (size_t i = 0; i < cl->n; i++) {
                float best = FLT_MAX;
                for (size_t j = 0; j < ns; j++)
                        best = fminf(best, dist2(cl->p + 3 * i, s + 3 * j));
                cl->d[i] = sqrtf(best);
        }
        return 0;
}

/* Greedy inscribed spheres: the deepest point not yet inside a sphere becomes the next
 * centre, with its depth as radius, until n spheres or no point left uncovered. */
static int medial(const struct cloud *cl, int n, struct ap_spheres *out)
{
        _cleanup_free_ uint8_t *covered = calloc(cl->n, 1);

        if (!covered)
                return -ENOMEM;
        while (out->n < n) {
                long best = -1;
                for (size_t i = 0; i < cl->n; i++)
                        if (!covered[i] && (best < 0 || cl->d[i] > cl->d[best]))
                                best = (long)i;
                if (best < 0)
                        break;
                float *s = out->s + 4 * out->n++;
                memcpy(s, cl->p + 3 * best, 3 * sizeof(float));
                s[3] = cl->d[best];
                for (size_t i = 0; i < cl->n; i++)
                        covered[i] |= dist2(cl->p + 3 * i, s) <= s[3] * s[3];
                covered[best] = 1;
        }
        return 0;
}

int ap_spheres_fit(const struct ap_mesh *m, int n, int grid, struct ap_spheres *out)
{
        struct cloud cl = {0};
        int r;

        memset(out, 0, sizeof(*out));
        if (!m || !m->nt || n < 1 || n > AP_SPHERES_MAX || grid < 8 || grid > 128)
                return -EINVAL;
        r = interior(m, grid, &cl);
        if (r >= 0)
                r = depths(m, &cl);
        out->s = malloc(4 * sizeof(float) * (size_t)n);
        if (r >= 0 && !out->s)
                r = -ENOMEM;
        if (r >= 0)
                r = medial(&cl, n, out);
        if (r >= 0) {
                out->cell = cl.step;
                ap_spheres_table(out);
        }
        free(cl.p);
        free(cl.d);
        if (r < 0)
                ap_spheres_free(out);
        return r;
}

void ap_spheres_free(struct ap_spheres *s)
{
        free(s->s);
        memset(s, 0, sizeof(*s));
}

static float eta_at(int e)
{
        return 0.5f * powf(4e4f, (float)e / (AP_SG_VIS_ETAS - 1));
}

/* The fraction of an SG lobe (sharpness eta) on the visible side of a great circle at
 * signed angle td from its axis (eq. 12), by quadrature over the polar angle. */
static double cut_fraction(double td, double eta)
{
        double top = fmin(M_PI, 10 / sqrt(eta)), num = 0, den = 0;
        const int steps = 400;

        for (int i = 0; i < steps; i++) {
                double th = (i + 0.5) * top / steps, st = sin(th);
                double w = exp(eta * (cos(th) - 1)) * st;
                double x = -cos(th) * sin(td) / fmax(st * cos(td), 1e-12);
                num += w * acos(CLAMP(x, -1.0, 1.0)) / M_PI;
                den += w;
        }
        return num / den;
}

void ap_spheres_table(struct ap_spheres *s)
{
        for (int e = 0; e < AP_SG_VIS_ETAS; e++) {
                double full = cut_fraction(M_PI / 2, eta_at(e));
                for (int a = 0; a < AP_SG_VIS_ANGLES; a++) {
                        double td = -M_PI / 2 + M_PI * a / (AP_SG_VIS_ANGLES - 1);
                        s->vis[e * AP_SG_VIS_ANGLES + a] =
                                (float)fmin(cut_fraction(td, eta_at(e)) / full, 1.0);
                }
        }
}

float ap_sg_visible(const struct ap_spheres *s, float theta_d, float eta)
{
        float fe = logf(fmaxf(eta, 0.5f) / 0.5f) / logf(4e4f) * (AP_SG_VIS_ETAS - 1);
        float fa = (theta_d + (float)M_PI_2) / (float)M_PI * (AP_SG_VIS_ANGLES - 1);
        fe = CLAMP(fe, 0.f, AP_SG_VIS_ETAS - 1.001f);
        fa = CLAMP(fa, 0.f, AP_SG_VIS_ANGLES - 1.001f);
        int e = (int)fe, a = (int)fa;
        float te = fe - e, ta = fa - a;
        const float *v = s->vis + e * AP_SG_VIS_ANGLES + a;

        return (1 - te) * ((1 - ta) * v[0] + ta * v[1]) +
               te * ((1 - ta) * v[AP_SG_VIS_ANGLES] + ta * v[AP_SG_VIS_ANGLES + 1]);
}

float ap_ssdf(const struct ap_spheres *s, const float v[3], const float n[3], const float zeta[3])
{
        float best = (float)M_PI_2, cb = 0, sb = 1; /* cos and sin of best */

        for (int j = 0; j < s->n; j++) {
                const float *c = s->s + 4 * j;
                float d[3] = {c[0] - v[0], c[1] - v[1], c[2] - v[2]}, r = c[3];
                float L = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                float dn = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
                if (L <= r || dn + r < 0) /* inside, or below the tangent plane */
                        continue;
                if (dn < 0 && L - r < s->cell) /* the sphere under v itself */
                        continue;
                /* eq. 9 is below best iff the angle to the centre is below best + beta
                 * (beta = asin(r / L), both angles at most pi/2): tested on cosines, the
                 * trigonometry left for the few that pass */
                float cz = (d[0] * zeta[0] + d[1] * zeta[1] + d[2] * zeta[2]) / L;
                float sbeta = r / L, cbeta = sqrtf(1 - sbeta * sbeta);
                if ((sb < 0 && sbeta <= -sb) || cz <= cbeta * cb - sbeta * sb)
                        continue;
                float val = acosf(CLAMP(cz, -1.f, 1.f)) - asinf(sbeta);
                if (val < best) {
                        best = val;
                        cb = cosf(best);
                        sb = sinf(best);
                }
        }
        return best;
}
