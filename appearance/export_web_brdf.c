/* export_web_brdf.c - the BRDF model's part of the web folder (webexport.h, docs/viewer.md):
 * its atlas mesh with per-corner uv, its texels (8 bits where that is enough, else float16),
 * its sphere set with the table of visible fractions, and per environment map the prefilter
 * (maps, normals, a, cmin, irradiance SH), the per-vertex V_d and the ground's V_d grid, and
 * the map itself: what ap_env_render (render_env.h) uses, so that the page computes the same
 * frame. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/web_internal.h"
#include "common/cleanup.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_env_renderer *, ap_env_renderer_free);

int ap_web_spheres(const struct ap_brdf_model *m, int n, struct ap_spheres *out)
{
        return ap_spheres_fit(&m->atlas.mesh, n, AP_ENV_SPHERE_GRID, out);
}

int ap_web_env_scene(const struct ap_brdf_model *m, const struct ap_envmap *env,
                     const struct ap_spheres *sp, struct ap_prefilter *pf, struct ap_env_scene *sc)
{
        struct ap_prefilter_params p = {
                .pairs = AP_ENV_PAIRS, .width = AP_WEB_PF_WIDTH, .threads = 2};

        ap_brdf_prefilter_params(m, &p);
        *sc = (struct ap_env_scene){
                .m = m,
                .env = env,
                .pf = pf,
                .sp = sp,
                .ground_albedo = {AP_ENV_GROUND_ALBEDO, AP_ENV_GROUND_ALBEDO, AP_ENV_GROUND_ALBEDO},
                .ground_radius = ap_env_default_ground(&m->atlas.mesh),
                .scale = (float)m->response};
        return ap_prefilter_build(env, &p, pf);
}

int web_brdf_load(struct web *w, const char *model_dir)
{
        int r = ap_brdf_read(model_dir, &w->brdf, w->err, w->errlen);

        if (r == 0 && w->brdf->kind == AP_BRDF_KIND_VIEW) /* no mesh: the viewer shows SH only */
                w->brdf = ap_brdf_model_free(w->brdf);
        if (r == -ENOENT)
                w->err[0] = 0;
        else if (r < 0 && !w->err[0])
                web_fail(w, r, "the BRDF model");
        return r == -ENOENT ? 0 : r;
}

void web_brdf_free(struct web *w)
{
        w->brdf = ap_brdf_model_free(w->brdf);
        ap_spheres_free(&w->sp);
}

/* n floats as float16 (clamped to its range). */
static void put_half(uint16_t *dst, const float *src, size_t n)
{
        for (size_t i = 0; i < n; i++) {
                _Float16 h = (_Float16)fminf(fmaxf(src[i], -65504.f), 65504.f);
                memcpy(dst + i, &h, 2);
        }
}

static uint8_t unorm8(float v)
{
        return (uint8_t)lrintf(255 * fminf(fmaxf(v, 0), 1));
}

/* The atlas mesh: float32 positions, uint32 triangles, float32 uv (6 per triangle). */
static int write_mesh(struct web *w, json_t *bm)
{
        const struct ap_atlas *a = &w->brdf->atlas;
        size_t pb = a->mesh.nv * 3 * 4, ib = a->mesh.nt * 3 * 4, ub = a->mesh.nt * 6 * 4;
        _cleanup_free_ unsigned char *buf = malloc(pb + ib + ub);
        json_t *e = json_pack("{s:i,s:i}", "vertices", (json_int_t)a->mesh.nv, "triangles",
                              (json_int_t)a->mesh.nt);

        json_object_set_new(bm, "mesh", e);
        if (!buf)
                return web_fail(w, -ENOMEM, "BRDF mesh");
        memcpy(buf, a->mesh.pos, pb);
        for (size_t i = 0; i < a->mesh.nt * 3; i++) {
                uint32_t v = a->mesh.idx[i];
                memcpy(buf + pb + 4 * i, &v, 4);
        }
        memcpy(buf + pb + ib, a->uv, ub);
        return web_write_chunk(w, "brdf_mesh", buf, pb + ib + ub, e);
}

/* The texels: RGBA8 albedo and ks; RGBA float16 normal and ax; tangent and ay; flags (bytes). */
static int write_texels(struct web *w, json_t *bm)
{
        const struct ap_brdf_model *m = w->brdf;
        size_t n = (size_t)m->atlas.width * m->atlas.height, len = 4 * n + 16 * n + n;
        _cleanup_free_ uint8_t *buf = malloc(len);
        uint16_t *nrm = (uint16_t *)(buf + 4 * n), *tan = nrm + 4 * n;
        json_int_t count[3] = {0};
        json_t *e = json_object();

        json_object_set_new(bm, "texels", e);
        if (!buf)
                return web_fail(w, -ENOMEM, "BRDF texels");
        for (size_t i = 0; i < n; i++) {
                const struct ap_brdf_texel *x = &m->texels[i];
                float nx[4] = {x->normal[0], x->normal[1], x->normal[2], x->ax};
                float tx[4] = {x->tangent[0], x->tangent[1], x->tangent[2], x->ay};
                for (int c = 0; c < 3; c++)
                        buf[4 * i + c] = unorm8(x->albedo[c]);
                buf[4 * i + 3] = unorm8(x->ks);
                put_half(nrm + 4 * i, nx, 4);
                put_half(tan + 4 * i, tx, 4);
                buf[20 * n + i] = (uint8_t)x->flags;
                for (int b = 0; b < 3; b++)
                        count[b] += (x->flags >> b) & 1;
        }
        json_object_set_new(e, "fitted", json_integer(count[0]));
        json_object_set_new(e, "diffuse_only", json_integer(count[1]));
        json_object_set_new(e, "masked", json_integer(count[2]));
        return web_write_chunk(w, "brdf_texels", buf, len, e);
}

/* The sphere set: 4 float32 a sphere, then ap_sg_visible's table (float32). */
static int write_spheres(struct web *w, json_t *bm)
{
        int n = w->o->spheres > 0 ? w->o->spheres : AP_ENV_SPHERES, r;
        size_t sb, tb = sizeof(w->sp.vis);
        _cleanup_free_ unsigned char *buf = NULL;
        json_t *e = json_object();

        json_object_set_new(bm, "spheres", e);
        r = ap_web_spheres(w->brdf, n, &w->sp);
        if (r == -EINVAL) { /* not a closed mesh: no shadows, as render_env.h without spheres */
                ap_spheres_table(&w->sp);
                json_object_set_new(e, "note", json_string("the mesh is not closed: no shadows"));
        } else if (r < 0)
                return web_fail(w, r, "the BRDF model's sphere set");
        sb = (size_t)w->sp.n * 4 * sizeof(float);
        if (!(buf = malloc(sb + tb)))
                return web_fail(w, -ENOMEM, "spheres");
        if (sb)
                memcpy(buf, w->sp.s, sb);
        memcpy(buf + sb, w->sp.vis, tb);
        json_object_set_new(e, "count", json_integer(w->sp.n));
        json_object_set_new(e, "cell", json_real(w->sp.cell));
        json_object_set_new(e, "etas", json_integer(AP_SG_VIS_ETAS));
        json_object_set_new(e, "angles", json_integer(AP_SG_VIS_ANGLES));
        return web_write_chunk(w, "brdf_spheres", buf, sb + tb, e);
}

int web_brdf_write(struct web *w, json_t *man)
{
        const struct ap_brdf_model *m = w->brdf;
        json_t *bm;
        int r;

        if (!m)
                return 0;
        bm = json_pack("{s:s,s:f,s:{s:i,s:i,s:i},s:[]}", "notes", m->notes, "response", m->response,
                       "atlas", "width", m->atlas.width, "height", m->atlas.height, "cell",
                       m->atlas.cell, "envs");
        json_object_set_new(man, "brdf", bm);
        w->brdf_man = bm;
        if ((r = write_mesh(w, bm)) < 0 || (r = write_texels(w, bm)) < 0)
                return r;
        return write_spheres(w, bm);
}

/* e halved (2x2 boxes) until at most AP_WEB_ENV_MAX_WIDTH wide, into out (a copy). */
static int page_map(const struct ap_envmap *e, struct ap_envmap *out)
{
        int w = e->width, h = e->height;

        out->rgb = malloc(3 * sizeof(float) * (size_t)w * h);
        if (!out->rgb)
                return -ENOMEM;
        memcpy(out->rgb, e->rgb, 3 * sizeof(float) * (size_t)w * h);
        while (w > AP_WEB_ENV_MAX_WIDTH && h > 1) {
                float *p = out->rgb;
                w /= 2, h /= 2;
                for (int y = 0; y < h; y++)
                        for (int x = 0; x < w; x++)
                                for (int c = 0; c < 3; c++) {
                                        size_t s = 3 * ((size_t)2 * y * 2 * w + 2 * x) + c;
                                        size_t row = 3 * (size_t)2 * w;
                                        p[3 * ((size_t)y * w + x) + c] =
                                                (p[s] + p[s + 3] + p[s + row] + p[s + row + 3]) / 4;
                                }
        }
        out->width = w, out->height = h;
        return 0;
}

static json_t *prefilter_json(const struct ap_prefilter *pf)
{
        json_t *nrm = json_array(), *sh = json_array();

        for (int i = 0; i < 3 * pf->p.pairs; i++)
                json_array_append_new(nrm, json_real(pf->normals[i]));
        for (int i = 0; i < AP_PREFILTER_SH * 3; i++)
                json_array_append_new(sh, json_real(pf->sh[i]));
        return json_pack("{s:i,s:i,s:i,s:f,s:f,s:o,s:o,s:f,s:f,s:f,s:[fff]}", "pairs", pf->p.pairs,
                         "width", pf->width, "height", pf->height, "a", pf->a, "cmin", pf->cmin,
                         "normals", nrm, "sh", sh, "ax", pf->p.ax, "ay", pf->p.ay, "f0", pf->p.f0,
                         "axis", pf->p.axis[0], pf->p.axis[1], pf->p.axis[2]);
}

/* Map i's chunk, float16: the map (RGB), the prefiltered maps (RGBA a pair), V_d per vertex,
 * the ground's V_d grid. */
static int env_chunk(struct web *w, size_t i, const struct ap_envmap *pm,
                     const struct ap_prefilter *pf, const struct ap_env_renderer *r, json_t *e)
{
        size_t nm = 3 * (size_t)pm->width * pm->height;
        size_t np = 4 * (size_t)pf->p.pairs * pf->width * pf->height, nv = w->brdf->atlas.mesh.nv;
        size_t ng = AP_ENV_GROUND_GRID * AP_ENV_GROUND_GRID, n = nm + np + nv + ng;
        _cleanup_free_ uint16_t *buf = calloc(n, 2);
        const float *gv = ap_env_renderer_ground_vis(r);
        char name[32];

        if (!buf)
                return web_fail(w, -ENOMEM, "BRDF environment");
        put_half(buf, pm->rgb, nm);
        put_half(buf + nm, pf->maps, np);
        put_half(buf + nm + np, ap_env_renderer_vertex_vis(r), nv);
        if (gv)
                put_half(buf + nm + np + nv, gv, ng);
        snprintf(name, sizeof(name), "brdf_env_%02zu", i);
        return web_write_chunk(w, name, buf, 2 * n, e);
}

int web_brdf_env(struct web *w, size_t i, const char *name, const struct ap_envmap *env)
{
        struct ap_prefilter pf = {0};
        struct ap_envmap pm = {0};
        struct ap_env_scene sc;
        _cleanup_(ap_env_renderer_freep) struct ap_env_renderer *rd = NULL;
        json_t *e;
        int r;

        if (!w->brdf)
                return 0;
        if ((r = ap_web_env_scene(w->brdf, env, &w->sp, &pf, &sc)) < 0 ||
            (r = ap_env_renderer_new(&sc, &rd)) < 0 || (r = page_map(env, &pm)) < 0) {
                ap_prefilter_free(&pf);
                return web_fail(w, r, name);
        }
        e = prefilter_json(&pf);
        json_object_set_new(e, "name", json_string(name));
        json_object_set_new(e, "map", json_pack("[ii]", pm.width, pm.height));
        json_object_set_new(e, "ground",
                            json_pack("{s:f,s:f,s:i}", "radius", sc.ground_radius, "albedo",
                                      sc.ground_albedo[0], "grid", AP_ENV_GROUND_GRID));
        json_array_append_new(json_object_get(w->brdf_man, "envs"), e);
        r = env_chunk(w, i, &pm, &pf, rd, e);
        ap_envmap_free(&pm);
        ap_prefilter_free(&pf);
        return r;
}
