/* test-gltf.c - the glTF export of the BRDF model (appearance/export_gltf.c) on a sphere
 * model built in memory (known parameters per texel): read back by a reader written from the
 * glTF 2.0 and KHR_materials_anisotropy specifications (jansson, libspng), whose texels decode
 * to the model's parameters within the 8-bit quantisation; the Khronos validator
 * (scripts/gltf-validate) reports no errors; Blender imports it (tests/appearance/gltf-blender.py);
 * gonioctl dataset export --format gltf writes the same files from the model's files; bad
 * arguments are refused and leave nothing behind. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <spng.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "appearance/brdf.h"
#include "appearance/export.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds.h"
#include "tests/test.h"
#include "tests/dataset/ds-util.h"

#define GRID   4                  /* quads a side of each face of the cube-sphere */
#define RADIUS 25.0               /* mm */
#define CELL   8                  /* atlas texels a cell side */
#define Q      (0.5 / 255 + 1e-4) /* half an 8-bit step */
/* a unit vector of 8-bit components ((x + 1) / 2 quantised) is within atan(sqrt(3) / 255)
 * = 0.39 degrees of the one written */
#define ANGLE_TOL (0.5f * (float)M_PI / 180)

/* ---- the model ---- */

/* Corner (i, j) of face f of the cube [-1, 1]^3, projected on the sphere. */
static void cube_point(int f, int i, int j, float *p)
{
        double a = 2.0 * i / GRID - 1, b = 2.0 * j / GRID - 1, q[3], l;
        int ax = f / 2, s = f % 2 ? -1 : 1;

        q[ax] = s;
        q[(ax + 1) % 3] = s * a;
        q[(ax + 2) % 3] = b;
        l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        for (int k = 0; k < 3; k++)
                p[k] = (float)(RADIUS * q[k] / l);
}

/* A cube-sphere: 6 faces of GRID x GRID quads, 2 triangles each, vertices shared in a face;
 * then a collapsed triangle (as at the poles of a UV sphere) whose first two corners are a
 * vertex of no other triangle (no area-weighted normal), at vertex 0. */
static void sphere(struct ap_mesh *m)
{
        size_t per = (GRID + 1) * (GRID + 1), t = 0;

        *m = (struct ap_mesh){.nv = 6 * per + 1, .nt = 6 * GRID * GRID * 2 + 1};
        m->pos = malloc(3 * m->nv * sizeof(float));
        m->idx = malloc(3 * m->nt * sizeof(uint32_t));
        CHECK(m->pos && m->idx);
        for (int f = 0; f < 6; f++)
                for (int i = 0; i <= GRID; i++)
                        for (int j = 0; j <= GRID; j++)
                                cube_point(f, i, j, &m->pos[3 * (f * per + i * (GRID + 1) + j)]);
        for (int f = 0; f < 6; f++)
                for (int i = 0; i < GRID; i++)
                        for (int j = 0; j < GRID; j++, t += 2) {
                                uint32_t a = (uint32_t)(f * per + i * (GRID + 1) + j);
                                uint32_t b = a + GRID + 1, q[6] = {a, b, a + 1, a + 1, b, b + 1};
                                memcpy(&m->idx[3 * t], q, sizeof(q));
                        }
        memcpy(&m->pos[3 * (m->nv - 1)], &m->pos[0], sizeof(float[3]));
        m->idx[3 * t] = m->idx[3 * t + 1] = (uint32_t)(m->nv - 1);
        m->idx[3 * t + 2] = 1;
}

static void normalize3(float *v)
{
        float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);

        for (int k = 0; k < 3; k++)
                v[k] /= l;
}

/* Texel x at point p (normal n): three materials by height (a dielectric, a coloured
 * conductor-like mix, a pure metal), roughness and anisotropy varying over the sphere, the
 * tangent along the parallels, the shading normal tilted from n; every 13th texel diffuse
 * only (ks 0), with nan every 17th not a number (which the model's files cannot hold),
 * every 11th masked, as are those of the collapsed triangle where the atlas has no normal. */
static void texel_at(size_t i, const float p[3], const float n[3], bool nan,
                     struct ap_brdf_texel *x)
{
        float h = p[2] / (float)RADIUS, t[3] = {-n[1], n[0], 0}, tn;
        int kind = h < -0.3f ? 0 : h < 0.3f ? 1 : 2;

        *x = (struct ap_brdf_texel){.flags = AP_BRDF_FITTED, .n_samples = 40};
        for (int k = 0; k < 3; k++)
                x->albedo[k] = kind == 2 ? 0 : (0.7f - 0.2f * (float)k) * (kind ? 0.5f : 1);
        x->ks = kind == 0 ? 0.2f : kind == 1 ? 0.6f : 1;
        x->f0 = kind == 0 ? 0.04f : kind == 1 ? 0.5f : 0.9f;
        x->ax = 0.05f + 0.3f * (p[0] / (float)RADIUS + 1) / 2;
        x->ay = 0.05f + 0.1f * (p[1] / (float)RADIUS + 1) / 2;
        for (int k = 0; k < 3; k++)
                x->normal[k] = n[k] + (k == 0 ? 0.15f : 0);
        normalize3(x->normal);
        if (hypotf(t[0], t[1]) < 1e-3f)
                t[0] = 1;
        tn = t[0] * x->normal[0] + t[1] * x->normal[1] + t[2] * x->normal[2];
        for (int k = 0; k < 3; k++)
                x->tangent[k] = t[k] - tn * x->normal[k];
        normalize3(x->tangent);
        if (i % 13 == 0) { /* the fit's fallback: no lobe */
                x->ks = 0;
                x->flags = AP_BRDF_DIFFUSE_ONLY;
        }
        if (nan && i % 17 == 0) /* a failed fit: written as masked */
                x->ay = NAN;
        if (i % 11 == 0 || fabsf(n[0]) + fabsf(n[1]) + fabsf(n[2]) == 0) /* or no normal */
                *x = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
}

/* The model on the cube-sphere (texel_at; texels of no triangle masked). */
static struct ap_brdf_model *make_model(bool nan)
{
        struct ap_brdf_model *m = calloc(1, sizeof(*m));
        struct ap_mesh mesh;

        CHECK(m);
        snprintf(m->name, sizeof(m->name), "sphere");
        sphere(&mesh);
        CHECK_INT(ap_atlas_build(&mesh, CELL, &m->atlas), 0);
        m->texels = calloc((size_t)m->atlas.width * m->atlas.height, sizeof(*m->texels));
        CHECK(m->texels);
        for (size_t i = 0; i < (size_t)m->atlas.width * m->atlas.height; i++) {
                float p[3], n[3];
                if (ap_atlas_point(&m->atlas, i, p, n))
                        texel_at(i, p, n, nan, &m->texels[i]);
                else
                        m->texels[i].flags = AP_BRDF_MASKED;
        }
        m->response = 1;
        return m;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_brdf_model *, ap_brdf_model_free);

static void rm_rfp(char **dir)
{
        if (*dir)
                tu_rm_rf(*dir);
        free(*dir);
}

/* Exports the model into dir/gltf; returns that path (static). */
static const char *export(const struct ap_brdf_model *m, const char *dir)
{
        static char out[600];
        char err[512] = "";

        snprintf(out, sizeof(out), "%s/gltf", dir);
        if (ap_export_gltf_model(m, out, err, sizeof(err)) != 0)
                fprintf(stderr, "export: %s\n", err);
        CHECK(access(out, F_OK) == 0);
        return out;
}

/* ---- a reader of the export, from the specifications ---- */

enum { IMG_BASE, IMG_MR, IMG_NORMAL, IMG_ANISO, IMG_N };

struct gltf {
        json_t *root;
        void *bin;
        size_t bin_len, nv;
        const float *attr[4]; /* POSITION, NORMAL, TANGENT, TEXCOORD_0 */
        uint8_t *img[IMG_N];  /* RGB8 */
        int width, height;
};

static void *slurp(const char *dir, const char *name, size_t *len)
{
        char path[800];
        void *buf = NULL;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 1 << 28, &buf, len), 0);
        return buf;
}

/* The image of texture info obj (a material's textureInfo), decoded to RGB8. */
static uint8_t *read_image(struct gltf *g, const char *dir, json_t *info)
{
        json_t *tex = json_array_get(json_object_get(g->root, "textures"),
                                     json_integer_value(json_object_get(info, "index")));
        json_t *img = json_array_get(json_object_get(g->root, "images"),
                                     json_integer_value(json_object_get(tex, "source")));
        _cleanup_free_ void *png = NULL;
        spng_ctx *ctx = spng_ctx_new(0);
        struct spng_ihdr ihdr;
        size_t len, out;
        uint8_t *px;

        CHECK(img && ctx);
        png = slurp(dir, json_string_value(json_object_get(img, "uri")), &len);
        CHECK_INT(spng_set_png_buffer(ctx, png, len), 0);
        CHECK_INT(spng_get_ihdr(ctx, &ihdr), 0);
        g->width = (int)ihdr.width;
        g->height = (int)ihdr.height;
        CHECK_INT(spng_decoded_image_size(ctx, SPNG_FMT_RGB8, &out), 0);
        CHECK((px = malloc(out)));
        CHECK_INT(spng_decode_image(ctx, px, out, SPNG_FMT_RGB8, 0), 0);
        spng_ctx_free(ctx);
        return px;
}

/* The float data of accessor k, checked to be of n components. */
static const float *accessor(struct gltf *g, json_int_t k, int n)
{
        json_t *a = json_array_get(json_object_get(g->root, "accessors"), (size_t)k);
        json_t *v = json_array_get(json_object_get(g->root, "bufferViews"),
                                   json_integer_value(json_object_get(a, "bufferView")));
        size_t off = (size_t)json_integer_value(json_object_get(v, "byteOffset")) +
                     (size_t)json_integer_value(json_object_get(a, "byteOffset"));

        CHECK(a && v);
        CHECK_INT(json_integer_value(json_object_get(a, "componentType")), 5126);
        CHECK(!json_object_get(v, "byteStride"));
        g->nv = (size_t)json_integer_value(json_object_get(a, "count"));
        CHECK(off + g->nv * n * sizeof(float) <= g->bin_len);
        return (const float *)((const char *)g->bin + off);
}

static void gltf_read(struct gltf *g, const char *dir)
{
        static const char *const names[4] = {"POSITION", "NORMAL", "TANGENT", "TEXCOORD_0"};
        static const int comps[4] = {3, 3, 4, 2};
        char path[800];
        json_t *prim, *mat;

        snprintf(path, sizeof(path), "%s/model.gltf", dir);
        CHECK((g->root = json_load_file(path, 0, NULL)));
        CHECK_STR(json_string_value(json_object_get(json_object_get(g->root, "asset"), "version")),
                  "2.0");
        g->bin = slurp(dir,
                       json_string_value(json_object_get(
                               json_array_get(json_object_get(g->root, "buffers"), 0), "uri")),
                       &g->bin_len);
        prim = json_array_get(json_object_get(json_array_get(json_object_get(g->root, "meshes"), 0),
                                              "primitives"),
                              0);
        CHECK(prim && !json_object_get(prim, "indices"));
        for (int k = 0; k < 4; k++)
                g->attr[k] = accessor(g,
                                      json_integer_value(json_object_get(
                                              json_object_get(prim, "attributes"), names[k])),
                                      comps[k]);
        mat = json_array_get(json_object_get(g->root, "materials"),
                             json_integer_value(json_object_get(prim, "material")));
        g->img[IMG_BASE] = read_image(
                g, dir,
                json_object_get(json_object_get(mat, "pbrMetallicRoughness"), "baseColorTexture"));
        g->img[IMG_MR] = read_image(g, dir,
                                    json_object_get(json_object_get(mat, "pbrMetallicRoughness"),
                                                    "metallicRoughnessTexture"));
        g->img[IMG_NORMAL] = read_image(g, dir, json_object_get(mat, "normalTexture"));
        g->img[IMG_ANISO] =
                read_image(g, dir,
                           json_object_get(json_object_get(json_object_get(mat, "extensions"),
                                                           "KHR_materials_anisotropy"),
                                           "anisotropyTexture"));
}

static void gltf_free(struct gltf *g)
{
        json_decref(g->root);
        free(g->bin);
        for (int k = 0; k < IMG_N; k++)
                free(g->img[k]);
}

static float dot3(const float *a, const float *b)
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const float *a, const float *b, float *c)
{
        c[0] = a[1] * b[2] - a[2] * b[1];
        c[1] = a[2] * b[0] - a[0] * b[2];
        c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Triangle t's tangent frame follows its uvs as glTF's normal textures need it: T along
 * +u, the bitangent N x T w up the image (along -v: glTF's v runs down the image). */
static void check_handedness(const struct gltf *g, size_t t)
{
        const float *p = &g->attr[0][9 * t], *uv = &g->attr[3][6 * t];
        float e1[3], e2[3], dpdu[3], dpdv[3], b[3];
        float du1 = uv[2] - uv[0], dv1 = uv[3] - uv[1], du2 = uv[4] - uv[0], dv2 = uv[5] - uv[1];
        float det = du1 * dv2 - du2 * dv1;

        if (p[0] == p[3] && p[1] == p[4] && p[2] == p[5])
                return; /* collapsed: any frame */
        for (int k = 0; k < 3; k++) {
                e1[k] = p[3 + k] - p[k];
                e2[k] = p[6 + k] - p[k];
                dpdu[k] = (e1[k] * dv2 - e2[k] * dv1) / det;
                dpdv[k] = (e2[k] * du1 - e1[k] * du2) / det;
        }
        for (int c = 0; c < 3; c++) {
                const float *n = &g->attr[1][3 * (3 * t + c)], *tg = &g->attr[2][4 * (3 * t + c)];
                cross3(n, tg, b);
                CHECK(dot3(tg, dpdu) > 0);
                CHECK(dot3(b, dpdv) * tg[3] < 0);
        }
}

/* Every corner is its own vertex: the mesh's position, the atlas' uv, a unit normal, a unit
 * tangent orthogonal to it with w = +-1, the frame oriented by the uvs. */
static void check_vertices(const struct gltf *g, const struct ap_atlas *a)
{
        CHECK_INT(g->nv, 3 * a->mesh.nt);
        for (size_t t = 0; t < a->mesh.nt; t++)
                check_handedness(g, t);
        for (size_t v = 0; v < g->nv; v++) {
                const float *p = &g->attr[0][3 * v], *n = &g->attr[1][3 * v],
                            *t = &g->attr[2][4 * v], *uv = &g->attr[3][2 * v];
                const float *q = &a->mesh.pos[3 * a->mesh.idx[v]];
                for (int k = 0; k < 3; k++)
                        CHECK_NEAR(p[k], q[k], 1e-6);
                CHECK_NEAR(uv[0], a->uv[2 * v], 1e-7);
                CHECK_NEAR(uv[1], a->uv[2 * v + 1], 1e-7);
                CHECK_NEAR(dot3(n, n), 1, 1e-5);
                CHECK_NEAR(dot3(t, t), 1, 1e-5);
                CHECK_NEAR(dot3(n, t), 0, 1e-5);
                CHECK(t[3] == 1 || t[3] == -1);
        }
}

/* The barycentric coordinates of texel (x, y)'s centre in triangle t's glTF uvs. */
static void texel_bary(const struct gltf *g, size_t t, int x, int y, float b[3])
{
        const float *uv = &g->attr[3][6 * t];
        float px = (x + 0.5f) / (float)g->width, py = (y + 0.5f) / (float)g->height;
        float d = (uv[3] - uv[5]) * (uv[0] - uv[4]) + (uv[4] - uv[2]) * (uv[1] - uv[5]);

        b[0] = ((uv[3] - uv[5]) * (px - uv[4]) + (uv[4] - uv[2]) * (py - uv[5])) / d;
        b[1] = ((uv[5] - uv[1]) * (px - uv[4]) + (uv[0] - uv[4]) * (py - uv[5])) / d;
        b[2] = 1 - b[0] - b[1];
}

/* The tangent frame at barycentric b of triangle t: the interpolated normal, the
 * interpolated tangent made orthogonal to it, the bitangent N x T w (glTF 2.0, "Meshes"). */
static void frame_at(const struct gltf *g, size_t t, const float b[3], float T[3], float B[3],
                     float N[3])
{
        float w = 0, tn;

        memset(N, 0, 3 * sizeof(float));
        memset(T, 0, 3 * sizeof(float));
        for (int c = 0; c < 3; c++) {
                for (int k = 0; k < 3; k++) {
                        N[k] += b[c] * g->attr[1][3 * (3 * t + c) + k];
                        T[k] += b[c] * g->attr[2][4 * (3 * t + c) + k];
                }
                w += b[c] * g->attr[2][4 * (3 * t + c) + 3];
        }
        normalize3(N);
        tn = dot3(T, N);
        for (int k = 0; k < 3; k++)
                T[k] -= tn * N[k];
        normalize3(T);
        cross3(N, T, B);
        for (int k = 0; k < 3; k++)
                B[k] *= w < 0 ? -1 : 1;
}

static float unorm(uint8_t v)
{
        return v / 255.0f;
}

static float snorm(uint8_t v)
{
        return 2 * v / 255.0f - 1;
}

/* KHR_materials_anisotropy's alpha along its direction, and the largest change of it within
 * half an 8-bit step of r and s. */
static float alpha_t(float r, float s)
{
        return r * r * (1 - s * s) + s * s;
}

static float alpha_tol(float r, float s)
{
        float a = alpha_t(r, s), d = 0;

        for (int i = -1; i <= 1; i += 2)
                for (int j = -1; j <= 1; j += 2)
                        d = fmaxf(d, fabsf(alpha_t(r + (float)(i * Q), s + (float)(j * Q)) - a));
        return d + 1e-5f;
}

static float srgb_decode(float c)
{
        return c <= 0.04045f ? c / 12.92f : powf((c + 0.055f) / 1.055f, 2.4f);
}

/* The roughness, anisotropy strength and direction of texel px (index i) in frame (T, B) with
 * decoded shading normal n, against x. */
static void check_lobe(const struct gltf *g, size_t i, const struct ap_brdf_texel *x,
                       const float T[3], const float B[3], const float n[3])
{
        float r = unorm(g->img[IMG_MR][3 * i + 1]), s = unorm(g->img[IMG_ANISO][3 * i + 2]);
        float dx = snorm(g->img[IMG_ANISO][3 * i]), dy = snorm(g->img[IMG_ANISO][3 * i + 1]);
        float d[3], want[3], dn, lo = x->ks > 0 ? fminf(x->ax, x->ay) : 1;
        float hi = x->ks > 0 ? fmaxf(x->ax, x->ay) : 1; /* no lobe: fully rough */

        CHECK_NEAR(r * r, lo, alpha_tol(r, 0));
        CHECK_NEAR(alpha_t(r, s), hi, alpha_tol(r, s));
        if (hi - lo < 0.02f)
                return; /* near isotropic: the direction hardly matters, and is coarse */
        for (int k = 0; k < 3; k++)
                d[k] = dx * T[k] + dy * B[k];
        dn = dot3(d, n);
        for (int k = 0; k < 3; k++)
                d[k] -= dn * n[k];
        normalize3(d);
        if (x->ax >= x->ay)
                memcpy(want, x->tangent, sizeof(want));
        else
                cross3(x->normal, x->tangent, want);
        CHECK(fabsf(dot3(d, want)) >= cosf(ANGLE_TOL));
}

/* The base colour and metalness of texel i against x (docs/exports.md's mapping). */
static void check_colour(const struct gltf *g, size_t i, const struct ap_brdf_texel *x)
{
        float m = unorm(g->img[IMG_MR][3 * i + 2]), c[3], f0 = 0, cmax = 0;

        for (int k = 0; k < 3; k++) {
                c[k] = srgb_decode(unorm(g->img[IMG_BASE][3 * i + k]));
                f0 += m * c[k] / 3;
                cmax = fmaxf(cmax, c[k]);
        }
        f0 += 0.04f * (1 - m);
        if (x->ks * x->f0 <= 0.04f) {
                CHECK_INT(g->img[IMG_MR][3 * i + 2], 0);
        } else {
                CHECK_NEAR(f0, x->ks * x->f0, 0.01);
        }
        for (int k = 0; k < 3 && cmax < 0.99f; k++)
                CHECK_NEAR((1 - m) * c[k], (1 - x->ks) * x->albedo[k], 0.01);
}

/* Texel (x, y) of triangle t decoded against the model's texel. */
static void check_texel(const struct gltf *g, const struct ap_brdf_model *m, int x, int y)
{
        size_t i = (size_t)y * g->width + x, t = (size_t)m->atlas.tri[i];
        const struct ap_brdf_texel *px = &m->texels[i];
        float b[3], T[3], B[3], N[3], n[3];

        texel_bary(g, t, x, y, b);
        CHECK(b[0] >= 0 && b[1] >= 0 && b[2] >= 0);
        frame_at(g, t, b, T, B, N);
        for (int k = 0; k < 3; k++)
                n[k] = snorm(g->img[IMG_NORMAL][3 * i]) * T[k] +
                       snorm(g->img[IMG_NORMAL][3 * i + 1]) * B[k] +
                       snorm(g->img[IMG_NORMAL][3 * i + 2]) * N[k];
        normalize3(n);
        CHECK(dot3(n, px->normal) >= cosf(ANGLE_TOL));
        check_lobe(g, i, px, T, B, n);
        check_colour(g, i, px);
}

/* The texels whose centres lie inside their triangle decode to the model's parameters;
 * masked ones are a rough grey dielectric. */
static void test_decode(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = make_model(true);
        const struct ap_atlas *a = &m->atlas;
        struct gltf g = {0};
        int seen = 0, masked = 0, diffuse = 0;

        gltf_read(&g, export(m, dir));
        CHECK_INT(g.width, a->width);
        CHECK_INT(g.height, a->height);
        check_vertices(&g, a);
        for (int y = 0; y < a->height; y++)
                for (int x = 0; x < a->width; x++) {
                        size_t i = (size_t)y * a->width + x;
                        const float *b = &a->bary[3 * i];
                        if (a->tri[i] < 0 || !(b[0] > 0 && b[1] > 0 && b[2] > 0))
                                continue;
                        if ((m->texels[i].flags & AP_BRDF_MASKED) || isnan(m->texels[i].ay)) {
                                CHECK_INT(g.img[IMG_MR][3 * i + 1], 255);
                                CHECK_INT(g.img[IMG_MR][3 * i + 2], 0);
                                masked++;
                                continue;
                        }
                        check_texel(&g, m, x, y);
                        diffuse += m->texels[i].ks == 0;
                        seen++;
                }
        fprintf(stderr, "%zu vertices, %dx%d texels, %d decoded (%d diffuse only), %d masked\n",
                g.nv, g.width, g.height, seen, diffuse, masked);
        CHECK(seen > 900 && masked > 50 && diffuse > 50);
        gltf_free(&g);
}

/* ---- the Khronos validator and Blender ---- */

/* Runs cmd (a shell command line) with its stdout into out (NUL-terminated), stderr passed on.
 * Returns its exit status. */
static int run(const char *cmd, char *out, size_t len)
{
        FILE *p = popen(cmd, "r");
        size_t n;
        int st;

        CHECK(p);
        n = fread(out, 1, len - 1, p);
        out[n] = 0;
        st = pclose(p);
        return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void test_validator(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = make_model(true);
        static char out[1 << 20];
        char cmd[1200];
        json_t *report, *issues;
        int r;

        CHECK(getenv("GLTF_VALIDATE")); /* scripts/gltf-validate (meson.build sets it) */
        snprintf(cmd, sizeof(cmd), "%s %s/model.gltf", getenv("GLTF_VALIDATE"), export(m, dir));
        r = run(cmd, out, sizeof(out));
        if (r == TEST_SKIP)
                exit(TEST_SKIP);
        fprintf(stderr, "%s\n", out);
        CHECK((report = json_loads(out, 0, NULL)));
        issues = json_object_get(report, "issues");
        CHECK_INT(json_integer_value(json_object_get(issues, "numErrors")), 0);
        CHECK_INT(json_integer_value(json_object_get(issues, "numWarnings")), 0);
        CHECK_INT(r, 0);
        CHECK(strstr(out, "KHR_materials_anisotropy") && !strstr(out, "UNSUPPORTED_EXTENSION"));
        json_decref(report);
}

static void test_blender(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = make_model(true);
        size_t first = m->atlas.mesh.idx[0];
        char cmd[1600], out[8192];
        int r;

        if (access("/usr/bin/blender", X_OK) != 0) {
                fprintf(stderr, "no /usr/bin/blender (scripts/install-deps installs it)\n");
                exit(TEST_SKIP);
        }
        CHECK(getenv("GLTF_BLENDER")); /* tests/appearance/gltf-blender.py */
        snprintf(cmd, sizeof(cmd),
                 "/usr/bin/blender -b --factory-startup -noaudio --python-exit-code 3 "
                 "--python %s -- %s/model.gltf %zu %zu %.9g %.9g %.9g 2>&1",
                 getenv("GLTF_BLENDER"), export(m, dir), 3 * m->atlas.mesh.nt, m->atlas.mesh.nt,
                 m->atlas.mesh.pos[3 * first], m->atlas.mesh.pos[3 * first + 1],
                 m->atlas.mesh.pos[3 * first + 2]);
        r = run(cmd, out, sizeof(out));
        fprintf(stderr, "%s", out);
        CHECK_INT(r, 0);
        CHECK_STR_CONTAINS(out, "gltf-blender: ok");
}

/* ---- gonioctl dataset export --format gltf ---- */

/* Whether the files of the glTF folders a and b are the same bytes. */
static bool same_files(const char *a, const char *b)
{
        static const char *const files[] = {"model.gltf",    "model.bin",
                                            "basecolor.png", "metallic_roughness.png",
                                            "normal.png",    "anisotropy.png"};
        char cmd[1600], out[64];

        for (size_t k = 0; k < sizeof(files) / sizeof(files[0]); k++) {
                snprintf(cmd, sizeof(cmd), "cmp %s/%s %s/%s >&2", a, files[k], b, files[k]);
                if (run(cmd, out, sizeof(out)) != 0)
                        return false;
        }
        return true;
}

/* The model written into a dataset (ap_brdf_write) and exported by gonioctl is the one the
 * writer exports from memory, byte for byte; a dataset without it is refused by name. */
static void test_gonioctl(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = make_model(false);
        char ds[600], args[2000], out[4096];
        struct ds *d;

        snprintf(ds, sizeof(ds), "%s/ds", dir);
        CHECK_INT(ds_create(ds, "gltf", NULL, &d), 0);
        ds_close(d);
        CHECK_INT(ap_brdf_write(m, ds), 0);
        snprintf(args, sizeof(args), "dataset export %s --format gltf --model sphere -o %s/cli", ds,
                 dir);
        CHECK_INT(test_run_gonioctl(args, out, sizeof(out)), 0);
        snprintf(args, sizeof(args), "%s/cli", dir);
        CHECK(same_files(export(m, dir), args));
        snprintf(args, sizeof(args), "dataset export %s --format gltf -o %s/none", ds, dir);
        CHECK(test_run_gonioctl(args, out, sizeof(out)) != 0);
        CHECK_STR_CONTAINS(out, "has no BRDF model 'default'");
        CHECK_INT(tu_count(dir, ""), 3); /* ds, cli, gltf */
}

/* ---- bad input: refused, nothing written (no temporary folder left) ---- */

static void test_bad(void)
{
        _cleanup_(rm_rfp) char *dir = tu_tmpdir();
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = make_model(true);
        struct ap_brdf_model empty = {0};
        char out[600], keep[700], err[512];

        snprintf(out, sizeof(out), "%s/gltf", dir);
        snprintf(keep, sizeof(keep), "%s/keep", out);
        CHECK_INT(ap_export_gltf_model(NULL, out, err, sizeof(err)), -EINVAL);
        CHECK_INT(ap_export_gltf_model(&empty, out, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, "empty mesh");
        CHECK_INT(tu_count(dir, ""), 0);
        CHECK_INT(mkdir(out, 0755), 0);
        CHECK_INT(mkdir(keep, 0755), 0);
        CHECK_INT(ap_export_gltf_model(m, out, err, sizeof(err)), -EEXIST);
        CHECK_STR_CONTAINS(err, "not an empty folder");
        CHECK_INT(tu_count(out, ""), 1);
        CHECK_INT(tu_count(dir, ""), 1);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"decode", test_decode},   {"validator", test_validator},
                {"blender", test_blender}, {"gonioctl", test_gonioctl},
                {"bad", test_bad},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
