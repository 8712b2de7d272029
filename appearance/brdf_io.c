/* brdf_io.c - the BRDF model on disk (brdf.h; docs/appearance.md, "The BRDF model"):
 * models/<name>/brdf/ of a dataset with brdf.json (jansson; "kind" texel or view), for the
 * texel kind texels.f32 and texels.u32 (the texel maps, little-endian) and mesh.bin (the mesh
 * with its atlas uv), for the view kind views/NNN.f32, NNN.u32 (the same records per pixel)
 * and NNN_points.f32 (each pixel's surface point), written into a temporary directory renamed
 * into place beside an SH model of the same name; read back with every problem named by
 * file, the atlas rebuilt from the mesh and its cell. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "appearance/brdf.h"
#include "appearance/io_internal.h"
#include "common/cleanup.h"
#include "common/fileio.h"

#define TEXEL_FLOATS 14 /* albedo 3, ks, ax, ay, f0, normal 3, tangent 3, rms */
#define TEXEL_U32S   2  /* n_samples, flags */
#define MESH_MAGIC   "GNBRDFM1"

struct ap_brdf_model *ap_brdf_model_free(struct ap_brdf_model *m)
{
        if (!m)
                return NULL;
        ap_atlas_free(&m->atlas);
        free(m->texels);
        for (size_t i = 0; i < m->n_views; i++) {
                free(m->views[i].px);
                free(m->views[i].points);
        }
        free(m->views);
        free(m);
        return NULL;
}

/* ---- writing ---- */

/* The records of the n texels x as files fname (TEXEL_FLOATS a texel) and uname (TEXEL_U32S)
 * in dfd. Returns 0, -EINVAL (a texel that is not ap_brdf_texel_valid) or -errno. */
static int put_texels(int dfd, const char *fname, const char *uname,
                      const struct ap_brdf_texel *texels, size_t n)
{
        _cleanup_free_ float *f = malloc(n * TEXEL_FLOATS * sizeof(float));
        _cleanup_free_ uint32_t *u = malloc(n * TEXEL_U32S * sizeof(uint32_t));
        int r;

        if (!f || !u)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++) { /* little-endian on the hosts we build for */
                const struct ap_brdf_texel *x = &texels[i];
                float *o = f + i * TEXEL_FLOATS;
                if (!ap_brdf_texel_valid(x)) /* it could not be read back */
                        return -EINVAL;
                memcpy(o, x->albedo, 3 * sizeof(float));
                o[3] = x->ks, o[4] = x->ax, o[5] = x->ay, o[6] = x->f0;
                memcpy(o + 7, x->normal, 3 * sizeof(float));
                memcpy(o + 10, x->tangent, 3 * sizeof(float));
                o[13] = x->rms;
                u[i * 2] = x->n_samples, u[i * 2 + 1] = x->flags;
        }
        r = ap_io_put_file(dfd, fname, f, n * TEXEL_FLOATS * sizeof(float));
        return r < 0 ? r : ap_io_put_file(dfd, uname, u, n * TEXEL_U32S * sizeof(uint32_t));
}

/* The files of view i of m into dfd's views/ and its entry into a. */
static int put_view(int dfd, const struct ap_brdf_model *m, size_t i, json_t *a)
{
        const struct ap_brdf_view *v = &m->views[i];
        size_t n = (size_t)v->cam.width * v->cam.height;
        char f[3][64];
        int r;

        snprintf(f[0], sizeof(f[0]), "views/%03zu.f32", i);
        snprintf(f[1], sizeof(f[1]), "views/%03zu.u32", i);
        snprintf(f[2], sizeof(f[2]), "views/%03zu_points.f32", i);
        if ((r = put_texels(dfd, f[0], f[1], v->px, n)) < 0 ||
            (r = ap_io_put_file(dfd, f[2], v->points, 3 * n * sizeof(float))) < 0)
                return r;
        return json_array_append_new(a, json_pack("{s:o,s:o,s:{s:f,s:f},s:s,s:s,s:s}", "dir",
                                                  ap_io_json_vec(v->dir, 3), "geometry",
                                                  ap_io_camera_json(&v->cam), "lobe", "ax",
                                                  (double)v->ax, "ay", (double)v->ay, "texels",
                                                  f[0], "counts", f[1], "points", f[2])) < 0
                       ? -ENOMEM
                       : 0;
}

/* The view kind's files and its part of brdf.json into doc. */
static int put_views(int dfd, const struct ap_brdf_model *m, json_t *doc)
{
        json_t *a = json_array();
        int r = a && json_object_set_new(doc, "views", a) == 0 &&
                                json_object_set_new(doc, "centre", ap_io_json_vec(m->centre, 3)) ==
                                        0
                        ? 0
                        : -ENOMEM;

        if (r == 0 && mkdirat(dfd, "views", 0755) < 0)
                r = -errno;
        for (size_t i = 0; r == 0 && i < m->n_views; i++)
                r = put_view(dfd, m, i, a);
        if (r == 0) {
                _cleanup_close_ int vfd = openat(dfd, "views", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
                r = vfd < 0 || fsync(vfd) < 0 ? -errno : 0;
        }
        return r;
}

static int put_mesh(int dfd, const struct ap_atlas *a)
{
        const struct ap_mesh *me = &a->mesh;
        size_t len = 16 + (3 * me->nv + 9 * me->nt) * 4;
        _cleanup_free_ uint8_t *b = malloc(len);
        uint32_t hdr[2] = {(uint32_t)me->nv, (uint32_t)me->nt};
        uint8_t *p = b;

        if (!b)
                return -ENOMEM;
        memcpy(p, MESH_MAGIC, 8), p += 8;
        memcpy(p, hdr, 8), p += 8;
        memcpy(p, me->pos, 12 * me->nv), p += 12 * me->nv;
        memcpy(p, me->idx, 12 * me->nt), p += 12 * me->nt;
        memcpy(p, a->uv, 24 * me->nt);
        return ap_io_put_file(dfd, "mesh.bin", b, len);
}

/* The texel kind's files and its part of brdf.json into doc. */
static int put_atlas(int dfd, const struct ap_brdf_model *m, json_t *doc)
{
        const struct ap_atlas *a = &m->atlas;
        int r = put_texels(dfd, "texels.f32", "texels.u32", m->texels,
                           (size_t)a->width * a->height);

        if (r == 0)
                r = put_mesh(dfd, a);
        if (r == 0 &&
            (json_object_set_new(doc, "atlas",
                                 json_pack("{s:i,s:i,s:i,s:I,s:I}", "width", a->width, "height",
                                           a->height, "cell", a->cell, "vertices",
                                           (json_int_t)a->mesh.nv, "triangles",
                                           (json_int_t)a->mesh.nt)) < 0 ||
             json_object_set_new(doc, "files",
                                 json_pack("{s:s,s:s,s:s}", "texels", "texels.f32", "counts",
                                           "texels.u32", "mesh", "mesh.bin")) < 0))
                r = -ENOMEM;
        return r;
}

static int put_model(int dfd, const struct ap_brdf_model *m)
{
        bool view = m->kind == AP_BRDF_KIND_VIEW;
        _cleanup_(json_decrefp) json_t *doc =
                json_pack("{s:s,s:s,s:s,s:f,s:s,s:{s:f}}", "format", AP_BRDF_FORMAT, "name",
                          m->name, "kind", view ? "view" : "texel", "response", m->response,
                          "notes", m->notes, "fit", "seconds", m->fit_seconds);
        _cleanup_free_ char *text = NULL;
        int r = !doc ? -ENOMEM : view ? put_views(dfd, m, doc) : put_atlas(dfd, m, doc);

        if (r == 0 && !(text = json_dumps(doc, JSON_INDENT(2))))
                r = -ENOMEM;
        return r < 0 ? r : ap_io_put_file(dfd, "brdf.json", text, strlen(text));
}

int ap_brdf_write(const struct ap_brdf_model *m, const char *ds_dir)
{
        char dir[4200], tmp[4300], final[4300];
        _cleanup_close_ int dfd = -EBADF;
        int r;

        if (!m || !ds_dir || !m->name[0] || strchr(m->name, '/') || m->name[0] == '.' ||
            !(m->kind == AP_BRDF_KIND_VIEW ? m->n_views > 0 : m->texels != NULL))
                return -EINVAL;
        snprintf(dir, sizeof(dir), "%s/models", ds_dir);
        if (mkdir(dir, 0755) < 0 && errno != EEXIST)
                return -errno;
        snprintf(dir, sizeof(dir), "%s/models/%s", ds_dir, m->name);
        if (mkdir(dir, 0755) < 0 && errno != EEXIST)
                return -errno;
        snprintf(final, sizeof(final), "%s/" AP_IO_BRDF_DIR, dir);
        snprintf(tmp, sizeof(tmp), "%s/.brdf.tmp", dir);
        ap_remove_tree(tmp); /* left by an interrupted write */
        if (mkdir(tmp, 0755) < 0)
                return -errno;
        dfd = open(tmp, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        r = dfd < 0 ? -errno : put_model(dfd, m);
        if (r == 0 && fsync(dfd) < 0)
                r = -errno;
        if (r == 0)
                r = ap_io_install_dir(tmp, final);
        if (r < 0)
                ap_remove_tree(tmp);
        return r;
}

/* ---- reading ---- */

/* The mesh of mesh.bin (nv vertices, nt triangles as brdf.json says) into *me. */
static int read_mesh(const struct ap_io_rd *rd, size_t nv, size_t nt, struct ap_mesh *me)
{
        _cleanup_free_ uint8_t *b = NULL;
        size_t len;
        int r = ap_io_slurp(rd, "mesh.bin", 16 + (3 * nv + 9 * nt) * 4, (void **)&b, &len);
        uint32_t hdr[2];

        if (r < 0)
                return r;
        memcpy(hdr, b + 8, 8);
        if (memcmp(b, MESH_MAGIC, 8) != 0 || hdr[0] != nv || hdr[1] != nt)
                return ap_io_bad(rd, "mesh.bin", "not a mesh of %zu vertices and %zu triangles", nv,
                                 nt);
        me->nv = nv, me->nt = nt;
        me->pos = malloc(12 * nv);
        me->idx = malloc(12 * nt);
        if (!me->pos || !me->idx)
                return -ENOMEM;
        memcpy(me->pos, b + 16, 12 * nv);
        memcpy(me->idx, b + 16 + 12 * nv, 12 * nt);
        for (size_t i = 0; i < 3 * nt; i++)
                if (me->idx[i] >= nv)
                        return ap_io_bad(rd, "mesh.bin", "triangle %zu: vertex %u of %zu", i / 3,
                                         me->idx[i], nv);
        return ap_mesh_orient(me);
}

bool ap_brdf_texel_valid(const struct ap_brdf_texel *x)
{
        const float *f[] = {x->albedo, &x->ks,    &x->ax,     &x->ay,
                            &x->f0,    x->normal, x->tangent, &x->rms};
        const int n[] = {3, 1, 1, 1, 1, 3, 3, 1};

        for (size_t i = 0; i < ELEMENTSOF(f); i++)
                for (int k = 0; k < n[i]; k++)
                        if (!isfinite(f[i][k]))
                                return false;
        return (x->flags & ~31u) == 0 &&
               (x->flags & AP_BRDF_MASKED || (x->ax > 0 && x->ay > 0 && x->ks >= 0 && x->ks <= 1));
}

/* One texel from its record; false when it is not ap_brdf_texel_valid. */
static bool texel_of(const float *f, const uint32_t *u, struct ap_brdf_texel *x)
{
        memcpy(x->albedo, f, 3 * sizeof(float));
        x->ks = f[3], x->ax = f[4], x->ay = f[5], x->f0 = f[6];
        memcpy(x->normal, f + 7, 3 * sizeof(float));
        memcpy(x->tangent, f + 10, 3 * sizeof(float));
        x->rms = f[13];
        x->n_samples = u[0], x->flags = u[1];
        return ap_brdf_texel_valid(x);
}

/* The n texels of files fname and uname into *ret (allocated). */
static int read_texels(const struct ap_io_rd *rd, const char *fname, const char *uname, size_t n,
                       struct ap_brdf_texel **ret)
{
        size_t len;
        _cleanup_free_ float *f = NULL;
        _cleanup_free_ uint32_t *u = NULL;
        int r = ap_io_slurp(rd, fname, n * TEXEL_FLOATS * 4, (void **)&f, &len);

        if (r == 0)
                r = ap_io_slurp(rd, uname, n * TEXEL_U32S * 4, (void **)&u, &len);
        if (r < 0)
                return r;
        *ret = calloc(n, sizeof(**ret));
        if (!*ret)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                if (!texel_of(f + i * TEXEL_FLOATS, u + i * TEXEL_U32S, &(*ret)[i]))
                        return ap_io_bad(rd, fname, "texel %zu: a parameter out of range", i);
        return 0;
}

/* The texel kind: brdf.json's atlas, the atlas rebuilt from mesh.bin, the texels. */
static int read_atlas(const struct ap_io_rd *rd, json_t *doc, struct ap_brdf_model *m)
{
        json_int_t nv = 0, nt = 0;
        struct ap_mesh me = {0};
        json_error_t e;
        int w, h, cell, r;

        if (json_unpack_ex(doc, &e, 0, "{s:{s:i,s:i,s:i,s:I,s:I}}", "atlas", "width", &w, "height",
                           &h, "cell", &cell, "vertices", &nv, "triangles", &nt) < 0)
                return ap_io_bad(rd, "brdf.json", "%s", e.text);
        if (nv < 3 || nt < 1 || nv > (1 << 28) || nt > (1 << 28) || cell < 4)
                return ap_io_bad(rd, "brdf.json", "atlas of %lld vertices, %lld triangles, cell %d",
                                 (long long)nv, (long long)nt, cell);
        r = read_mesh(rd, (size_t)nv, (size_t)nt, &me);
        if (r == 0)
                r = ap_atlas_build(&me, cell, &m->atlas);
        ap_mesh_free(&me);
        if (r == 0 && (m->atlas.width != w || m->atlas.height != h))
                return ap_io_bad(rd, "brdf.json", "atlas %dx%d, its mesh and cell give %dx%d", w, h,
                                 m->atlas.width, m->atlas.height);
        if (r == -EINVAL)
                return ap_io_bad(rd, "mesh.bin", "no atlas of cell %d on this mesh", cell);
        return r < 0 ? r
                     : read_texels(rd, "texels.f32", "texels.u32",
                                   (size_t)m->atlas.width * m->atlas.height, &m->texels);
}

/* View i of the view kind: its entry o of brdf.json and its files. */
static int read_view(const struct ap_io_rd *rd, json_t *o, struct ap_brdf_view *v, size_t i)
{
        char where[32], f[3][64];
        size_t n, len;
        int r;

        snprintf(where, sizeof(where), "views[%zu]", i);
        snprintf(f[0], sizeof(f[0]), "views/%03zu.f32", i);
        snprintf(f[1], sizeof(f[1]), "views/%03zu.u32", i);
        snprintf(f[2], sizeof(f[2]), "views/%03zu_points.f32", i);
        double lobe[2] = {0, 0};
        json_error_t e;

        r = ap_io_get_vec(rd, o, "dir", v->dir, 3, where);
        if (r == 0)
                r = ap_io_get_camera(rd, json_object_get(o, "geometry"), &v->cam, where);
        if (r < 0)
                return r;
        if (json_unpack_ex(o, &e, 0, "{s:{s:F,s:F}}", "lobe", "ax", &lobe[0], "ay", &lobe[1]) < 0 ||
            !(lobe[0] >= 0 && lobe[1] >= 0 && lobe[0] <= 1 && lobe[1] <= 1))
                return ap_io_bad(rd, "brdf.json", "%s: no lobe of ax, ay within 0..1", where);
        v->ax = (float)lobe[0], v->ay = (float)lobe[1];
        n = (size_t)v->cam.width * v->cam.height;
        r = read_texels(rd, f[0], f[1], n, &v->px);
        if (r == 0)
                r = ap_io_slurp(rd, f[2], 3 * n * sizeof(float), (void **)&v->points, &len);
        return r;
}

/* The view kind: brdf.json's views and centre, each view's files. */
static int read_views(const struct ap_io_rd *rd, json_t *doc, struct ap_brdf_model *m)
{
        json_t *a = json_object_get(doc, "views");
        size_t n = json_array_size(a);
        int r = ap_io_get_vec(rd, doc, "centre", m->centre, 3, "brdf.json");

        if (r < 0)
                return r;
        if (!json_is_array(a) || n == 0 || n > 100000)
                return ap_io_bad(rd, "brdf.json", "'views' is not an array of views");
        if (!(m->views = calloc(n, sizeof(*m->views))))
                return -ENOMEM;
        for (m->n_views = 0; r == 0 && m->n_views < n; m->n_views++)
                r = read_view(rd, json_array_get(a, m->n_views), &m->views[m->n_views], m->n_views);
        return r;
}

/* brdf.json's fields into m, then the kind's. */
static int read_header(const struct ap_io_rd *rd, json_t *doc, struct ap_brdf_model *m)
{
        const char *fmt = "", *name = "", *notes = "", *kind = "texel";
        json_error_t e;

        if (json_unpack_ex(doc, &e, 0, "{s:s,s:s,s?s,s:F,s:s}", "format", &fmt, "name", &name,
                           "kind", &kind, "response", &m->response, "notes", &notes) < 0)
                return ap_io_bad(rd, "brdf.json", "%s", e.text);
        if (strcmp(fmt, AP_BRDF_FORMAT) != 0)
                return ap_io_bad(rd, "brdf.json", "format '%s', expected '%s'", fmt,
                                 AP_BRDF_FORMAT);
        if (strcmp(kind, "texel") != 0 && strcmp(kind, "view") != 0)
                return ap_io_bad(rd, "brdf.json", "kind '%s', expected texel or view", kind);
        snprintf(m->name, sizeof(m->name), "%s", name);
        snprintf(m->notes, sizeof(m->notes), "%s", notes);
        json_unpack(doc, "{s?{s?F}}", "fit", "seconds", &m->fit_seconds);
        m->kind = kind[0] == 'v' ? AP_BRDF_KIND_VIEW : AP_BRDF_KIND_TEXEL;
        return m->kind == AP_BRDF_KIND_VIEW ? read_views(rd, doc, m) : read_atlas(rd, doc, m);
}

int ap_brdf_read(const char *dir, struct ap_brdf_model **ret, char *err, size_t errlen)
{
        char sub[4200];
        struct ap_io_rd rd = {sub, err, errlen, "brdf.json"};
        _cleanup_(json_decrefp) json_t *doc = NULL;
        _cleanup_free_ void *text = NULL;
        struct ap_brdf_model *m;
        json_error_t e;
        size_t len;
        int r;

        *ret = NULL;
        snprintf(sub, sizeof(sub), "%s/" AP_IO_BRDF_DIR, dir);
        r = ap_io_slurp(&rd, "brdf.json", 0, &text, &len);
        if (r < 0)
                return r == -EBADMSG ? -ENOENT : r;
        doc = json_loadb(text, len, 0, &e);
        if (!doc)
                return ap_io_bad(&rd, "brdf.json", "line %d: %s", e.line, e.text);
        m = calloc(1, sizeof(*m));
        if (!m)
                return -ENOMEM;
        r = read_header(&rd, doc, m);
        if (r < 0) {
                ap_brdf_model_free(m);
                return r;
        }
        *ret = m;
        return 0;
}
