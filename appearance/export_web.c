/* export_web.c - the model as a static web folder (webexport.h): the page's own files, a
 * manifest (data/model.js: the views' cameras and weight quantisation, the views'
 * triangulation, the lights) and the data chunks (data/NAME.js: base64 of gzip) the page
 * loads progressively: the mesh, the PCA basis, then one chunk per view (its mask and its
 * weights, cropped to the mask and quantised to 8 bits per view and component); with a BRDF
 * model beside the SH model, its chunks too (export_web_brdf.c).
 *
 * DESIGN: the page computes what ap_render computes (render.h), so it gets the same data:
 * the views' cameras with their distortion, the triangulation's faces and boundary edges
 * (views.h), the model's basis; it builds the views' depth maps and the light table itself. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "appearance/envmap.h"
#include "appearance/export.h"
#include "appearance/mesh.h"
#include "appearance/model.h"
#include "appearance/views.h"
#include "appearance/web_internal.h"
#include "appearance/webexport.h"
#include "common/cleanup.h"
#include "common/fileio.h"

#define SKY_WIDTH  128 /* the built-in sky's lat-long map */
#define SKY_HEIGHT 64

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_views *, ap_views_free);

int web_fail(struct web *w, int r, const char *what)
{
        snprintf(w->err, w->errlen, "%s: %s", what, strerror(-r));
        return r;
}

/* gzip of len bytes of data into *out (free it). */
static int gzip(const void *data, size_t len, unsigned char **out, size_t *out_len)
{
        z_stream z = {0};
        size_t cap = compressBound(len) + 64;
        int r;

        *out = malloc(cap);
        if (!*out || deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
                return -ENOMEM;
        z.next_in = (unsigned char *)data, z.avail_in = (uInt)len;
        z.next_out = *out, z.avail_out = (uInt)cap;
        r = deflate(&z, Z_FINISH);
        *out_len = z.total_out;
        deflateEnd(&z);
        return r == Z_STREAM_END ? 0 : -ENOMEM;
}

int web_write_chunk(struct web *w, const char *name, const void *data, size_t len, json_t *entry)
{
        static const char b64[] =
                "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        _cleanup_free_ unsigned char *z = NULL;
        _cleanup_free_ char *text = NULL;
        char path[4300];
        size_t zlen, n = 0;
        int r;

        if ((r = gzip(data, len, &z, &zlen)) < 0)
                return web_fail(w, r, name);
        text = malloc(zlen / 3 * 4 + 128 + strlen(name));
        if (!text)
                return web_fail(w, -ENOMEM, name);
        n = (size_t)sprintf(text, "gonio.chunk(\"%s\", \"", name);
        for (size_t i = 0; i < zlen; i += 3) {
                uint32_t v = (uint32_t)z[i] << 16 | (i + 1 < zlen ? z[i + 1] << 8 : 0) |
                             (i + 2 < zlen ? z[i + 2] : 0);
                text[n++] = b64[v >> 18];
                text[n++] = b64[(v >> 12) & 63];
                text[n++] = i + 1 < zlen ? b64[(v >> 6) & 63] : '=';
                text[n++] = i + 2 < zlen ? b64[v & 63] : '=';
        }
        n += (size_t)sprintf(text + n, "\");\n");
        snprintf(path, sizeof(path), "%s/data/%s.js", w->dir, name);
        json_object_set_new(entry, "chunk", json_string(name));
        json_object_set_new(entry, "bytes", json_integer((json_int_t)n));
        json_object_set_new(entry, "raw_bytes", json_integer((json_int_t)len));
        return (r = gn_write_atomic(AT_FDCWD, path, text, n, NULL)) < 0 ? web_fail(w, r, path) : 0;
}

/* The mesh: float32 positions (mm, object frame), then uint32 triangle indices. */
static int write_mesh(struct web *w, json_t *man)
{
        const struct ap_mesh *me = &w->mesh;
        size_t pb = me->nv * 3 * sizeof(float), ib = me->nt * 3 * sizeof(uint32_t);
        _cleanup_free_ unsigned char *buf = malloc(pb + ib);
        json_t *e = json_object();
        double lo[3], hi[3];

        json_object_set_new(man, "mesh", e);
        if (!buf)
                return web_fail(w, -ENOMEM, "mesh");
        memcpy(buf, me->pos, pb);
        for (size_t i = 0; i < me->nt * 3; i++) {
                uint32_t v = (uint32_t)me->idx[i];
                memcpy(buf + pb + 4 * i, &v, 4);
        }
        ap_mesh_bounds(me, lo, hi);
        json_object_set_new(e, "vertices", json_integer((json_int_t)me->nv));
        json_object_set_new(e, "triangles", json_integer((json_int_t)me->nt));
        json_object_set_new(e, "front", json_integer(me->front)); /* the winding's side out */
        json_object_set_new(
                man, "centre",
                json_pack("[fff]", (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2));
        return web_write_chunk(w, "mesh", buf, pb + ib, e);
}

/* The basis: (K + 1) x 3M float32, row 0 the mean (model.h). */
static int write_basis(struct web *w, json_t *man)
{
        const struct ap_model *m = w->m;
        size_t row = 3 * (size_t)m->n_coef;
        _cleanup_free_ float *b = malloc((size_t)(m->k + 1) * row * sizeof(float));
        json_t *e = json_object();

        json_object_set_new(man, "basis", e);
        if (!b)
                return web_fail(w, -ENOMEM, "basis");
        memcpy(b, m->mean, row * sizeof(float));
        memcpy(b + row, m->basis, (size_t)m->k * row * sizeof(float));
        return web_write_chunk(w, "basis", b, (size_t)(m->k + 1) * row * sizeof(float), e);
}

/* The mask's bounding box grown by one pixel (the bilinear taps' reach): x0 y0 w h. */
static void mask_crop(const struct ap_view *v, int crop[4])
{
        int w = v->cam.width, h = v->cam.height, lo[2] = {w, h}, hi[2] = {-1, -1};

        for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                        if (v->mask[(size_t)y * w + x]) {
                                lo[0] = x < lo[0] ? x : lo[0], hi[0] = x > hi[0] ? x : hi[0];
                                lo[1] = y < lo[1] ? y : lo[1], hi[1] = y > hi[1] ? y : hi[1];
                        }
        if (hi[0] < 0) { /* nothing masked in: one pixel */
                crop[0] = crop[1] = 0, crop[2] = crop[3] = 1;
                return;
        }
        crop[0] = lo[0] > 0 ? lo[0] - 1 : 0, crop[1] = lo[1] > 0 ? lo[1] - 1 : 0;
        crop[2] = (hi[0] + 2 < w ? hi[0] + 2 : w) - crop[0];
        crop[3] = (hi[1] + 2 < h ? hi[1] + 2 : h) - crop[1];
}

/* Component k's quantisation to 8 bits over the masked pixels: W = offset + scale * q. */
static void quantisation(const struct ap_view *v, int K, int k, float *scale, float *offset)
{
        float lo, hi;

        ap_view_range(v, K, k, &lo, &hi);
        *offset = lo;
        *scale = hi > lo ? (hi - lo) / 255 : 0;
}

/* View i's chunk: the cropped mask (0/1) then ceil(K/4) RGBA planes of quantised weights. */
static void view_bytes(const struct ap_view *v, int K, const int crop[4], const float *scale,
                       const float *offset, unsigned char *out)
{
        size_t n = (size_t)crop[2] * crop[3], g4 = 4 * (size_t)((K + 3) / 4);

        memset(out, 0, n + n * g4);
        for (int y = 0; y < crop[3]; y++)
                for (int x = 0; x < crop[2]; x++) {
                        size_t src = (size_t)(y + crop[1]) * v->cam.width + x + crop[0];
                        size_t dst = (size_t)y * crop[2] + x;
                        if (!v->mask[src])
                                continue;
                        out[dst] = 1;
                        for (int k = 0; k < K; k++) {
                                float q = scale[k] > 0
                                                  ? (v->weights[src * K + k] - offset[k]) / scale[k]
                                                  : 0;
                                out[n + (size_t)(k / 4) * n * 4 + dst * 4 + k % 4] =
                                        (unsigned char)lrintf(fminf(255, fmaxf(0, q)));
                        }
                }
}

static json_t *camera_json(const struct ap_camera *c)
{
        json_t *j = json_pack("{sisisfsfsfsf}", "width", c->width, "height", c->height, "fx", c->fx,
                              "fy", c->fy, "cx", c->cx, "cy", c->cy);
        json_t *d = json_array(), *R = json_array(), *t = json_array();

        for (int i = 0; i < 5; i++)
                json_array_append_new(d, json_real(c->dist[i]));
        for (int i = 0; i < 9; i++)
                json_array_append_new(R, json_real(c->R[i]));
        for (int i = 0; i < 3; i++)
                json_array_append_new(t, json_real(c->t[i]));
        json_object_set_new(j, "dist", d);
        json_object_set_new(j, "R", R);
        json_object_set_new(j, "t", t);
        return j;
}

static int write_view(struct web *w, size_t i, json_t *views)
{
        const struct ap_view *v = &w->m->views[i];
        int K = w->m->k, crop[4];
        float scale[AP_K_MAX], offset[AP_K_MAX];
        json_t *e = camera_json(&v->cam), *js = json_array(), *jo = json_array();
        _cleanup_free_ unsigned char *buf = NULL;
        char name[32];
        size_t n;

        json_array_append_new(views, e);
        mask_crop(v, crop);
        n = (size_t)crop[2] * crop[3];
        buf = malloc(n + n * 4 * (size_t)((K + 3) / 4));
        if (!buf)
                return web_fail(w, -ENOMEM, "view");
        for (int k = 0; k < K; k++) {
                quantisation(v, K, k, &scale[k], &offset[k]);
                json_array_append_new(js, json_real(scale[k]));
                json_array_append_new(jo, json_real(offset[k]));
        }
        view_bytes(v, K, crop, scale, offset, buf);
        json_object_set_new(e, "scale", js);
        json_object_set_new(e, "offset", jo);
        json_object_set_new(e, "crop", json_pack("[iiii]", crop[0], crop[1], crop[2], crop[3]));
        json_object_set_new(e, "dir", json_pack("[fff]", v->dir[0], v->dir[1], v->dir[2]));
        json_object_set_new(e, "camera", json_string(v->camera));
        snprintf(name, sizeof(name), "view_%03zu", i);
        return web_write_chunk(w, name, buf, n + n * 4 * (size_t)((K + 3) / 4), e);
}

/* The views' triangulation (views.h) as the page's shader reads it. */
static json_t *triangulation_json(const struct ap_views *v, size_t n_views)
{
        json_t *faces = json_array(), *bnd = json_array(), *dup = json_array();
        json_t *start = json_array();

        for (size_t i = 0; i < ap_views_n_faces(v); i++) {
                int idx[3], nb[3];
                float e[3][3];
                json_t *f = json_array();
                ap_views_face(v, i, idx, e, nb);
                for (int j = 0; j < 3; j++)
                        json_array_append_new(f, json_integer(idx[j]));
                for (int j = 0; j < 9; j++)
                        json_array_append_new(f, json_real(e[j / 3][j % 3]));
                for (int j = 0; j < 3; j++)
                        json_array_append_new(f, json_integer(nb[j]));
                json_array_append_new(faces, f);
        }
        for (size_t i = 0; i < 6 * AP_VIEWS_CUBE * AP_VIEWS_CUBE; i++)
                json_array_append_new(start, json_integer(ap_views_start(v, i)));
        for (size_t i = 0; i < ap_views_n_boundary(v); i++) {
                int ab[2];
                double n[3];
                ap_views_boundary(v, i, ab, n);
                json_array_append_new(bnd, json_pack("[iifff]", ab[0], ab[1], n[0], n[1], n[2]));
        }
        for (size_t i = 0; i < n_views; i++)
                json_array_append_new(dup, json_boolean(ap_views_is_dup(v, i)));
        return json_pack("{s:o,s:o,s:o,s:o,s:i}", "faces", faces, "boundary", bnd, "dup", dup,
                         "start", start, "cube", AP_VIEWS_CUBE);
}

/* A sky for the environment mode when none is given: a bright sun high on one side, a blue
 * sky and a dark ground (in the model's light units per steradian). */
static int sky(struct ap_envmap *e)
{
        static const double sun[3] = {0.45, -0.35, 0.82};

        e->width = SKY_WIDTH, e->height = SKY_HEIGHT;
        e->rgb = malloc(3 * (size_t)SKY_WIDTH * SKY_HEIGHT * sizeof(float));
        if (!e->rgb)
                return -ENOMEM;
        for (int y = 0; y < SKY_HEIGHT; y++)
                for (int x = 0; x < SKY_WIDTH; x++) {
                        float *p = &e->rgb[3 * ((size_t)y * SKY_WIDTH + x)];
                        double d[3], c;
                        ap_envmap_dir(SKY_WIDTH, SKY_HEIGHT, x + 0.5, y + 0.5, d);
                        c = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2];
                        p[0] = p[1] = p[2] = (float)(3 * exp(30 * (c - 1)));
                        p[0] += d[2] > 0 ? 0.05f : 0.02f;
                        p[1] += d[2] > 0 ? 0.07f : 0.02f;
                        p[2] += d[2] > 0 ? 0.12f : 0.015f;
                }
        return 0;
}

static json_t *env_json(const char *name, const struct ap_envmap *e, int order)
{
        int n = 3 * order * order;
        double coef[3 * AP_ORDER_MAX * AP_ORDER_MAX];
        json_t *c = json_array();

        ap_envmap_project(e, order, coef);
        for (int i = 0; i < n; i++)
                json_array_append_new(c, json_real(coef[i]));
        return json_pack("{s:s,s:o}", "name", name, "coef", c);
}

/* Environment map i: its SH projection, and the BRDF model's data for it. */
static int write_env(struct web *w, json_t *envs, const char *name, const struct ap_envmap *e)
{
        json_array_append_new(envs, env_json(name, e, w->m->order));
        return web_brdf_env(w, json_array_size(envs) - 1, name, e);
}

/* The environment maps: the given files, else the built-in sky. */
static int write_envs(struct web *w, json_t *man)
{
        const char *const *files = w->o->envmaps;
        json_t *envs = json_array();
        struct ap_envmap e = {0};
        int r = 0;

        json_object_set_new(man, "envs", envs);
        for (size_t i = 0; files && files[i] && r >= 0; i++) {
                const char *slash = strrchr(files[i], '/');
                if ((r = ap_envmap_load(files[i], &e, w->err, w->errlen)) < 0)
                        return r;
                r = write_env(w, envs, slash ? slash + 1 : files[i], &e);
                ap_envmap_free(&e);
        }
        if (r < 0 || json_array_size(envs))
                return r;
        if ((r = sky(&e)) < 0)
                return web_fail(w, r, "sky");
        r = write_env(w, envs, "sky", &e);
        ap_envmap_free(&e);
        return r;
}

static int write_manifest(struct web *w, json_t *man)
{
        _cleanup_free_ char *json = json_dumps(man, JSON_COMPACT | JSON_REAL_PRECISION(9));
        _cleanup_free_ char *text = NULL;
        char path[4200];
        int r, n;

        if (!json || (n = asprintf(&text, "gonio.manifest(%s);\n", json)) < 0)
                return web_fail(w, -ENOMEM, "manifest");
        snprintf(path, sizeof(path), "%s/data/model.js", w->dir);
        return (r = gn_write_atomic(AT_FDCWD, path, text, (size_t)n, NULL)) < 0
                       ? web_fail(w, r, path)
                       : 0;
}

static int write_assets(struct web *w)
{
        char path[4200];
        int r;

        for (const struct ap_web_asset *a = ap_web_assets; a->name; a++) {
                snprintf(path, sizeof(path), "%s/%s", w->dir, a->name);
                if ((r = gn_write_atomic(AT_FDCWD, path, a->data, a->len, NULL)) < 0)
                        return web_fail(w, r, path);
        }
        return 0;
}

static json_t *manifest_new(const struct ap_model *m)
{
        return json_pack("{s:s,s:s,s:i,s:i,s:i,s:s,s:{s:f,s:f}}", "format", AP_WEB_FORMAT, "name",
                         m->name, "order", m->order, "n_coef", m->n_coef, "components", m->k,
                         "notes", m->notes, "light", "distance_mm", m->light_distance_mm,
                         "intensity", m->light_intensity);
}

/* Fills the temporary folder dir (ap_fill_fn). */
static int fill(void *ctx, const char *dir, char *err, size_t errlen)
{
        struct web *w = ctx;
        _cleanup_(json_decrefp) json_t *man = manifest_new(w->m);
        json_t *views = json_array();
        char data[4200];
        int r;

        (void)err, (void)errlen; /* w holds them */
        w->dir = dir;
        snprintf(data, sizeof(data), "%s/data", dir);
        json_object_set_new(man, "views", views);
        if (mkdir(data, 0755) < 0)
                return web_fail(w, -errno, data);
        if ((r = write_assets(w)) < 0 || (r = write_mesh(w, man)) < 0 ||
            (r = write_basis(w, man)) < 0 || (r = web_brdf_write(w, man)) < 0 ||
            (r = write_envs(w, man)) < 0)
                return r;
        for (size_t i = 0; i < w->m->n_views; i++)
                if ((r = write_view(w, i, views)) < 0)
                        return r;
        json_object_set_new(man, "triangulation", triangulation_json(w->views, w->m->n_views));
        return write_manifest(w, man);
}

/* The model, its mesh and its views' triangulation into w. */
static int load(struct web *w, const char *model_dir)
{
        char ds[4096], src[4200];
        double(*dirs)[3];
        int r;

        if ((r = ap_model_read(model_dir, &w->m, w->err, w->errlen)) < 0) {
                if (!w->err[0])
                        snprintf(w->err, w->errlen, "%s: %s", model_dir,
                                 r == -ENOENT ? "no model there" : strerror(-r));
                return r;
        }
        if ((r = web_brdf_load(w, model_dir)) < 0)
                return r;
        ap_model_dataset(model_dir, ds, sizeof(ds));
        if ((r = ap_mesh_for_dataset(ds, w->o->backends, &w->mesh, src, sizeof(src), w->err,
                                     w->errlen)) < 0)
                return r;
        if (!(dirs = malloc(w->m->n_views * sizeof(*dirs))))
                return web_fail(w, -ENOMEM, model_dir);
        for (size_t i = 0; i < w->m->n_views; i++)
                memcpy(dirs[i], w->m->views[i].dir, sizeof(dirs[i]));
        r = ap_views_new((const double(*)[3])dirs, w->m->n_views, &w->views);
        free(dirs);
        return r < 0 ? web_fail(w, r, "the views' triangulation") : 0;
}

int ap_web_export(const char *model_dir, const char *out_dir, const struct ap_web_opts *o,
                  char *err, size_t errlen)
{
        struct ap_web_opts none = {0};
        struct web w = {.o = o ? o : &none, .err = err, .errlen = errlen};
        int r;

        if (!model_dir || !out_dir || !*out_dir)
                return -EINVAL;
        err[0] = 0;
        if ((r = load(&w, model_dir)) >= 0)
                r = ap_write_folder(out_dir, fill, &w, err, errlen);
        ap_views_free(w.views);
        web_brdf_free(&w);
        ap_mesh_free(&w.mesh);
        ap_model_free(w.m);
        return r;
}
