/* meshread.c - mesh checks and file readers of the scan tests (see meshread.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "meshread.h"
#include "tests/test.h"

#define MR_MAX_PROPS 16

void mr_face_normal(const struct sec_point *v, const uint32_t *f, double n[3], double c[3])
{
        const float *a = v[f[0]].x, *b = v[f[1]].x, *d = v[f[2]].x;
        double e[3], g[3], len;

        for (int q = 0; q < 3; q++) {
                e[q] = (double)b[q] - a[q];
                g[q] = (double)d[q] - a[q];
                c[q] = ((double)a[q] + b[q] + d[q]) / 3;
        }
        n[0] = e[1] * g[2] - e[2] * g[1];
        n[1] = e[2] * g[0] - e[0] * g[2];
        n[2] = e[0] * g[1] - e[1] * g[0];
        len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int q = 0; q < 3; q++)
                n[q] /= len;
}

static int cmp_u64(const void *a, const void *b)
{
        uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;

        return (x > y) - (x < y);
}

/* Whether the sorted array e of n holds x. */
static int has(const uint64_t *e, size_t n, uint64_t x)
{
        return bsearch(&x, e, n, sizeof(*e), cmp_u64) != NULL;
}

size_t mr_check_edges(const uint32_t *f, size_t n)
{
        _cleanup_free_ uint64_t *e = malloc((3 * n + 1) * sizeof(*e));
        size_t border = 0;

        CHECK(e);
        for (size_t t = 0; t < n; t++)
                for (int k = 0; k < 3; k++)
                        e[3 * t + k] = (uint64_t)f[3 * t + k] << 32 | f[3 * t + (k + 1) % 3];
        qsort(e, 3 * n, sizeof(*e), cmp_u64);
        for (size_t i = 0; i < 3 * n; i++) {
                CHECK(i == 0 || e[i] != e[i - 1]); /* walked twice the same way */
                border += !has(e, 3 * n, e[i] >> 32 | e[i] << 32);
        }
        return border;
}

static uint64_t key(const struct sec_point *p)
{
        return (uint64_t)(uint32_t)p->line << 32 | (uint32_t)p->row;
}

size_t mr_border_vertices(const struct cal_mesh *m, uint64_t **keys)
{
        _cleanup_free_ uint64_t *e = malloc((3 * m->n_tri + 1) * sizeof(*e));
        uint64_t *k = malloc((6 * m->n_tri + 1) * sizeof(*k));
        size_t n = 0, u = 0;

        CHECK(e && k);
        for (size_t t = 0; t < m->n_tri; t++)
                for (int j = 0; j < 3; j++)
                        e[3 * t + j] =
                                (uint64_t)m->tri[3 * t + j] << 32 | m->tri[3 * t + (j + 1) % 3];
        qsort(e, 3 * m->n_tri, sizeof(*e), cmp_u64);
        for (size_t i = 0; i < 3 * m->n_tri; i++)
                if (!has(e, 3 * m->n_tri, e[i] >> 32 | e[i] << 32)) {
                        k[n++] = key(&m->v[e[i] >> 32]);
                        k[n++] = key(&m->v[(uint32_t)e[i]]);
                }
        qsort(k, n, sizeof(*k), cmp_u64);
        for (size_t i = 0; i < n; i++)
                if (!u || k[i] != k[u - 1])
                        k[u++] = k[i];
        *keys = k;
        return u;
}

bool mr_has_vertex(const struct cal_mesh *m, uint64_t k)
{
        for (size_t i = 0; i < m->n_v; i++)
                if (key(&m->v[i]) == k)
                        return true;
        return false;
}

/* A PLY element: name, count, properties (a list: count type and item type). */
struct ply_elem {
        char name[32];
        size_t count;
        int n_props;
        struct {
                char name[32];
                int size, list_size; /* bytes of the value (of an item for a list); list: count */
                char type[16];
        } p[MR_MAX_PROPS];
};

/* Bytes of a PLY scalar type (both spellings of the spec), 0 if unknown. */
static int type_size(const char *t)
{
        static const char *const names[][2] = {
                {"char", "int8"}, {"uchar", "uint8"}, {"short", "int16"},   {"ushort", "uint16"},
                {"int", "int32"}, {"uint", "uint32"}, {"float", "float32"}, {"double", "float64"}};
        static const int sizes[] = {1, 1, 2, 2, 4, 4, 4, 8};

        for (int i = 0; i < 8; i++)
                if (!strcmp(t, names[i][0]) || !strcmp(t, names[i][1]))
                        return sizes[i];
        return 0;
}

/* Parses the header at buf; returns the start of the data and fills e (*n elements). */
static const char *ply_header(const char *buf, struct ply_elem *e, int *n)
{
        const char *s = buf;
        char line[256], a[32], b[32], c[32];

        *n = 0;
        CHECK(!strncmp(s, "ply\n", 4));
        while ((s = strchr(s, '\n') + 1) && strncmp(s, "end_header\n", 11)) {
                size_t len = strcspn(s, "\n");
                snprintf(line, sizeof(line), "%.*s", (int)len, s);
                if (!strncmp(line, "format ", 7))
                        CHECK_STR(line, "format binary_little_endian 1.0");
                else if (sscanf(line, "element %31s %zu", a, &e[*n].count) == 2) {
                        snprintf(e[*n].name, sizeof(e[*n].name), "%s", a);
                        e[(*n)++].n_props = 0;
                } else if (sscanf(line, "property list %31s %31s %31s", a, b, c) == 3) {
                        struct ply_elem *x = &e[*n - 1];
                        snprintf(x->p[x->n_props].name, 32, "%s", c);
                        x->p[x->n_props].list_size = type_size(a);
                        x->p[x->n_props++].size = type_size(b);
                } else if (sscanf(line, "property %31s %31s", a, b) == 2) {
                        struct ply_elem *x = &e[*n - 1];
                        snprintf(x->p[x->n_props].name, 32, "%s", b);
                        snprintf(x->p[x->n_props].type, 16, "%s", a);
                        x->p[x->n_props].list_size = 0;
                        x->p[x->n_props++].size = type_size(a);
                } else
                        CHECK(!strncmp(line, "comment", 7) || !strncmp(line, "obj_info", 8));
        }
        return s + 11;
}

/* The value of a little-endian scalar of size bytes at b (float for 4-byte "float"). */
static double ply_value(const uint8_t *b, int size, const char *type)
{
        uint64_t u = 0;
        float f;

        for (int i = 0; i < size; i++)
                u |= (uint64_t)b[i] << (8 * i);
        if (!strcmp(type, "float") || !strcmp(type, "float32")) {
                uint32_t w = (uint32_t)u;
                memcpy(&f, &w, 4);
                return f;
        }
        return (double)u;
}

/* Stores property p (value x) of vertex v. */
static void ply_vertex_prop(struct sec_point *v, const char *p, double x)
{
        static const char *const names[] = {"x",  "y",   "z",     "nx",  "ny",
                                            "nz", "red", "green", "blue"};

        for (int k = 0; k < 9; k++)
                if (!strcmp(p, names[k])) {
                        if (k < 3)
                                v->x[k] = (float)x;
                        else if (k < 6)
                                v->n[k - 3] = (float)x;
                        else
                                v->rgb[k - 6] = (uint8_t)x;
                }
}

/* Reads the faces of element e at *b into out. */
static void ply_faces(const struct ply_elem *e, const uint8_t **b, struct cal_mesh *out)
{
        CHECK(e->n_props == 1 && !strcmp(e->p[0].name, "vertex_indices"));
        CHECK(out->tri = calloc(3 * e->count + 1, sizeof(*out->tri)));
        for (size_t t = 0; t < e->count; t++) {
                CHECK(ply_value(*b, e->p[0].list_size, "") == 3);
                *b += e->p[0].list_size;
                for (int k = 0; k < 3; k++, *b += e->p[0].size)
                        out->tri[3 * t + k] = (uint32_t)ply_value(*b, e->p[0].size, "");
        }
        out->n_tri = e->count;
}

void mr_read_ply(int dir_fd, const char *name, struct cal_mesh *out)
{
        _cleanup_free_ char *buf = NULL;
        struct ply_elem e[4];
        const uint8_t *b;
        size_t len;
        int n;

        memset(out, 0, sizeof(*out));
        CHECK_INT(gn_read_file_at(dir_fd, name, 1 << 30, (void **)&buf, &len), 0);
        b = (const uint8_t *)ply_header(buf, e, &n);
        CHECK(n >= 1 && n <= 2 && !strcmp(e[0].name, "vertex") && e[0].n_props == 9);
        CHECK(out->v = calloc(e[0].count + 1, sizeof(*out->v)));
        for (size_t i = 0; i < e[0].count; i++)
                for (int k = 0; k < e[0].n_props; b += e[0].p[k++].size)
                        ply_vertex_prop(&out->v[i], e[0].p[k].name,
                                        ply_value(b, e[0].p[k].size, e[0].p[k].type));
        out->n_v = e[0].count;
        if (n == 2) {
                CHECK(!strcmp(e[1].name, "face"));
                ply_faces(&e[1], &b, out);
        }
        CHECK(b == (const uint8_t *)buf + len);
}

void mr_expect_ply(int dir_fd, const char *name, const struct cal_mesh *m)
{
        struct cal_mesh r;

        mr_read_ply(dir_fd, name, &r);
        CHECK(r.n_v == m->n_v && r.n_tri == m->n_tri && r.tri);
        for (size_t i = 0; i < m->n_v; i++)
                CHECK(!memcmp(r.v[i].x, m->v[i].x, sizeof(r.v[i].x)) &&
                      !memcmp(r.v[i].n, m->v[i].n, sizeof(r.v[i].n)) &&
                      !memcmp(r.v[i].rgb, m->v[i].rgb, 3));
        CHECK(!memcmp(r.tri, m->tri, 3 * m->n_tri * sizeof(*m->tri)));
        cal_mesh_free(&r);
}

/* The 0-based index of an OBJ reference s ("7", "-2") among n so far. */
static long obj_index(const char *s, size_t n)
{
        long i = strtol(s, NULL, 10);

        CHECK(i != 0);
        return i > 0 ? i - 1 : (long)n + i;
}

/* Checks face line s (after "f ") against face t of m. */
static void obj_face(const struct cal_mesh *m, size_t t, const char *s, size_t nv, size_t nvn)
{
        char ref[3][64];

        CHECK(sscanf(s, "%63s %63s %63s", ref[0], ref[1], ref[2]) == 3);
        for (int k = 0; k < 3; k++) {
                char *vn = strstr(ref[k], "//") ? strstr(ref[k], "//") + 2
                           : strchr(ref[k], '/') && strchr(strchr(ref[k], '/') + 1, '/')
                                   ? strchr(strchr(ref[k], '/') + 1, '/') + 1
                                   : NULL;
                CHECK(obj_index(ref[k], nv) == m->tri[3 * t + k]);
                CHECK(vn && obj_index(vn, nvn) == m->tri[3 * t + k]); /* normal of the vertex */
        }
}

void mr_expect_obj(int dir_fd, const char *name, const struct cal_mesh *m)
{
        _cleanup_free_ char *buf = NULL;
        size_t len, nv = 0, nvn = 0, nf = 0;
        char *save = NULL;

        CHECK_INT(gn_read_file_at(dir_fd, name, 1 << 30, (void **)&buf, &len), 0);
        for (char *l = strtok_r(buf, "\n", &save); l; l = strtok_r(NULL, "\n", &save)) {
                float x[3], c[3];
                if (!strncmp(l, "v ", 2)) {
                        CHECK(nv < m->n_v);
                        CHECK(sscanf(l + 2, "%f %f %f %f %f %f", x, x + 1, x + 2, c, c + 1,
                                     c + 2) == 6);
                        for (int k = 0; k < 3; k++)
                                CHECK(x[k] == m->v[nv].x[k] &&
                                      lroundf(c[k] * 255) == m->v[nv].rgb[k]);
                        nv++;
                } else if (!strncmp(l, "vn ", 3)) {
                        CHECK(nvn < m->n_v);
                        CHECK(sscanf(l + 3, "%f %f %f", x, x + 1, x + 2) == 3);
                        for (int k = 0; k < 3; k++)
                                CHECK(fabsf(x[k] - m->v[nvn].n[k]) <= 1e-6f);
                        nvn++;
                } else if (!strncmp(l, "f ", 2)) {
                        CHECK(nf < m->n_tri);
                        obj_face(m, nf++, l + 2, nv, nvn);
                } else
                        CHECK(l[0] == '#');
        }
        CHECK(nv == m->n_v && nvn == m->n_v && nf == m->n_tri);
}
