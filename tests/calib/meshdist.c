/* meshdist.c - point to triangle mesh distance through a uniform grid (meshdist.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "tests/calib/meshdist.h"
#include "tests/test.h"

static double dot3(const double a[3], const double b[3])
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void vertex(const struct sim_mesh *m, size_t t, int k, double v[3])
{
        const float *p = m->pos + 3 * (size_t)m->idx[3 * t + k];

        v[0] = p[0], v[1] = p[1], v[2] = p[2];
}

/* c = a + s (b - a) + t (d - a) */
static void combine(const double a[3], const double b[3], const double d[3], double s, double t,
                    double c[3])
{
        for (int k = 0; k < 3; k++)
                c[k] = a[k] + s * (b[k] - a[k]) + t * (d[k] - a[k]);
}

/* The point c of triangle abd closest to p, by the region of the triangle's plane p falls in
 * (a vertex, an edge or the face). */
static void closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                const double d[3], double c[3])
{
        double ab[3], ad[3], ap[3], bp[3], dp[3];

        for (int k = 0; k < 3; k++)
                ab[k] = b[k] - a[k], ad[k] = d[k] - a[k], ap[k] = p[k] - a[k], bp[k] = p[k] - b[k],
                dp[k] = p[k] - d[k];
        double d1 = dot3(ab, ap), d2 = dot3(ad, ap), d3 = dot3(ab, bp), d4 = dot3(ad, bp);
        double d5 = dot3(ab, dp), d6 = dot3(ad, dp);
        double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vd = d1 * d4 - d3 * d2;

        if (d1 <= 0 && d2 <= 0)
                return combine(a, b, d, 0, 0, c);
        if (d3 >= 0 && d4 <= d3)
                return combine(a, b, d, 1, 0, c);
        if (d6 >= 0 && d5 <= d6)
                return combine(a, b, d, 0, 1, c);
        if (vd <= 0 && d1 >= 0 && d3 <= 0)
                return combine(a, b, d, d1 / (d1 - d3), 0, c);
        if (vb <= 0 && d2 >= 0 && d6 <= 0)
                return combine(a, b, d, 0, d2 / (d2 - d6), c);
        if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
                double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
                return combine(a, b, d, 1 - w, w, c);
        }
        double den = 1 / (va + vb + vd);
        combine(a, b, d, vb * den, vd * den, c);
}

/* The cell index range [lo, hi] along each axis of the box x0..x1 (clamped to the grid). */
static void cell_range(const struct meshdist *md, const double x0[3], const double x1[3], int lo[3],
                       int hi[3])
{
        for (int k = 0; k < 3; k++) {
                lo[k] = (int)floor((x0[k] - md->lo[k]) / md->cell);
                hi[k] = (int)floor((x1[k] - md->lo[k]) / md->cell);
                lo[k] = lo[k] < 0 ? 0 : lo[k] >= md->dim[k] ? md->dim[k] - 1 : lo[k];
                hi[k] = hi[k] < 0 ? 0 : hi[k] >= md->dim[k] ? md->dim[k] - 1 : hi[k];
        }
}

static size_t cell_of(const struct meshdist *md, int x, int y, int z)
{
        return ((size_t)z * md->dim[1] + y) * md->dim[0] + x;
}

/* Calls back for each cell overlapped by triangle t's bounding box: counts (fill false) or
 * files t (fill true, start[] as cursors). */
static void bin_triangle(struct meshdist *md, size_t t, bool fill, uint32_t *cursor)
{
        double v[3][3], x0[3], x1[3];
        int lo[3], hi[3];

        for (int k = 0; k < 3; k++)
                vertex(&md->m, t, k, v[k]);
        for (int k = 0; k < 3; k++) {
                x0[k] = fmin(fmin(v[0][k], v[1][k]), v[2][k]);
                x1[k] = fmax(fmax(v[0][k], v[1][k]), v[2][k]);
        }
        cell_range(md, x0, x1, lo, hi);
        for (int z = lo[2]; z <= hi[2]; z++)
                for (int y = lo[1]; y <= hi[1]; y++)
                        for (int x = lo[0]; x <= hi[0]; x++) {
                                size_t c = cell_of(md, x, y, z);
                                if (fill)
                                        md->tri[cursor[c]++] = (uint32_t)t;
                                else
                                        md->start[c + 1]++;
                        }
}

void md_open(struct meshdist *md, struct sim_mesh m, double cell)
{
        double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        size_t cells;
        uint32_t *cursor;

        memset(md, 0, sizeof(*md));
        md->m = m;
        md->cell = cell;
        md->lo[0] = md->lo[1] = md->lo[2] = INFINITY;
        for (size_t i = 0; i < 3 * m.nv; i++) {
                md->lo[i % 3] = fmin(md->lo[i % 3], m.pos[i]);
                hi[i % 3] = fmax(hi[i % 3], m.pos[i]);
        }
        for (int k = 0; k < 3; k++) { /* a cell of margin all round */
                md->lo[k] = m.nv ? md->lo[k] - cell : 0;
                md->dim[k] = m.nv ? (int)ceil((hi[k] - md->lo[k]) / cell) + 2 : 1;
        }
        cells = (size_t)md->dim[0] * md->dim[1] * md->dim[2];
        md->start = calloc(cells + 1, sizeof(*md->start));
        CHECK(md->start);
        for (size_t t = 0; t < m.nt; t++)
                bin_triangle(md, t, false, NULL);
        for (size_t c = 0; c < cells; c++)
                md->start[c + 1] += md->start[c];
        md->tri = malloc((md->start[cells] + 1) * sizeof(*md->tri));
        cursor = malloc(cells * sizeof(*cursor));
        CHECK(md->tri && cursor);
        memcpy(cursor, md->start, cells * sizeof(*cursor));
        for (size_t t = 0; t < m.nt; t++)
                bin_triangle(md, t, true, cursor);
        free(cursor);
}

void md_close(struct meshdist *md)
{
        free(md->m.pos);
        free(md->m.idx);
        free(md->start);
        free(md->tri);
        memset(md, 0, sizeof(*md));
}

/* Keeps triangle t in (best, c, n) when its closest point to p is nearer; degenerate triangles
 * (the poles of a polar grid) have no plane and are passed over, their neighbours cover them. */
static void try_triangle(const struct meshdist *md, size_t t, const double p[3], double *best,
                         double c[3], double n[3])
{
        double v[3][3], q[3], e1[3], e2[3], m[3], d2 = 0, len;

        for (int k = 0; k < 3; k++)
                vertex(&md->m, t, k, v[k]);
        for (int k = 0; k < 3; k++)
                e1[k] = v[1][k] - v[0][k], e2[k] = v[2][k] - v[0][k];
        m[0] = e1[1] * e2[2] - e1[2] * e2[1];
        m[1] = e1[2] * e2[0] - e1[0] * e2[2];
        m[2] = e1[0] * e2[1] - e1[1] * e2[0];
        len = sqrt(dot3(m, m));
        if (!(len > 1e-12))
                return;
        closest_on_triangle(p, v[0], v[1], v[2], q);
        for (int k = 0; k < 3; k++)
                d2 += (p[k] - q[k]) * (p[k] - q[k]);
        if (!(d2 < *best * *best))
                return;
        *best = sqrt(d2);
        for (int k = 0; k < 3; k++)
                c[k] = q[k], n[k] = m[k] / len;
}

double md_closest(const struct meshdist *md, const double p[3], double c[3], double n[3])
{
        double best = INFINITY;
        int at[3], lo[3], hi[3], rmax = md->dim[0] + md->dim[1] + md->dim[2];

        for (int k = 0; k < 3; k++)
                if (!(p[k] >= md->lo[k] && p[k] < md->lo[k] + md->dim[k] * md->cell)) {
                        for (size_t t = 0; t < md->m.nt; t++) /* outside the grid: all */
                                try_triangle(md, t, p, &best, c, n);
                        return best;
                }
        cell_range(md, p, p, at, hi);
        /* shells of cells around p's: cells of shell r + 1 lie at least r cells from p */
        for (int r = 0; r <= rmax && !(best <= (r - 1) * md->cell); r++) {
                double x0[3], x1[3];
                for (int k = 0; k < 3; k++) {
                        x0[k] = md->lo[k] + (at[k] - r) * md->cell;
                        x1[k] = md->lo[k] + (at[k] + r) * md->cell;
                }
                cell_range(md, x0, x1, lo, hi);
                for (int z = lo[2]; z <= hi[2]; z++)
                        for (int y = lo[1]; y <= hi[1]; y++)
                                for (int x = lo[0]; x <= hi[0]; x++) {
                                        size_t cc = cell_of(md, x, y, z);
                                        if (abs(x - at[0]) < r && abs(y - at[1]) < r &&
                                            abs(z - at[2]) < r)
                                                continue; /* an inner shell's */
                                        for (uint32_t i = md->start[cc]; i < md->start[cc + 1]; i++)
                                                try_triangle(md, md->tri[i], p, &best, c, n);
                                }
        }
        return best;
}
