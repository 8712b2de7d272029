/* views.c - the triangulated sphere of sampled view directions (views.h): the convex hull
 * by testing the plane of every triple (view sets are small), coplanar facets (a grid cell
 * of turntable x camera-arm angles, a ring at one elevation) fanned into triangles, holes
 * marked, the boundary edges listed, and a cube map of start faces for a short walk to the
 * face around a direction. Weights are gnomonic barycentrics: those of the point where the
 * ray along the direction meets the face's plane, as in the paper. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/cube.h"
#include "appearance/views.h"
#include "common/cleanup.h"
#include "common/sortx.h"

#define PLANE_EPS      1e-9 /* a point this close to a plane is on it */
#define DUP_COS        (1.0 - 5e-13)
#define BARY_EPS       -1e-6f
#define CUBE_OUTSIDE   AP_VIEWS_OUTSIDE
#define CUBE_TEXEL_RAD (1.5 * M_PI / 2 / AP_VIEWS_CUBE) /* beyond a texel's half diagonal */

struct face {
        int v[3];      /* counter-clockwise seen from outside */
        float e[3][3]; /* e[i] = v[i+1] x v[i+2]: d . e[i] is the weight of v[i] (unnormalised) */
        int nb[3];     /* face across the edge opposite v[i], -1 none */
        double d;      /* plane offset: the face's circumcap has angular radius acos(d) */
        bool hole;
};

struct edge {
        int a, b;
        double n[3]; /* unit a x b */
};

struct ap_views {
        size_t n;
        double (*dir)[3];
        bool *dup;
        struct face *f;
        size_t nf, nf_cap, n_valid;
        struct edge *bnd;
        size_t nb;
        int32_t *cube; /* 6 * AP_VIEWS_CUBE^2 start faces */
};

static double dot3(const double a[3], const double b[3])
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double out[3])
{
        out[0] = a[1] * b[2] - a[2] * b[1];
        out[1] = a[2] * b[0] - a[0] * b[2];
        out[2] = a[0] * b[1] - a[1] * b[0];
}

static bool normalise3(double v[3])
{
        double l = sqrt(dot3(v, v));

        if (!(l > 1e-300))
                return false;
        for (int i = 0; i < 3; i++)
                v[i] /= l;
        return true;
}

static int add_face(struct ap_views *v, int a, int b, int c, double d)
{
        struct face *f;
        const int ix[3] = {a, b, c};

        if (v->nf == v->nf_cap) {
                size_t cap = v->nf_cap ? 2 * v->nf_cap : 64;
                struct face *nf = realloc(v->f, cap * sizeof(*nf));
                if (!nf)
                        return -ENOMEM;
                v->f = nf;
                v->nf_cap = cap;
        }
        f = &v->f[v->nf++];
        *f = (struct face){.v = {a, b, c}, .nb = {-1, -1, -1}, .d = d};
        for (int i = 0; i < 3; i++) {
                double e[3];
                cross3(v->dir[ix[(i + 1) % 3]], v->dir[ix[(i + 2) % 3]], e);
                for (int j = 0; j < 3; j++)
                        f->e[i][j] = (float)e[j];
        }
        return 0;
}

/* The points of the plane (n, d), sorted counter-clockwise about n around their centroid. */
static size_t plane_polygon(const struct ap_views *v, const double n[3], double d, int *out)
{
        double c[3] = {0}, u[3], w[3], ang[v->n];
        size_t m = 0;

        for (size_t l = 0; l < v->n; l++)
                if (!v->dup[l] && fabs(dot3(n, v->dir[l]) - d) <= PLANE_EPS)
                        out[m++] = (int)l;
        for (size_t i = 0; i < m; i++)
                for (int j = 0; j < 3; j++)
                        c[j] += v->dir[out[i]][j] / (double)m;
        for (int j = 0; j < 3; j++)
                u[j] = v->dir[out[0]][j] - c[j];
        normalise3(u);
        cross3(n, u, w);
        for (size_t i = 0; i < m; i++) {
                double p[3] = {v->dir[out[i]][0] - c[0], v->dir[out[i]][1] - c[1],
                               v->dir[out[i]][2] - c[2]};
                ang[out[i]] = atan2(dot3(w, p), dot3(u, p));
        }
        for (size_t i = 1; i < m; i++) /* insertion sort: facets are small */
                for (size_t j = i; j > 0 && ang[out[j]] < ang[out[j - 1]]; j--) {
                        int t = out[j];
                        out[j] = out[j - 1];
                        out[j - 1] = t;
                }
        return m;
}

/* Which side of plane (n, d) the views are on: bit 0 some above, bit 1 some below. */
static int plane_sides(const struct ap_views *v, const double n[3], double d)
{
        int s = 0;

        for (size_t l = 0; l < v->n && s != 3; l++) {
                double h = dot3(n, v->dir[l]) - d;
                s |= h > PLANE_EPS ? 1 : h < -PLANE_EPS ? 2 : 0;
        }
        return s;
}

/* The hull facet through views i < j < k when it is one and they are its three lowest
 * indices: fanned into faces. Returns 1 (added), 0 (not a facet), 2 (all views coplanar). */
static int try_facet(struct ap_views *v, int i, int j, int k)
{
        double e1[3], e2[3], n[3], d;
        int poly[v->n], s, r;
        size_t m;

        for (int a = 0; a < 3; a++) {
                e1[a] = v->dir[j][a] - v->dir[i][a];
                e2[a] = v->dir[k][a] - v->dir[i][a];
        }
        cross3(e1, e2, n);
        if (!normalise3(n))
                return 0;
        d = dot3(n, v->dir[i]);
        s = plane_sides(v, n, d);
        if (s == 0)
                return 2;
        if (s == 3)
                return 0;
        if (s == 1) {
                for (int a = 0; a < 3; a++)
                        n[a] = -n[a];
                d = -d;
        }
        m = plane_polygon(v, n, d, poly);
        for (size_t a = 0; a < m; a++)
                if (poly[a] < k && poly[a] != i && poly[a] != j)
                        return 0;
        for (size_t a = 1; a + 1 < m; a++)
                if ((r = add_face(v, poly[0], poly[a], poly[a + 1], d)) < 0)
                        return r;
        return 1;
}

static int build_hull(struct ap_views *v)
{
        int r;

        for (size_t i = 0; i < v->n; i++)
                for (size_t j = i + 1; j < v->n && !v->dup[i]; j++)
                        for (size_t k = j + 1; k < v->n && !v->dup[j]; k++) {
                                if (v->dup[k])
                                        continue;
                                r = try_facet(v, (int)i, (int)j, (int)k);
                                if (r < 0)
                                        return r;
                                if (r == 2) /* one plane holds every view: no faces */
                                        return 0;
                        }
        return 0;
}

static int mark_holes(struct ap_views *v)
{
        _cleanup_free_ double *rad = malloc((v->nf + 1) * sizeof(double));
        double median;

        if (!rad)
                return -ENOMEM;
        for (size_t i = 0; i < v->nf; i++)
                rad[i] = acos(fmax(-1, fmin(1, v->f[i].d)));
        qsort(rad, v->nf, sizeof(double), gn_cmp_double);
        median = v->nf ? rad[v->nf / 2] : 0;
        for (size_t i = 0; i < v->nf; i++) {
                double ri = acos(fmax(-1, fmin(1, v->f[i].d)));
                v->f[i].hole = v->f[i].d <= 0 || ri > AP_VIEWS_HOLE_RATIO * median;
                v->n_valid += !v->f[i].hole;
        }
        return 0;
}

static bool face_has_edge(const struct face *f, int a, int b)
{
        bool ha = false, hb = false;

        for (int i = 0; i < 3; i++) {
                ha |= f->v[i] == a;
                hb |= f->v[i] == b;
        }
        return ha && hb;
}

static void link_faces(struct ap_views *v)
{
        for (size_t f = 0; f < v->nf; f++)
                for (int i = 0; i < 3; i++) {
                        int a = v->f[f].v[(i + 1) % 3], b = v->f[f].v[(i + 2) % 3];
                        for (size_t g = 0; g < v->nf && v->f[f].nb[i] < 0; g++)
                                if (g != f && face_has_edge(&v->f[g], a, b))
                                        v->f[f].nb[i] = (int)g;
                }
}

static int add_edge(struct ap_views *v, int a, int b)
{
        struct edge *e = realloc(v->bnd, (v->nb + 1) * sizeof(*e));

        if (!e)
                return -ENOMEM;
        v->bnd = e;
        e = &v->bnd[v->nb];
        *e = (struct edge){a, b, {0}};
        cross3(v->dir[a], v->dir[b], e->n);
        if (!normalise3(e->n)) /* antipodal or equal: no arc, vertices only */
                return 0;
        v->nb++;
        return 0;
}

/* Edges of non-hole faces that border a hole or nothing; with no such face, the polygon of
 * the coplanar views (two views: their arc). */
static int list_boundary(struct ap_views *v)
{
        int poly[v->n], r;
        size_t m = 0;

        for (size_t f = 0; f < v->nf; f++)
                for (int i = 0; i < 3 && !v->f[f].hole; i++) {
                        int g = v->f[f].nb[i];
                        if ((g < 0 || v->f[g].hole) &&
                            (r = add_edge(v, v->f[f].v[(i + 1) % 3], v->f[f].v[(i + 2) % 3])) < 0)
                                return r;
                }
        if (v->n_valid)
                return 0;
        for (size_t l = 0; l < v->n; l++)
                if (!v->dup[l])
                        poly[m++] = (int)l;
        if (m == 2)
                return add_edge(v, poly[0], poly[1]);
        if (m < 3)
                return 0;
        {
                double e1[3], e2[3], n[3];
                for (int a = 0; a < 3; a++) {
                        e1[a] = v->dir[poly[1]][a] - v->dir[poly[0]][a];
                        e2[a] = v->dir[poly[2]][a] - v->dir[poly[0]][a];
                }
                cross3(e1, e2, n);
                normalise3(n);
                m = plane_polygon(v, n, dot3(n, v->dir[poly[0]]), poly);
        }
        for (size_t i = 0; i < m; i++)
                if ((r = add_edge(v, poly[i], poly[(i + 1) % m])) < 0)
                        return r;
        return 0;
}

/* Unnormalised gnomonic weights of d in face f; true when d's ray meets f. */
static bool face_weights(const struct face *f, const float d[3], float w[3])
{
        for (int i = 0; i < 3; i++)
                w[i] = d[0] * f->e[i][0] + d[1] * f->e[i][1] + d[2] * f->e[i][2];
        return w[0] + w[1] + w[2] > 0;
}

static int find_face(const struct ap_views *v, const float d[3])
{
        float w[3];

        for (size_t f = 0; f < v->nf; f++)
                if (!v->f[f].hole && face_weights(&v->f[f], d, w) && w[0] >= BARY_EPS &&
                    w[1] >= BARY_EPS && w[2] >= BARY_EPS)
                        return (int)f;
        return -1;
}

/* Cube-map texel of direction d (cube.h), n a side. */
static size_t cube_texel(const float d[3], int n)
{
        float s, t;
        int face = ap_cube_face(d, &s, &t);
        int is = (int)((s + 1) * 0.5f * (float)n), it = (int)((t + 1) * 0.5f * (float)n);

        is = is < 0 ? 0 : is >= n ? n - 1 : is;
        it = it < 0 ? 0 : it >= n ? n - 1 : it;
        return ((size_t)face * (size_t)n + (size_t)it) * (size_t)n + (size_t)is;
}

/* The nearest boundary edge or view of d: up to two views in idx and w; the angle. */
static double nearest_boundary(const struct ap_views *v, const double d[3], int idx[3], float w[3])
{
        double len = sqrt(dot3(d, d)), best = -2; /* the cosine of the nearest's angle */

        for (size_t l = 0; l < v->n; l++) /* vertices: nearest view alone */
                if (!v->dup[l] && dot3(d, v->dir[l]) / len > best) {
                        best = dot3(d, v->dir[l]) / len;
                        idx[0] = idx[1] = idx[2] = (int)l;
                        w[0] = 1, w[1] = w[2] = 0;
                }
        for (size_t i = 0; i < v->nb; i++) {
                const struct edge *e = &v->bnd[i];
                double h = dot3(d, e->n), p[3], c[3], wa, wb, cs;
                for (int j = 0; j < 3; j++)
                        p[j] = d[j] - h * e->n[j];
                cs = sqrt(dot3(p, p)) / len;
                if (cs <= best)
                        continue;
                cross3(p, v->dir[e->b], c);
                wa = dot3(c, e->n);
                cross3(v->dir[e->a], p, c);
                wb = dot3(c, e->n);
                if (wa < 0 || wb < 0 || wa + wb <= 0)
                        continue;
                best = cs;
                idx[0] = e->a, idx[1] = e->b, idx[2] = e->a;
                w[0] = (float)(wa / (wa + wb)), w[1] = (float)(wb / (wa + wb)), w[2] = 0;
        }
        return acos(fmax(-1, fmin(1, best)));
}

/* The start face of the texel around d: the face d is in, else CUBE_OUTSIDE where the
 * whole texel is farther than CUBE_TEXEL_RAD from the covered region, else -1 (search). */
static int32_t texel_start(const struct ap_views *v, const float d[3])
{
        double dd[3] = {d[0], d[1], d[2]};
        int idx[3];
        float w[3];
        int f = find_face(v, d);

        if (f >= 0 || !v->n_valid)
                return f;
        return nearest_boundary(v, dd, idx, w) > CUBE_TEXEL_RAD ? CUBE_OUTSIDE : -1;
}

static int build_cube(struct ap_views *v)
{
        const int n = AP_VIEWS_CUBE;

        v->cube = malloc(6 * (size_t)n * n * sizeof(int32_t));
        if (!v->cube)
                return -ENOMEM;
        for (int face = 0; face < 6; face++)
                for (int it = 0; it < n; it++)
                        for (int is = 0; is < n; is++) {
                                float d[3];
                                ap_cube_dir(face, 2 * (is + 0.5f) / n - 1, 2 * (it + 0.5f) / n - 1,
                                            d);
                                v->cube[cube_texel(d, n)] = texel_start(v, d);
                        }
        return 0;
}

int ap_views_new(const double (*dirs)[3], size_t n, struct ap_views **ret)
{
        struct ap_views *v;
        int r;

        if (!dirs || !ret || n == 0)
                return -EINVAL;
        v = calloc(1, sizeof(*v));
        if (!v)
                return -ENOMEM;
        v->n = n;
        v->dir = malloc(n * sizeof(*v->dir));
        v->dup = calloc(n, sizeof(bool));
        r = v->dir && v->dup ? 0 : -ENOMEM;
        for (size_t i = 0; r >= 0 && i < n; i++) {
                memcpy(v->dir[i], dirs[i], sizeof(v->dir[i]));
                if (!normalise3(v->dir[i]))
                        r = -EINVAL;
                for (size_t j = 0; r >= 0 && j < i && !v->dup[i]; j++)
                        v->dup[i] = !v->dup[j] && dot3(v->dir[i], v->dir[j]) > DUP_COS;
        }
        if (r >= 0 && (r = build_hull(v)) >= 0 && (r = mark_holes(v)) >= 0) {
                link_faces(v);
                if ((r = list_boundary(v)) >= 0)
                        r = build_cube(v);
        }
        if (r < 0) {
                ap_views_free(v);
                return r;
        }
        *ret = v;
        return 0;
}

struct ap_views *ap_views_free(struct ap_views *v)
{
        if (!v)
                return NULL;
        free(v->dir);
        free(v->dup);
        free(v->f);
        free(v->bnd);
        free(v->cube);
        free(v);
        return NULL;
}

size_t ap_views_n_faces(const struct ap_views *v)
{
        return v ? v->n_valid : 0;
}

/* Face f's index among the faces that are not holes; -1 for a hole or none. */
static int valid_index(const struct ap_views *v, int f)
{
        int n = 0;

        if (f < 0 || v->f[f].hole)
                return -1;
        for (int g = 0; g < f; g++)
                n += !v->f[g].hole;
        return n;
}

void ap_views_face(const struct ap_views *v, size_t i, int idx[3], float e[3][3], int nb[3])
{
        for (size_t f = 0; f < v->nf; f++) {
                if (v->f[f].hole || i-- > 0)
                        continue;
                memcpy(idx, v->f[f].v, sizeof(v->f[f].v));
                memcpy(e, v->f[f].e, sizeof(v->f[f].e));
                for (int j = 0; j < 3; j++)
                        nb[j] = valid_index(v, v->f[f].nb[j]);
                return;
        }
}

int ap_views_start(const struct ap_views *v, size_t texel)
{
        int f = v->n_valid ? v->cube[texel] : CUBE_OUTSIDE;

        return f == CUBE_OUTSIDE ? AP_VIEWS_OUTSIDE : valid_index(v, f);
}

size_t ap_views_n_boundary(const struct ap_views *v)
{
        return v->nb;
}

void ap_views_boundary(const struct ap_views *v, size_t i, int ab[2], double n[3])
{
        ab[0] = v->bnd[i].a, ab[1] = v->bnd[i].b;
        memcpy(n, v->bnd[i].n, sizeof(v->bnd[i].n));
}

bool ap_views_is_dup(const struct ap_views *v, size_t i)
{
        return v->dup[i];
}

static int finish(const struct face *f, const float raw[3], int idx[3], float w[3])
{
        float s = raw[0] + raw[1] + raw[2];
        int n = 0;

        for (int i = 0; i < 3; i++) {
                idx[i] = f->v[i];
                w[i] = raw[i] > 0 ? raw[i] / s : 0;
                n += w[i] > 0;
        }
        return n ? n : 1;
}

/* Walks from the cube map's start face to the face around d; -1 when d leaves the
 * triangulated region. */
static int walk(const struct ap_views *v, const float d[3], float raw[3])
{
        int f = v->cube[cube_texel(d, AP_VIEWS_CUBE)];

        if (f == CUBE_OUTSIDE)
                return f;

        for (size_t step = 0; f >= 0 && step < v->nf; step++) {
                int m = 0;
                if (!face_weights(&v->f[f], d, raw))
                        return -1;
                for (int i = 1; i < 3; i++)
                        if (raw[i] < raw[m])
                                m = i;
                if (raw[m] >= BARY_EPS * (raw[0] + raw[1] + raw[2]))
                        return f;
                f = v->f[f].nb[m];
                if (f >= 0 && v->f[f].hole)
                        return -1;
        }
        return -1;
}

int ap_views_weights(const struct ap_views *v, const float d[3], int idx[3], float w[3])
{
        double dd[3] = {d[0], d[1], d[2]};
        float raw[3];
        int f = v->n_valid ? walk(v, d, raw) : CUBE_OUTSIDE;

        if (f == -1 && (f = find_face(v, d)) >= 0)
                face_weights(&v->f[f], d, raw);
        if (f >= 0)
                return finish(&v->f[f], raw, idx, w);
        nearest_boundary(v, dd, idx, w);
        return w[1] > 0 ? 2 : 1;
}

double ap_views_outside_angle(const struct ap_views *v, const double d[3])
{
        float df[3] = {(float)d[0], (float)d[1], (float)d[2]};
        int idx[3];
        float w[3];

        if (find_face(v, df) >= 0)
                return 0;
        return nearest_boundary(v, d, idx, w);
}
