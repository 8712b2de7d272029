/* export_gltf.c - the BRDF model (brdf.h) as glTF 2.0 (export.h, docs/exports.md "glTF"):
 * model.gltf (JSON), model.bin (the vertices) and four PNG textures on the model's atlas:
 * base colour (sRGB), metallic-roughness, tangent-space normal, KHR_materials_anisotropy.
 *
 * DESIGN. Every corner of the per-triangle atlas is its own vertex (no two triangles share
 * UVs), drawn without indices. A corner's NORMAL is its vertex's area-weighted normal and
 * its TANGENT the triangle's dP/du made orthogonal to it, w the handedness that makes
 * N x T w point along -dP/dv (glTF's v runs down the image, its bitangent up). A texel's
 * frame is the one a renderer interpolates at its centre: N the normalised blend of the
 * corners' normals, T the blend of their tangents made orthogonal to N (Gram-Schmidt),
 * B = N x T w. The shading normal and the anisotropy direction are written in that frame. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/brdf.h"
#include "appearance/export_internal.h"
#include "appearance/model_png.h"
#include "common/fileio.h"
#include "sim/render/vec.h"

#define GLTF_DIELECTRIC_F0 0.04f /* glTF's specular F0 of a non-metal (its ior 1.5) */
#define GLTF_FLOAT         5126
#define GLTF_ARRAY_BUFFER  34962
#define GLTF_LINEAR        9729
#define GLTF_CLAMP         33071

/* The textures, in the order of the JSON's images. */
enum { TEX_BASE, TEX_MR, TEX_NORMAL, TEX_ANISO, TEX_N };
static const char *const tex_file[TEX_N] = {"basecolor.png", "metallic_roughness.png", "normal.png",
                                            "anisotropy.png"};

/* The vertex attributes, in the order of model.bin. */
static const struct {
        const char *name, *type;
        int n;
} attr[] = {{"POSITION", "VEC3", 3},
            {"NORMAL", "VEC3", 3},
            {"TANGENT", "VEC4", 4},
            {"TEXCOORD_0", "VEC2", 2}};
#define N_ATTR (sizeof(attr) / sizeof(attr[0]))

static struct v3 v3_at(const float *p)
{
        return v3(p[0], p[1], p[2]);
}

/* a made orthogonal to unit n and normalised; any unit vector orthogonal to n when a is
 * (nearly) parallel to n. */
static struct v3 orthonormal(struct v3 a, struct v3 n)
{
        struct v3 t = v3_madd(a, n, -v3_dot(a, n));

        if (v3_len(t) > 1e-6f * (v3_len(a) + 1e-30f))
                return v3_norm(t);
        t = fabsf(n.x) < 0.9f ? v3(1, 0, 0) : v3(0, 1, 0);
        return v3_norm(v3_madd(t, n, -v3_dot(t, n)));
}

/* The geometric normal of triangle t, unit, or +z for a degenerate one. */
static struct v3 face_normal(const struct ap_mesh *m, size_t t)
{
        struct v3 p0 = v3_at(&m->pos[3 * m->idx[3 * t]]),
                  p1 = v3_at(&m->pos[3 * m->idx[3 * t + 1]]),
                  p2 = v3_at(&m->pos[3 * m->idx[3 * t + 2]]);
        struct v3 n = v3_cross(v3_sub(p1, p0), v3_sub(p2, p0));

        return v3_len(n) > 0 ? v3_norm(n) : v3(0, 0, 1);
}

/* The normals of triangle t's corners: their vertices' area-weighted normals; for a vertex
 * of collapsed triangles only (no normal), the mean of the other corners' or else the
 * triangle's own. */
static void corner_normals(const struct ap_atlas *a, size_t t, struct v3 n[3])
{
        struct v3 sum = v3(0, 0, 0);
        bool ok[3];

        for (int c = 0; c < 3; c++) {
                n[c] = v3_at(&a->vnormal[3 * a->mesh.idx[3 * t + c]]);
                ok[c] = fabsf(v3_len(n[c]) - 1) < 1e-3f;
                sum = ok[c] ? v3_add(sum, n[c]) : sum;
        }
        sum = v3_len(sum) > 1e-3f ? v3_norm(sum) : face_normal(&a->mesh, t);
        for (int c = 0; c < 3; c++)
                n[c] = ok[c] ? n[c] : sum;
}

/* The vertices of triangle t (3 corners x 12 floats: position, normal, tangent xyzw, uv). */
static void corner_vertices(const struct ap_atlas *a, size_t t, float out[3][12])
{
        const struct ap_mesh *m = &a->mesh;
        const float *uv = &a->uv[6 * t];
        struct v3 p[3], nc[3], e1, e2, dpdu, dpdv;
        float du1 = uv[2] - uv[0], dv1 = uv[3] - uv[1], du2 = uv[4] - uv[0], dv2 = uv[5] - uv[1];
        float det = du1 * dv2 - du2 * dv1;

        corner_normals(a, t, nc);
        for (int c = 0; c < 3; c++)
                p[c] = v3_at(&m->pos[3 * m->idx[3 * t + c]]);
        e1 = v3_sub(p[1], p[0]);
        e2 = v3_sub(p[2], p[0]);
        dpdu = v3_scale(v3_sub(v3_scale(e1, dv2), v3_scale(e2, dv1)), det != 0 ? 1 / det : 0);
        dpdv = v3_scale(v3_sub(v3_scale(e2, du1), v3_scale(e1, du2)), det != 0 ? 1 / det : 0);
        for (int c = 0; c < 3; c++) {
                struct v3 n = nc[c], tg = orthonormal(dpdu, n);
                float *o = out[c];
                memcpy(o, &p[c], sizeof(float[3]));
                memcpy(o + 3, &n, sizeof(float[3]));
                memcpy(o + 6, &tg, sizeof(float[3]));
                o[9] = v3_dot(v3_cross(n, tg), dpdv) > 0 ? -1.0f : 1.0f;
                o[10] = uv[2 * c];
                o[11] = uv[2 * c + 1];
        }
}

/* ---- the textures ---- */

/* A texel's tangent frame (DESIGN). */
struct frame {
        struct v3 t, b, n;
};

/* The frame at texel i's centre from its triangle's corners in vert (DESIGN). */
static struct frame texel_frame(const struct ap_atlas *a, const float *vert, size_t i)
{
        const float *bary = &a->bary[3 * i];
        const float *c = &vert[36 * (size_t)a->tri[i]];
        struct v3 n = v3(0, 0, 0), t = v3(0, 0, 0);
        struct frame f;
        float w = 0;

        for (int k = 0; k < 3; k++) {
                n = v3_madd(n, v3_at(&c[12 * k + 3]), bary[k]);
                t = v3_madd(t, v3_at(&c[12 * k + 6]), bary[k]);
                w += bary[k] * c[12 * k + 9];
        }
        f.n = v3_len(n) > 1e-6f ? v3_norm(n) : v3_at(&c[3]);
        f.t = orthonormal(t, f.n);
        f.b = v3_scale(v3_cross(f.n, f.t), w < 0 ? -1.0f : 1.0f);
        return f;
}

/* [0, 1] into a byte. */
static uint8_t unorm8(float x)
{
        return (uint8_t)lrintf(255.0f * fminf(fmaxf(x, 0.0f), 1.0f));
}

/* [-1, 1] into a byte, as normal and anisotropy textures hold vectors. */
static uint8_t snorm8(float x)
{
        return unorm8(0.5f * x + 0.5f);
}

/* A linear value in [0, 1] encoded with the sRGB transfer function (IEC 61966-2-1). */
static float srgb_encode(float c)
{
        c = fminf(fmaxf(c, 0.0f), 1.0f);
        return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1 / 2.4f) - 0.055f;
}

/* glTF's mean specular F0 at metalness m for the diffuse colour d (the base colour
 * d / (1 - m), each channel at most 1). */
static float metal_f0(const float d[3], float m, float c[3])
{
        float s = 0;

        for (int k = 0; k < 3; k++)
                s += c[k] = m < 1 ? fminf(d[k] / (1 - m), 1.0f) : 0.0f;
        return GLTF_DIELECTRIC_F0 * (1 - m) + m * s / 3;
}

/* Base colour c and metalness *m for texel x (docs/exports.md): glTF's diffuse colour
 * (1 - m) c is the model's (1 - ks) albedo, its mean F0 the model's ks f0 (bisection on m);
 * a texel whose ks f0 is below a dielectric's 0.04 is a dielectric (m = 0). */
static void metal_fit(const struct ap_brdf_texel *x, float c[3], float *m)
{
        float d[3], s = x->ks * x->f0, lo = 0, hi = 1;

        for (int k = 0; k < 3; k++)
                d[k] = (1 - x->ks) * x->albedo[k];
        *m = 0;
        if (s > GLTF_DIELECTRIC_F0 && d[0] + d[1] + d[2] <= 0) {
                *m = 1;
                c[0] = c[1] = c[2] = fminf(s, 1.0f);
                return;
        }
        for (int it = 0; it < 40 && s > GLTF_DIELECTRIC_F0; it++) {
                *m = 0.5f * (lo + hi);
                if (metal_f0(d, *m, c) < s)
                        lo = *m;
                else
                        hi = *m;
        }
        metal_f0(d, *m, c);
}

/* Texel x's roughness r and anisotropy strength s with its direction dir (the one of larger
 * alpha): KHR_materials_anisotropy's alpha_b = r^2, alpha_t = mix(r^2, 1, s^2). A texel
 * without a lobe (ks 0: diffuse only) is fully rough, so that glTF's 0.04 floor of specular
 * makes no glint. */
static void aniso_fit(const struct ap_brdf_texel *x, float *r, float *s, struct v3 *dir)
{
        bool lobe = x->ks > 0;
        float amin = lobe ? fminf(fminf(x->ax, x->ay), 1.0f) : 1.0f;
        float amax = lobe ? fminf(fmaxf(x->ax, x->ay), 1.0f) : 1.0f;
        struct v3 n = v3_at(x->normal), t = v3_at(x->tangent);

        amin = fmaxf(amin, 0.0f);
        *r = sqrtf(amin);
        *s = amin < 1 ? sqrtf(fmaxf(amax - amin, 0.0f) / (1 - amin)) : 0.0f;
        *dir = x->ax >= x->ay ? t : v3_cross(n, t);
}

/* The 4 texture pixels (RGB) of texel x in frame f. */
static void encode_texel(const struct ap_brdf_texel *x, const struct frame *f, uint8_t px[TEX_N][3])
{
        struct v3 n = v3_norm(v3_at(x->normal)), dir, d;
        float c[3], m, r, s, nn = v3_dot(n, f->n), dx, dy, l;

        metal_fit(x, c, &m);
        aniso_fit(x, &r, &s, &dir);
        for (int k = 0; k < 3; k++)
                px[TEX_BASE][k] = unorm8(srgb_encode(c[k]));
        px[TEX_MR][0] = 255;
        px[TEX_MR][1] = unorm8(r);
        px[TEX_MR][2] = unorm8(m);
        px[TEX_NORMAL][0] = snorm8(v3_dot(n, f->t));
        px[TEX_NORMAL][1] = snorm8(v3_dot(n, f->b));
        px[TEX_NORMAL][2] = snorm8(nn);
        /* the vector of the (t, b) plane that projects along n onto dir */
        d = v3_madd(dir, n, nn > 1e-3f ? -v3_dot(dir, f->n) / nn : 0.0f);
        dx = v3_dot(d, f->t);
        dy = v3_dot(d, f->b);
        l = hypotf(dx, dy);
        px[TEX_ANISO][0] = snorm8(l > 0 ? dx / l : 1);
        px[TEX_ANISO][1] = snorm8(l > 0 ? dy / l : 0);
        px[TEX_ANISO][2] = unorm8(s);
}

/* The texture pixels of texels without a fitted material: grey 0.5, rough, a dielectric,
 * the interpolated normal, isotropic. */
static void encode_blank(uint8_t px[TEX_N][3])
{
        static const uint8_t blank[TEX_N][3] = {
                {188, 188, 188}, {255, 255, 0}, {128, 128, 255}, {255, 128, 0}};

        memcpy(px, blank, sizeof(blank));
}

/* Whether every parameter of texel x is a number (a fit can leave NaN where it failed). */
static bool texel_finite(const struct ap_brdf_texel *x)
{
        const float v[] = {x->albedo[0],  x->albedo[1],  x->albedo[2], x->ks,        x->ax,
                           x->ay,         x->f0,         x->normal[0], x->normal[1], x->normal[2],
                           x->tangent[0], x->tangent[1], x->tangent[2]};

        for (size_t k = 0; k < sizeof(v) / sizeof(v[0]); k++)
                if (!isfinite(v[k]))
                        return false;
        return true;
}

/* Fills the texture images img[TEX_N] (3 bytes a texel each) of model m: blank where a
 * texel is of no triangle, masked or not a number. */
static void fill_textures(const struct ap_brdf_model *m, const float *vert, uint8_t *img[TEX_N])
{
        const struct ap_atlas *a = &m->atlas;

        for (size_t i = 0; i < (size_t)a->width * a->height; i++) {
                const struct ap_brdf_texel *x = &m->texels[i];
                uint8_t px[TEX_N][3];
                if (a->tri[i] < 0 || (x->flags & AP_BRDF_MASKED) || !texel_finite(x)) {
                        encode_blank(px);
                } else {
                        struct frame f = texel_frame(a, vert, i);
                        encode_texel(x, &f, px);
                }
                for (int k = 0; k < TEX_N; k++)
                        memcpy(&img[k][3 * i], px[k], 3);
        }
}

/* ---- the files ---- */

static int write_file(const char *dir, const char *name, const void *buf, size_t len, char *err,
                      size_t errlen)
{
        char path[4300];
        int r;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        r = gn_write_atomic(AT_FDCWD, path, buf, len, NULL);
        if (r < 0)
                snprintf(err, errlen, "cannot write %s: %s", path, strerror(-r));
        return r;
}

/* model.bin: the attributes one after the other (attr[]), from the interleaved vertices. */
static int write_bin(const char *dir, const float *vert, size_t nv, char *err, size_t errlen)
{
        _cleanup_free_ float *buf = malloc(nv * 12 * sizeof(float) + 1);
        float *o = buf;

        if (!buf)
                return -ENOMEM;
        for (size_t k = 0, off = 0; k < N_ATTR; off += (size_t)attr[k++].n)
                for (size_t v = 0; v < nv; v++, o += attr[k].n)
                        memcpy(o, &vert[12 * v + off], attr[k].n * sizeof(float));
        return write_file(dir, "model.bin", buf, nv * 12 * sizeof(float), err, errlen);
}

static int write_textures(const char *dir, const struct ap_atlas *a, uint8_t *img[TEX_N], char *err,
                          size_t errlen)
{
        int r = 0;

        for (int k = 0; r == 0 && k < TEX_N; k++) {
                _cleanup_free_ void *png = NULL;
                size_t len;
                r = ap_png_encode(a->width, a->height, 3, NULL, img[k], &png, &len);
                if (r < 0)
                        snprintf(err, errlen, "cannot encode %s: %s", tex_file[k], strerror(-r));
                else
                        r = write_file(dir, tex_file[k], png, len, err, errlen);
        }
        return r;
}

/* The bufferViews and accessors of model.bin (attr[] one after the other), into root. */
static int json_attributes(json_t *root, json_t *attributes, const float *vert, size_t nv)
{
        json_t *views = json_array(), *acc = json_array();
        size_t off = 0;

        json_object_set_new(root, "bufferViews", views);
        json_object_set_new(root, "accessors", acc);
        for (size_t k = 0, f = 0; k < N_ATTR; f += (size_t)attr[k++].n) {
                size_t len = nv * attr[k].n * sizeof(float);
                json_t *a = json_pack("{s:i, s:i, s:I, s:s}", "bufferView", (int)k, "componentType",
                                      GLTF_FLOAT, "count", (json_int_t)nv, "type", attr[k].type);
                json_array_append_new(views,
                                      json_pack("{s:i, s:I, s:I, s:i}", "buffer", 0, "byteOffset",
                                                (json_int_t)off, "byteLength", (json_int_t)len,
                                                "target", GLTF_ARRAY_BUFFER));
                if (k == 0) { /* POSITION: min and max are required */
                        json_t *lo = json_array(), *hi = json_array();
                        for (int j = 0; j < 3; j++) {
                                float mn = INFINITY, mx = -INFINITY;
                                for (size_t v = 0; v < nv; v++)
                                        mn = fminf(mn, vert[12 * v + j]),
                                        mx = fmaxf(mx, vert[12 * v + j]);
                                json_array_append_new(lo, json_real(mn));
                                json_array_append_new(hi, json_real(mx));
                        }
                        json_object_set_new(a, "min", lo);
                        json_object_set_new(a, "max", hi);
                }
                json_array_append_new(acc, a);
                json_object_set_new(attributes, attr[k].name, json_integer((json_int_t)k));
                off += len;
        }
        return json_object_set_new(
                root, "buffers",
                json_pack("[{s:s, s:I}]", "uri", "model.bin", "byteLength", (json_int_t)off));
}

/* The material, textures, sampler and images, into root. */
static int json_material(json_t *root, const char *name)
{
        json_t *tex = json_array(), *img = json_array();

        for (int k = 0; k < TEX_N; k++) {
                json_array_append_new(tex, json_pack("{s:i, s:i}", "sampler", 0, "source", k));
                json_array_append_new(img, json_pack("{s:s}", "uri", tex_file[k]));
        }
        json_object_set_new(root, "textures", tex);
        json_object_set_new(root, "images", img);
        /* no mipmaps: their coarser levels would mix the atlas' triangles */
        json_object_set_new(root, "samplers",
                            json_pack("[{s:i, s:i, s:i, s:i}]", "magFilter", GLTF_LINEAR,
                                      "minFilter", GLTF_LINEAR, "wrapS", GLTF_CLAMP, "wrapT",
                                      GLTF_CLAMP));
        return json_object_set_new(
                root, "materials",
                json_pack("[{s:s, s:{s:{s:i}, s:{s:i}}, s:{s:i}, s:{s:{s:f, s:{s:i}}}}]", "name",
                          name, "pbrMetallicRoughness", "baseColorTexture", "index", TEX_BASE,
                          "metallicRoughnessTexture", "index", TEX_MR, "normalTexture", "index",
                          TEX_NORMAL, "extensions", "KHR_materials_anisotropy",
                          "anisotropyStrength", 1.0, "anisotropyTexture", "index", TEX_ANISO));
}

/* The glTF document of model m (vertices vert, nv of them). The node turns gonio's object
 * frame (z up, mm) into glTF's (y up, m): (x, y, z) mm -> (x, z, -y) / 1000 m. */
static json_t *gltf_json(const struct ap_brdf_model *m, const float *vert, size_t nv)
{
        _cleanup_(json_decrefp) json_t *root = json_pack(
                "{s:{s:s, s:s}, s:[s], s:i, s:[{s:[i]}], s:[{s:i, s:s, s:[f, f, f, f], "
                "s:[f, f, f]}]}",
                "asset", "version", "2.0", "generator", "gonio (appearance/export_gltf.c)",
                "extensionsUsed", "KHR_materials_anisotropy", "scene", 0, "scenes", "nodes", 0,
                "nodes", "mesh", 0, "name", m->name, "rotation", -M_SQRT1_2, 0.0, 0.0, M_SQRT1_2,
                "scale", 1e-3, 1e-3, 1e-3);
        json_t *attributes = json_object();

        if (!root || !attributes)
                return NULL;
        json_object_set_new(root, "meshes",
                            json_pack("[{s:s, s:[{s:o, s:i}]}]", "name", m->name, "primitives",
                                      "attributes", attributes, "material", 0));
        if (json_attributes(root, attributes, vert, nv) < 0 || json_material(root, m->name) < 0)
                return NULL;
        return TAKE_PTR(root);
}

static int write_json(const char *dir, json_t *root, char *err, size_t errlen)
{
        _cleanup_free_ char *s = json_dumps(root, JSON_INDENT(1) | JSON_REAL_PRECISION(9));

        if (!s)
                return -ENOMEM;
        return write_file(dir, "model.gltf", s, strlen(s), err, errlen);
}

static void free_images(uint8_t *img[TEX_N])
{
        for (int k = 0; k < TEX_N; k++)
                free(img[k]);
}

/* Writes model m as glTF into the empty folder dir (an ap_fill_fn). */
static int gltf_fill(void *ctx, const char *dir, char *err, size_t errlen)
{
        const struct ap_brdf_model *m = ctx;
        const struct ap_atlas *a = &m->atlas;
        size_t nv = 3 * a->mesh.nt, n = (size_t)a->width * a->height;
        _cleanup_free_ float *vert = malloc(nv * 12 * sizeof(float) + 1);
        _cleanup_(json_decrefp) json_t *root = NULL;
        uint8_t *img[TEX_N] = {0};
        int r = vert ? 0 : -ENOMEM;

        for (int k = 0; r == 0 && k < TEX_N; k++)
                if (!(img[k] = malloc(3 * n)))
                        r = -ENOMEM;
        for (size_t t = 0; r == 0 && t < a->mesh.nt; t++)
                corner_vertices(a, t, (float(*)[12]) & vert[36 * t]);
        if (r == 0) {
                fill_textures(m, vert, img);
                r = write_textures(dir, a, img, err, errlen);
        }
        if (r == 0)
                r = write_bin(dir, vert, nv, err, errlen);
        if (r == 0 && !(root = gltf_json(m, vert, nv)))
                r = -ENOMEM;
        if (r == 0)
                r = write_json(dir, root, err, errlen);
        if (r == -ENOMEM)
                snprintf(err, errlen, "out of memory writing the glTF of model %s", m->name);
        free_images(img);
        return r;
}

int ap_export_gltf_model(const struct ap_brdf_model *m, const char *dir, char *err, size_t errlen)
{
        if (!m || !dir || !*dir || m->atlas.mesh.nt == 0 || !m->texels || !m->atlas.vnormal) {
                snprintf(err, errlen, "no model, no folder or an empty mesh to export as glTF");
                return -EINVAL;
        }
        return ap_write_folder(dir, gltf_fill, (void *)m, err, errlen);
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_brdf_model *, ap_brdf_model_free);

int ap_export_gltf(struct ds *d, const char *ds_dir, const char *dir,
                   const struct ap_export_opts *o, char *err, size_t errlen)
{
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = NULL;
        const char *name = o->model ? o->model : "default";
        char path[4200];
        int r;

        (void)d;
        snprintf(path, sizeof(path), "%s/models/%s", ds_dir, name);
        r = ap_brdf_read(path, &m, err, errlen);
        if (r == -ENOENT)
                snprintf(err, errlen,
                         "%s has no BRDF model '%s' (models/%s/brdf): fit one with gonioctl "
                         "model fit --brdf",
                         ds_dir, name, name);
        if (r < 0)
                return r;
        if (m->kind == AP_BRDF_KIND_VIEW) {
                snprintf(err, errlen,
                         "%s: BRDF model '%s' is of the view kind (fitted without a mesh): glTF "
                         "needs a mesh; scan the object and fit again",
                         ds_dir, name);
                return -EINVAL;
        }
        return gltf_fill(m, dir, err, errlen);
}
