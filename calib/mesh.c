/* mesh.c - the (angle, row) grid of a light-sectioning cloud as a triangle mesh, and its
 * simplification with meshoptimizer (see mesh.h). */
#include <errno.h>
#include <math.h>
#include <meshoptimizer.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "mesh.h"
#include "common/sortx.h"

#define DEG      (M_PI / 180)
#define FOLD_DEG 75 /* a simplified face this far from its corners' normals is a fold */

/* One laser's grid: its lines in angle order (indices into c->lines) and the lengths an
 * edge is expected to have. */
struct grid {
        const struct sec_ctx *c;
        const struct cal_mesh_opts *o;
        size_t *line, n;
        double row_step; /* median distance of neighbouring rows of one line, mm */
        struct cal_mesh *m;
        double vote; /* faces wound towards their camera minus those wound away */
};

void cal_mesh_opts_default(struct cal_mesh_opts *o)
{
        *o = (struct cal_mesh_opts){.max_edge = 5, .seam_step = 1.5};
}

void cal_mesh_free(struct cal_mesh *m)
{
        free(m->v);
        free(m->tri);
        memset(m, 0, sizeof(*m));
}

static double dist3(const float a[3], const float b[3])
{
        return sqrt((double)(a[0] - b[0]) * (a[0] - b[0]) + (double)(a[1] - b[1]) * (a[1] - b[1]) +
                    (double)(a[2] - b[2]) * (a[2] - b[2]));
}

/* The median distance between points of neighbouring rows in g's lines. */
static int row_step(struct grid *g)
{
        const struct sec_ctx *c = g->c;
        _cleanup_free_ double *d = malloc((c->n_pts ? c->n_pts : 1) * sizeof(*d));
        size_t n = 0;

        if (!d)
                return -ENOMEM;
        for (size_t k = 0; k < g->n; k++) {
                const struct sec_line *l = &c->lines[g->line[k]];
                for (size_t i = l->first; i + 1 < l->first + l->count; i++)
                        if (c->pts[i + 1].row == c->pts[i].row + 1)
                                d[n++] = dist3(c->pts[i].x, c->pts[i + 1].x);
        }
        g->row_step = gn_median(d, n);
        return 0;
}

/* Distance of point p from the turntable axis (z). */
static double radius(const struct sec_point *p)
{
        return hypot(p->x[0], p->x[1]);
}

/* True when the quad a b c d (rows r, r+1 of line A; r+1, r of line B, dtheta degrees on)
 * has no edge longer than its expected length times o->max_edge. */
static bool quad_ok(const struct grid *g, const struct sec_point *a, const struct sec_point *b,
                    const struct sec_point *c, const struct sec_point *d, double dtheta)
{
        double k = g->o->max_edge, lr = k * g->row_step;
        double la0 = k * fmax(g->row_step, (radius(a) + radius(d)) / 2 * dtheta * DEG);
        double la1 = k * fmax(g->row_step, (radius(b) + radius(c)) / 2 * dtheta * DEG);

        return dist3(a->x, b->x) <= lr && dist3(d->x, c->x) <= lr && dist3(a->x, d->x) <= la0 &&
               dist3(b->x, c->x) <= la1;
}

/* The normal n of face f (3 indices into v) by the right-hand rule, its length twice the
 * face's area. */
static void face_normal(const struct sec_point *v, const uint32_t *f, double n[3])
{
        const float *a = v[f[0]].x, *b = v[f[1]].x, *c = v[f[2]].x;
        double e[3], g[3];

        for (int q = 0; q < 3; q++) {
                e[q] = (double)b[q] - a[q];
                g[q] = (double)c[q] - a[q];
        }
        n[0] = e[1] * g[2] - e[2] * g[1];
        n[1] = e[2] * g[0] - e[0] * g[2];
        n[2] = e[0] * g[1] - e[1] * g[0];
}

/* Appends face i j k and counts whether it faces the camera of line `line`. */
static void add_face(struct grid *g, uint32_t i, uint32_t j, uint32_t k, size_t line)
{
        const float *a = g->c->pts[i].x;
        const double *eye = g->c->lines[line].eye;
        uint32_t *t = g->m->tri + 3 * g->m->n_tri++;
        double n[3], s = 0;

        t[0] = i;
        t[1] = j;
        t[2] = k;
        face_normal(g->c->pts, t, n);
        for (int q = 0; q < 3; q++)
                s += n[q] * (eye[q] - a[q]);
        g->vote += s > 0 ? 1 : s < 0 ? -1 : 0;
}

/* Adds the quad a b c d (point indices, in this cyclic order) as two triangles split along
 * the shorter diagonal. */
static void add_quad(struct grid *g, uint32_t a, uint32_t b, uint32_t c, uint32_t d, size_t line)
{
        const struct sec_point *p = g->c->pts;

        if (dist3(p[a].x, p[c].x) <= dist3(p[b].x, p[d].x)) {
                add_face(g, a, b, c, line);
                add_face(g, a, c, d, line);
        } else {
                add_face(g, a, b, d, line);
                add_face(g, b, c, d, line);
        }
}

/* Joins lines ia and ib (indices into c->lines) dtheta degrees apart: for each pair of
 * neighbouring rows both lines have, a quad when its edges pass quad_ok. */
static void join(struct grid *g, size_t ia, size_t ib, double dtheta)
{
        const struct sec_ctx *c = g->c;
        const struct sec_line *A = &c->lines[ia], *B = &c->lines[ib];
        size_t j = B->first, jend = B->first + B->count;

        for (size_t i = A->first; i + 1 < A->first + A->count; i++) {
                int32_t r = c->pts[i].row;
                if (c->pts[i + 1].row != r + 1)
                        continue;
                while (j < jend && c->pts[j].row < r)
                        j++;
                if (j + 1 >= jend || c->pts[j].row != r || c->pts[j + 1].row != r + 1)
                        continue;
                if (quad_ok(g, &c->pts[i], &c->pts[i + 1], &c->pts[j + 1], &c->pts[j], dtheta))
                        add_quad(g, (uint32_t)i, (uint32_t)i + 1, (uint32_t)j + 1, (uint32_t)j, ia);
        }
}

static double line_deg(const struct grid *g, size_t k)
{
        return g->c->lines[g->line[k]].turntable_deg;
}

/* Joins the consecutive lines of g, and the last to the first when they close the turn. */
static int join_laser(struct grid *g)
{
        _cleanup_free_ double *step = malloc(g->n * sizeof(*step));
        double wrap, med;

        if (!step)
                return -ENOMEM;
        for (size_t k = 0; k + 1 < g->n; k++) {
                step[k] = line_deg(g, k + 1) - line_deg(g, k);
                join(g, g->line[k], g->line[k + 1], step[k]);
        }
        med = gn_median(step, g->n - 1);
        wrap = line_deg(g, 0) + 360 - line_deg(g, g->n - 1);
        if (g->n >= 3 && med > 0 && wrap > 0 && wrap <= g->o->seam_step * med) {
                join(g, g->line[g->n - 1], g->line[0], wrap);
                g->m->seams_closed++;
        }
        return 0;
}

/* Meshes the lines of laser l, wound towards the camera by a majority of the faces. */
static int mesh_laser(const struct sec_ctx *c, const struct cal_mesh_opts *o, int l, size_t *line,
                      struct cal_mesh *m)
{
        struct grid g = {.c = c, .o = o, .line = line, .m = m};
        size_t first = m->n_tri;
        int r;

        for (size_t i = 0; i < c->n_lines; i++)
                if (c->lines[i].laser == l)
                        line[g.n++] = i;
        if (g.n < 2)
                return 0;
        if ((r = row_step(&g)) < 0 || (r = join_laser(&g)) < 0)
                return r;
        if (g.vote < 0) /* the grid's handedness is one for all its faces */
                for (size_t t = first; t < m->n_tri; t++) {
                        uint32_t s = m->tri[3 * t + 1];
                        m->tri[3 * t + 1] = m->tri[3 * t + 2];
                        m->tri[3 * t + 2] = s;
                }
        return 0;
}

/* Drops the vertices no face uses and renumbers the faces; map has room for m->n_v. */
static void compact(struct cal_mesh *m, uint32_t *map)
{
        size_t n = 0;

        memset(map, 0xff, m->n_v * sizeof(*map));
        for (size_t i = 0; i < 3 * m->n_tri; i++)
                map[m->tri[i]] = 0;
        for (size_t i = 0; i < m->n_v; i++)
                if (map[i] == 0) {
                        map[i] = (uint32_t)n;
                        m->v[n++] = m->v[i];
                }
        for (size_t i = 0; i < 3 * m->n_tri; i++)
                m->tri[i] = map[m->tri[i]];
        m->n_v = n;
}

/* Sets each vertex normal to the area-weighted mean of its faces' normals. */
static void vertex_normals(struct cal_mesh *m)
{
        for (size_t i = 0; i < m->n_v; i++)
                memset(m->v[i].n, 0, sizeof(m->v[i].n));
        for (size_t t = 0; t < m->n_tri; t++) {
                const uint32_t *f = m->tri + 3 * t;
                double n[3];
                face_normal(m->v, f, n);
                for (int k = 0; k < 3; k++)
                        for (int q = 0; q < 3; q++)
                                m->v[f[k]].n[q] += (float)n[q];
        }
        for (size_t i = 0; i < m->n_v; i++) {
                float *n = m->v[i].n, len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                for (int q = 0; len > 0 && q < 3; q++)
                        n[q] /= len;
        }
}

int cal_mesh_from_grid(const struct sec_ctx *c, const struct cal_mesh_opts *o, struct cal_mesh *out)
{
        size_t n = c->n_pts ? c->n_pts : 1;
        _cleanup_free_ size_t *line = malloc((c->n_lines ? c->n_lines : 1) * sizeof(*line));
        _cleanup_free_ uint32_t *map = malloc(n * sizeof(*map));
        int r = 0;

        memset(out, 0, sizeof(*out));
        if (!(o->max_edge >= 1) || !(o->seam_step >= 1) || c->n_pts >= UINT32_MAX / 2)
                return -EINVAL;
        out->v = malloc(n * sizeof(*out->v));
        out->tri = malloc(n * 6 * sizeof(*out->tri)); /* at most two faces a point */
        if (!line || !map || !out->v || !out->tri) {
                cal_mesh_free(out);
                return -ENOMEM;
        }
        if (c->n_pts) /* pts is NULL in an empty context */
                memcpy(out->v, c->pts, c->n_pts * sizeof(*out->v));
        out->n_v = c->n_pts;
        for (int l = 0; l < c->n_lasers && r >= 0; l++)
                r = mesh_laser(c, o, l, line, out);
        if (r < 0) {
                cal_mesh_free(out);
                return r;
        }
        compact(out, map);
        vertex_normals(out);
        return 0;
}

/* Drops the faces turned more than FOLD_DEG away from the mean normal of their corners
 * before the simplification: the folds meshoptimizer can make of slivers near the turntable
 * axis (where all lines meet and neighbouring lines are closer than the noise), flipped or
 * standing across the surface with their corners on one line. */
static void drop_folds(struct cal_mesh *m)
{
        size_t n = 0;

        for (size_t t = 0; t < m->n_tri; t++) {
                uint32_t *f = m->tri + 3 * t;
                double n0[3], c[3], s = 0, ln = 0, lc = 0;
                face_normal(m->v, f, n0);
                for (int q = 0; q < 3; q++) {
                        c[q] = (double)m->v[f[0]].n[q] + m->v[f[1]].n[q] + m->v[f[2]].n[q];
                        s += n0[q] * c[q];
                        ln += n0[q] * n0[q];
                        lc += c[q] * c[q];
                }
                if (s > cos(FOLD_DEG * DEG) * sqrt(ln * lc))
                        memmove(m->tri + 3 * n++, f, 3 * sizeof(*f));
        }
        m->folds += m->n_tri - n;
        m->n_tri = n;
}

int cal_mesh_simplify(struct cal_mesh *m, size_t target, double max_error_mm, double *error_mm)
{
        const float *pos = m->n_v ? m->v[0].x : NULL;
        _cleanup_free_ uint32_t *map = NULL;
        uint32_t *dst;
        float scale, err = 0;
        size_t n;

        if (!target || !(max_error_mm > 0))
                return -EINVAL;
        if (error_mm)
                *error_mm = 0;
        if (m->n_tri <= target)
                return 0;
        map = malloc(m->n_v * sizeof(*map));
        dst = malloc(3 * m->n_tri * sizeof(*dst));
        if (!map || !dst) {
                free(dst);
                return -ENOMEM;
        }
        scale = meshopt_simplifyScale(pos, m->n_v, sizeof(*m->v));
        n = meshopt_simplify(dst, m->tri, 3 * m->n_tri, pos, m->n_v, sizeof(*m->v), 3 * target,
                             (float)(max_error_mm / scale), meshopt_SimplifyLockBorder, &err);
        free(m->tri);
        m->tri = dst;
        m->n_tri = n / 3;
        if (error_mm)
                *error_mm = (double)err * scale;
        drop_folds(m);
        compact(m, map);
        vertex_normals(m);
        return 0;
}
