/* meshio.c - object meshes from files: PLY (ascii, binary little/big endian; vertex x y z,
 * optional nx ny nz and u v / s t / texture_u texture_v; faces as index lists) and
 * Wavefront OBJ (v, vt, vn, f with v, v/t, v//n, v/t/n, negative indices). Polygons are
 * split into triangle fans. */
#include <ctype.h>
#include <endian.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "internal.h"

#define MESH_MAX_ELEMS 50000000

/* Growable array of floats or indices. */
struct fbuf {
        float *v;
        size_t n, cap;
};

static int fbuf_push(struct fbuf *b, float x)
{
        if (b->n == b->cap) {
                size_t cap = b->cap ? 2 * b->cap : 1024;
                float *v = realloc(b->v, cap * sizeof(float));
                if (!v)
                        return -ENOMEM;
                b->v = v;
                b->cap = cap;
        }
        b->v[b->n++] = x;
        return 0;
}

static void fbuf_free(struct fbuf *b)
{
        free(b->v);
}

/* ---------------- OBJ ---------------- */

struct obj {
        struct fbuf v, vt, vn;
        struct fbuf corners; /* (v, vt, vn) index triples, -1 when absent, as floats */
};

static int obj_index(const char *tok, size_t n, long *out)
{
        char *end;
        long i = strtol(tok, &end, 10);

        if (end == tok)
                return 0;
        i = i < 0 ? (long)n + i : i - 1;
        if (i < 0 || (size_t)i >= n)
                return -ERANGE;
        *out = i;
        return 1;
}

static int obj_corner(struct obj *o, const char *tok)
{
        long iv = -1, it = -1, in = -1;
        const char *s1 = strchr(tok, '/'), *s2 = s1 ? strchr(s1 + 1, '/') : NULL;
        int r = obj_index(tok, o->v.n / 3, &iv);

        if (r <= 0)
                return r < 0 ? r : -EBADMSG;
        if (s1 && s1[1] != '/' && (r = obj_index(s1 + 1, o->vt.n / 2, &it)) < 0)
                return r;
        if (s2 && (r = obj_index(s2 + 1, o->vn.n / 3, &in)) < 0)
                return r;
        if (fbuf_push(&o->corners, iv) || fbuf_push(&o->corners, it) || fbuf_push(&o->corners, in))
                return -ENOMEM;
        return 0;
}

static int obj_face(struct obj *o, char *rest)
{
        char *save = NULL, *tok;
        size_t first = o->corners.n, k = 0;
        float c0[3], cp[3];
        int r;

        /* fan: re-emit (first, previous, current) for every corner past the third */
        for (tok = strtok_r(rest, " \t\r\n", &save); tok; tok = strtok_r(NULL, " \t\r\n", &save)) {
                if (k >= 3) {
                        size_t cur = o->corners.n;
                        memcpy(cp, o->corners.v + cur - 3, sizeof(cp));
                        for (int i = 0; i < 3; i++)
                                if (fbuf_push(&o->corners, c0[i]))
                                        return -ENOMEM;
                        for (int i = 0; i < 3; i++)
                                if (fbuf_push(&o->corners, cp[i]))
                                        return -ENOMEM;
                }
                r = obj_corner(o, tok);
                if (r < 0)
                        return r;
                if (k == 0)
                        memcpy(c0, o->corners.v + first, sizeof(c0));
                k++;
        }
        return k >= 3 ? 0 : -EBADMSG;
}

static int obj_line(struct obj *o, char *line)
{
        float a[3] = {0};

        if (!strncmp(line, "v ", 2) || !strncmp(line, "vn ", 3)) {
                struct fbuf *b = line[1] == 'n' ? &o->vn : &o->v;
                if (sscanf(line + 2, "%f %f %f", &a[0], &a[1], &a[2]) != 3)
                        return -EBADMSG;
                for (int i = 0; i < 3; i++)
                        if (fbuf_push(b, a[i]))
                                return -ENOMEM;
        } else if (!strncmp(line, "vt ", 3)) {
                if (sscanf(line + 3, "%f %f", &a[0], &a[1]) < 1)
                        return -EBADMSG;
                if (fbuf_push(&o->vt, a[0]) || fbuf_push(&o->vt, a[1]))
                        return -ENOMEM;
        } else if (!strncmp(line, "f ", 2)) {
                return obj_face(o, line + 2);
        }
        return 0;
}

/* Every triangle corner becomes its own vertex (keeps per-corner uv and normals). */
static int obj_to_mesh(struct obj *o, struct mesh *m)
{
        size_t nc = o->corners.n / 3;
        bool has_n = o->vn.n > 0, has_t = o->vt.n > 0;
        int r = mesh_alloc(m, nc, nc / 3, has_n, has_t);

        if (r < 0)
                return r;
        for (size_t i = 0; i < nc; i++) {
                long iv = (long)o->corners.v[3 * i], it = (long)o->corners.v[3 * i + 1];
                long in = (long)o->corners.v[3 * i + 2];
                memcpy(m->pos + 3 * i, o->v.v + 3 * iv, 3 * sizeof(float));
                if (has_t && it >= 0)
                        memcpy(m->uv + 2 * i, o->vt.v + 2 * it, 2 * sizeof(float));
                if (has_n && in >= 0)
                        memcpy(m->nrm + 3 * i, o->vn.v + 3 * in, 3 * sizeof(float));
                m->idx[i] = (uint32_t)i;
        }
        return 0;
}

static int load_obj(FILE *f, struct mesh *m, int *line_no)
{
        struct obj o = {0};
        char line[4096];
        int r = 0;

        while (r >= 0 && fgets(line, sizeof(line), f)) {
                (*line_no)++;
                r = obj_line(&o, line);
        }
        if (r >= 0)
                r = o.corners.n >= 9 ? obj_to_mesh(&o, m) : -ENODATA;
        fbuf_free(&o.v);
        fbuf_free(&o.vt);
        fbuf_free(&o.vn);
        fbuf_free(&o.corners);
        return r;
}

/* ---------------- PLY ---------------- */

enum ply_fmt { PLY_ASCII, PLY_LE, PLY_BE };

struct ply_prop {
        char name[32];
        int type, count_type; /* sizes in bytes, + 0x10 for float types; count_type 0: scalar */
};

struct ply_elem {
        char name[32];
        size_t count;
        struct ply_prop props[16];
        int n_props;
};

struct ply {
        enum ply_fmt fmt;
        struct ply_elem elems[8];
        int n_elems;
};

static int ply_type(const char *s)
{
        static const struct {
                const char *name;
                int code;
        } types[] = {
                {"char", 1},     {"int8", 1},       {"uchar", 1},     {"uint8", 1},
                {"short", 2},    {"int16", 2},      {"ushort", 2},    {"uint16", 2},
                {"int", 4},      {"int32", 4},      {"uint", 4},      {"uint32", 4},
                {"float", 0x14}, {"float32", 0x14}, {"double", 0x18}, {"float64", 0x18},
        };
        for (size_t i = 0; i < ELEMENTSOF(types); i++)
                if (!strcmp(s, types[i].name))
                        return types[i].code | (s[0] == 'u' ? 0x100 : 0);
        return -EBADMSG;
}

static int ply_header_line(struct ply *p, char *line)
{
        char a[32], b[32], c[32], d[32];
        unsigned long n;

        if (sscanf(line, "format %31s", a) == 1) {
                p->fmt = !strcmp(a, "ascii")                  ? PLY_ASCII
                         : !strcmp(a, "binary_little_endian") ? PLY_LE
                                                              : PLY_BE;
        } else if (sscanf(line, "element %31s %lu", a, &n) == 2) {
                if (p->n_elems == ELEMENTSOF(p->elems) || n > MESH_MAX_ELEMS)
                        return -E2BIG;
                struct ply_elem *e = &p->elems[p->n_elems++];
                memset(e, 0, sizeof(*e));
                snprintf(e->name, sizeof(e->name), "%s", a);
                e->count = n;
        } else if (sscanf(line, "property list %31s %31s %31s", a, b, c) == 3) {
                struct ply_elem *e = p->n_elems ? &p->elems[p->n_elems - 1] : NULL;
                if (!e || e->n_props == ELEMENTSOF(e->props))
                        return -EBADMSG;
                struct ply_prop *pr = &e->props[e->n_props++];
                snprintf(pr->name, sizeof(pr->name), "%s", c);
                pr->count_type = ply_type(a);
                pr->type = ply_type(b);
                if (pr->count_type < 0 || pr->type < 0)
                        return -EBADMSG;
        } else if (sscanf(line, "property %31s %31s", a, d) == 2) {
                struct ply_elem *e = p->n_elems ? &p->elems[p->n_elems - 1] : NULL;
                if (!e || e->n_props == ELEMENTSOF(e->props))
                        return -EBADMSG;
                struct ply_prop *pr = &e->props[e->n_props++];
                snprintf(pr->name, sizeof(pr->name), "%s", d);
                pr->type = ply_type(a);
                if (pr->type < 0)
                        return -EBADMSG;
        }
        return 0;
}

static int ply_read_value(FILE *f, enum ply_fmt fmt, int type, double *out)
{
        uint8_t b[8];
        int size = type & 0xf;

        if (fmt == PLY_ASCII)
                return fscanf(f, "%lf", out) == 1 ? 0 : -EBADMSG;
        if (fread(b, size, 1, f) != 1)
                return -EBADMSG;
        if ((fmt == PLY_BE) != (__BYTE_ORDER == __BIG_ENDIAN))
                for (int i = 0; i < size / 2; i++) {
                        uint8_t t = b[i];
                        b[i] = b[size - 1 - i];
                        b[size - 1 - i] = t;
                }
        if (type & 0x10) {
                float fv;
                double dv;
                if (size == 4)
                        memcpy(&fv, b, 4), *out = fv;
                else
                        memcpy(&dv, b, 8), *out = dv;
                return 0;
        }
        bool u = type & 0x100;
        switch (size) {
        case 1:
                *out = u ? (double)b[0] : (double)(int8_t)b[0];
                break;
        case 2: {
                uint16_t v;
                memcpy(&v, b, 2);
                *out = u ? (double)v : (double)(int16_t)v;
                break;
        }
        default: {
                uint32_t v;
                memcpy(&v, b, 4);
                *out = u ? (double)v : (double)(int32_t)v;
                break;
        }
        }
        return 0;
}

/* Column of each wanted vertex property: x y z nx ny nz u v. */
static void ply_vertex_cols(const struct ply_elem *e, int col[8])
{
        static const char *names[8][3] = {
                {"x"},
                {"y"},
                {"z"},
                {"nx"},
                {"ny"},
                {"nz"},
                {"u", "s", "texture_u"},
                {"v", "t", "texture_v"},
        };
        for (int k = 0; k < 8; k++) {
                col[k] = -1;
                for (int i = 0; i < e->n_props; i++)
                        for (int a = 0; a < 3 && names[k][a]; a++)
                                if (!strcmp(e->props[i].name, names[k][a]))
                                        col[k] = i;
        }
}

static int ply_vertices(FILE *f, const struct ply *p, const struct ply_elem *e, struct fbuf *vals)
{
        int col[8], r = 0;

        ply_vertex_cols(e, col);
        if (col[0] < 0 || col[1] < 0 || col[2] < 0)
                return -EBADMSG;
        for (size_t i = 0; i < e->count; i++) {
                double row[16] = {0};
                for (int k = 0; k < e->n_props; k++)
                        if (e->props[k].count_type ||
                            (r = ply_read_value(f, p->fmt, e->props[k].type, &row[k])) < 0)
                                return e->props[k].count_type ? -EBADMSG : r;
                for (int k = 0; k < 8; k++)
                        if (fbuf_push(vals, col[k] >= 0 ? (float)row[col[k]] : NAN))
                                return -ENOMEM;
        }
        return 0;
}

static int ply_faces(FILE *f, const struct ply *p, const struct ply_elem *e, struct fbuf *idx)
{
        int r;

        for (size_t i = 0; i < e->count; i++)
                for (int k = 0; k < e->n_props; k++) {
                        const struct ply_prop *pr = &e->props[k];
                        double cnt = 1, v, first = 0, prev = 0;
                        bool is_idx = pr->count_type && (!strcmp(pr->name, "vertex_indices") ||
                                                         !strcmp(pr->name, "vertex_index"));
                        if (pr->count_type &&
                            (r = ply_read_value(f, p->fmt, pr->count_type, &cnt)) < 0)
                                return r;
                        if (!(cnt >= 0 && cnt <= 64)) /* NaN too: (int)NaN is undefined */
                                return -EBADMSG;
                        for (int j = 0; j < (int)cnt; j++) {
                                if ((r = ply_read_value(f, p->fmt, pr->type, &v)) < 0)
                                        return r;
                                if (is_idx && j >= 2 &&
                                    (fbuf_push(idx, first) || fbuf_push(idx, prev) ||
                                     fbuf_push(idx, v)))
                                        return -ENOMEM;
                                first = j == 0 ? v : first;
                                prev = v;
                        }
                }
        return 0;
}

static int ply_to_mesh(const struct fbuf *vals, const struct fbuf *idx, struct mesh *m)
{
        size_t nv = vals->n / 8;
        bool has_n = nv && !isnan(vals->v[3]), has_t = nv && !isnan(vals->v[6]);
        int r = mesh_alloc(m, nv, idx->n / 3, has_n, has_t);

        if (r < 0)
                return r;
        for (size_t i = 0; i < nv; i++) {
                memcpy(m->pos + 3 * i, vals->v + 8 * i, 3 * sizeof(float));
                if (has_n)
                        memcpy(m->nrm + 3 * i, vals->v + 8 * i + 3, 3 * sizeof(float));
                if (has_t)
                        memcpy(m->uv + 2 * i, vals->v + 8 * i + 6, 2 * sizeof(float));
        }
        for (size_t i = 0; i < idx->n; i++) {
                if (!(idx->v[i] >= 0 && idx->v[i] < (float)nv)) /* NaN, huge: no cast */
                        return -ERANGE;
                m->idx[i] = (uint32_t)idx->v[i];
        }
        return 0;
}

static int load_ply(FILE *f, struct mesh *m, int *line_no)
{
        struct ply p = {0};
        struct fbuf vals = {0}, idx = {0};
        char line[512];
        int r = 0;

        while (r >= 0 && fgets(line, sizeof(line), f)) {
                (*line_no)++;
                if (!strncmp(line, "end_header", 10))
                        break;
                r = ply_header_line(&p, line);
        }
        for (int e = 0; r >= 0 && e < p.n_elems; e++) {
                if (!strcmp(p.elems[e].name, "vertex"))
                        r = ply_vertices(f, &p, &p.elems[e], &vals);
                else
                        r = ply_faces(f, &p, &p.elems[e], &idx);
        }
        if (r >= 0)
                r = idx.n >= 3 ? ply_to_mesh(&vals, &idx, m) : -ENODATA;
        fbuf_free(&vals);
        fbuf_free(&idx);
        return r;
}

int mesh_load(const char *path, struct mesh *m, char *err, size_t errlen)
{
        _cleanup_fclose_ FILE *f = fopen(path, "rb");
        const char *ext = strrchr(path, '.');
        int line_no = 0, r;

        if (!f) {
                r = -errno;
                snprintf(err, errlen, "%s: %s", path, strerror(-r));
                return r;
        }
        if (ext && !strcasecmp(ext, ".ply"))
                r = load_ply(f, m, &line_no);
        else if (ext && !strcasecmp(ext, ".obj"))
                r = load_obj(f, m, &line_no);
        else
                r = -EPROTONOSUPPORT;
        if (r < 0) {
                mesh_free(m);
                snprintf(err, errlen, "%s:%d: cannot load mesh: %s", path, line_no,
                         r == -EPROTONOSUPPORT ? "not a .ply or .obj file" : strerror(-r));
        }
        return r;
}
