/* brdf_io.c - the BRDF model on disk (brdf.h; docs/appearance.md, "The BRDF model"):
 * models/<name>/brdf/ of a dataset with brdf.json (jansson), texels.f32 and texels.u32 (the
 * texel maps, little-endian) and mesh.bin (the mesh with its atlas uv), written into a
 * temporary directory renamed into place beside an SH model of the same name; read back with
 * every problem named by file, the atlas rebuilt from the mesh and its cell. */
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
        free(m);
        return NULL;
}

/* ---- writing ---- */

static int put_texels(int dfd, const struct ap_brdf_model *m)
{
        size_t n = (size_t)m->atlas.width * m->atlas.height;
        _cleanup_free_ float *f = malloc(n * TEXEL_FLOATS * sizeof(float));
        _cleanup_free_ uint32_t *u = malloc(n * TEXEL_U32S * sizeof(uint32_t));
        int r;

        if (!f || !u)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++) { /* little-endian on the hosts we build for */
                const struct ap_brdf_texel *x = &m->texels[i];
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
        r = ap_io_put_file(dfd, "texels.f32", f, n * TEXEL_FLOATS * sizeof(float));
        return r < 0 ? r : ap_io_put_file(dfd, "texels.u32", u, n * TEXEL_U32S * sizeof(uint32_t));
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

static int put_json(int dfd, const struct ap_brdf_model *m)
{
        const struct ap_atlas *a = &m->atlas;
        _cleanup_(json_decrefp) json_t *doc =
                json_pack("{s:s,s:s,s:{s:i,s:i,s:i,s:I,s:I},s:f,s:s,s:{s:f},s:{s:s,s:s,s:s}}",
                          "format", AP_BRDF_FORMAT, "name", m->name, "atlas", "width", a->width,
                          "height", a->height, "cell", a->cell, "vertices", (json_int_t)a->mesh.nv,
                          "triangles", (json_int_t)a->mesh.nt, "response", m->response, "notes",
                          m->notes, "fit", "seconds", m->fit_seconds, "files", "texels",
                          "texels.f32", "counts", "texels.u32", "mesh", "mesh.bin");
        _cleanup_free_ char *text = doc ? json_dumps(doc, JSON_INDENT(2)) : NULL;

        return text ? ap_io_put_file(dfd, "brdf.json", text, strlen(text)) : -ENOMEM;
}

int ap_brdf_write(const struct ap_brdf_model *m, const char *ds_dir)
{
        char dir[4200], tmp[4300], final[4300];
        _cleanup_close_ int dfd = -EBADF;
        int r;

        if (!m || !ds_dir || !m->name[0] || strchr(m->name, '/') || m->name[0] == '.' || !m->texels)
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
        r = dfd < 0 ? -errno : put_texels(dfd, m);
        if (r == 0)
                r = put_mesh(dfd, &m->atlas);
        if (r == 0)
                r = put_json(dfd, m);
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
        return (x->flags & ~7u) == 0 &&
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

static int read_texels(const struct ap_io_rd *rd, struct ap_brdf_model *m)
{
        size_t n = (size_t)m->atlas.width * m->atlas.height, len;
        _cleanup_free_ float *f = NULL;
        _cleanup_free_ uint32_t *u = NULL;
        int r = ap_io_slurp(rd, "texels.f32", n * TEXEL_FLOATS * 4, (void **)&f, &len);

        if (r == 0)
                r = ap_io_slurp(rd, "texels.u32", n * TEXEL_U32S * 4, (void **)&u, &len);
        if (r < 0)
                return r;
        m->texels = calloc(n, sizeof(*m->texels));
        if (!m->texels)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                if (!texel_of(f + i * TEXEL_FLOATS, u + i * TEXEL_U32S, &m->texels[i]))
                        return ap_io_bad(rd, "texels.f32", "texel %zu: a parameter out of range",
                                         i);
        return 0;
}

/* brdf.json's fields into m, the atlas rebuilt from mesh.bin. */
static int read_header(const struct ap_io_rd *rd, json_t *doc, struct ap_brdf_model *m)
{
        const char *fmt = "", *name = "", *notes = "";
        json_int_t nv = 0, nt = 0;
        struct ap_mesh me = {0};
        json_error_t e;
        int w, h, cell, r;

        if (json_unpack_ex(doc, &e, 0, "{s:s,s:s,s:{s:i,s:i,s:i,s:I,s:I},s:F,s:s}", "format", &fmt,
                           "name", &name, "atlas", "width", &w, "height", &h, "cell", &cell,
                           "vertices", &nv, "triangles", &nt, "response", &m->response, "notes",
                           &notes) < 0)
                return ap_io_bad(rd, "brdf.json", "%s", e.text);
        if (strcmp(fmt, AP_BRDF_FORMAT) != 0)
                return ap_io_bad(rd, "brdf.json", "format '%s', expected '%s'", fmt,
                                 AP_BRDF_FORMAT);
        if (nv < 3 || nt < 1 || nv > (1 << 28) || nt > (1 << 28) || cell < 4)
                return ap_io_bad(rd, "brdf.json", "atlas of %lld vertices, %lld triangles, cell %d",
                                 (long long)nv, (long long)nt, cell);
        snprintf(m->name, sizeof(m->name), "%s", name);
        snprintf(m->notes, sizeof(m->notes), "%s", notes);
        json_unpack(doc, "{s?{s?F}}", "fit", "seconds", &m->fit_seconds);
        r = read_mesh(rd, (size_t)nv, (size_t)nt, &me);
        if (r == 0)
                r = ap_atlas_build(&me, cell, &m->atlas);
        ap_mesh_free(&me);
        if (r == 0 && (m->atlas.width != w || m->atlas.height != h))
                return ap_io_bad(rd, "brdf.json", "atlas %dx%d, its mesh and cell give %dx%d", w, h,
                                 m->atlas.width, m->atlas.height);
        return r == -EINVAL ? ap_io_bad(rd, "mesh.bin", "no atlas of cell %d on this mesh", cell)
                            : r;
}

int ap_brdf_read(const char *dir, struct ap_brdf_model **ret, char *err, size_t errlen)
{
        char sub[4200];
        struct ap_io_rd rd = {sub, err, errlen};
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
        if (r == 0)
                r = read_texels(&rd, m);
        if (r < 0) {
                ap_brdf_model_free(m);
                return r;
        }
        *ret = m;
        return 0;
}
