/* brdf_fit.c - the BRDF fit's setup and course (brdf_fit.h): the geometry exactly as the SH
 * fit places it (ap_geometry_read), the camera's response and the material's Fresnel f0 from
 * the rig file's simulated scene where it has one; the texel kind: the object's mesh (mesh.h)
 * and its atlas, the samples (brdf_samples.c), then the texels fitted on threads
 * (brdf_solve.c) and the fallbacks counted into the model's notes; the view kind where there
 * is no mesh or it is asked for (brdf_view.c). */
#include <errno.h>
#include <gsl/gsl_errno.h>
#include <math.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "appearance/brdf_internal.h"
#include "appearance/mesh.h"
#include "common/cleanup.h"
#include "sim/render/internal.h" /* the scene's sensor and material */

void ap_brdf_fit_opts_default(struct ap_brdf_fit_opts *o)
{
        *o = (struct ap_brdf_fit_opts){.name = "default",
                                       .texels = AP_BRDF_TEXELS_DEFAULT,
                                       .threads = 2,
                                       .saturation = 0.995,
                                       .f0 = 0.04,
                                       .background = 0.01};
}

void brdf_note(char *notes, size_t len, const char *fmt, ...)
{
        size_t n = strlen(notes);
        char buf[512];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(buf, sizeof(buf), fmt, ap);
        va_end(ap);
        snprintf(notes + n, len - n, "%s%s", n ? "; " : "", buf);
}

/* The response (pixel value at the base exposure and gain per unit of I / r^2 f cos, as
 * sim/render/render.c's escale and sensor.c's gain) and f0 from the rig's simulated scene. */
static void sensor_and_material(struct brdf_ctx *c, struct ap_brdf_model *m)
{
        struct sim_scene *s = NULL;
        char err[512];

        c->response = 1;
        c->f0 = c->o->f0;
        if (sim_scene_new(c->g->rc, &s, err, sizeof(err)) < 0) {
                brdf_note(m->notes, sizeof(m->notes), "no simulated sensor: response 1, f0 %g",
                          c->f0);
                return;
        }
        c->response =
                c->exposure_ref * 1e-6 * s->sensor.response * c->gain_ref / s->sensor.full_well;
        if (s->has_object && s->mats[s->geoms[0].mat].model == SPEC_BECKMANN)
                c->f0 = s->mats[s->geoms[0].mat].f0;
        else
                brdf_note(m->notes, sizeof(m->notes),
                          "f0 %g (the scene's object has no Beckmann lobe)", c->f0);
        sim_scene_free(s);
}

/* A mesh too fine for o->texels (a cell of AP_ATLAS_MIN_CELL texels a side holds two
 * triangles: its atlas would hold more than 4 times the texels asked) simplified to fit
 * them, noted in m. */
static int fit_mesh_to_texels(const struct brdf_ctx *c, struct ap_mesh *mesh,
                              struct ap_brdf_model *m)
{
        size_t target = MAX(2 * c->o->texels / (AP_ATLAS_MIN_CELL * AP_ATLAS_MIN_CELL), 1),
               nt = mesh->nt;
        int r;

        if (nt <= 4 * target) /* the atlas at most 4x the texels asked: left as it is */
                return 0;
        if ((r = ap_mesh_simplify(mesh, target)) < 0)
                return r;
        brdf_note(m->notes, sizeof(m->notes),
                  "mesh simplified from %zu to %zu triangles for an atlas of about %zu texels "
                  "(--texels)",
                  nt, mesh->nt, c->o->texels);
        return 0;
}

/* The mesh (simplified to the texels, noted in m) and its atlas; each texel's point and
 * normal. */
static int atlas_setup(struct brdf_ctx *c, struct ap_brdf_model *m, char *err, size_t errlen)
{
        struct ap_mesh mesh;
        char src[512];
        size_t n;
        int r = ap_mesh_for_dataset(c->dir, c->o->backends, &mesh, src, sizeof(src), err, errlen);

        if (r < 0)
                return r;
        if ((r = fit_mesh_to_texels(c, &mesh, m)) < 0) {
                ap_mesh_free(&mesh);
                return r;
        }
        r = ap_atlas_build(&mesh, ap_atlas_cell_for(mesh.nt, c->o->texels), &c->atlas);
        ap_mesh_free(&mesh);
        if (r < 0) {
                snprintf(err, errlen, "%s: no atlas of %zu texels on it", src, c->o->texels);
                return r;
        }
        n = (size_t)c->atlas.width * c->atlas.height;
        c->points = malloc(3 * n * sizeof(float));
        c->normals = malloc(3 * n * sizeof(float));
        if (!c->points || !c->normals)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                if (!ap_atlas_point(&c->atlas, i, &c->points[3 * i], &c->normals[3 * i]))
                        c->points[3 * i] = NAN;
        return 0;
}

void brdf_base_tangent(const float n[3], float t[3])
{
        float a[3] = {0, 0, 1}, d, l;

        if (fabsf(n[2]) > 0.999f)
                a[0] = 1, a[2] = 0;
        d = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
        for (int i = 0; i < 3; i++)
                t[i] = a[i] - d * n[i];
        l = sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        for (int i = 0; i < 3; i++)
                t[i] /= l;
}

struct worker {
        const struct brdf_ctx *c;
        const struct brdf_samples *s;
        struct ap_brdf_model *m;
        int k, n;       /* texels k, k + n, k + 2n... */
        size_t invalid; /* texels whose solve gave no valid parameters (masked) */
};

static void *work(void *arg)
{
        struct worker *w = arg;
        size_t n = w->s->n_texels;

        for (size_t i = (size_t)w->k; i < n; i += (size_t)w->n) {
                struct ap_brdf_texel *x = &w->m->texels[i];
                if (isnan(w->c->points[3 * i])) {
                        *x = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
                        continue;
                }
                memcpy(x->normal, &w->c->normals[3 * i], sizeof(x->normal));
                brdf_base_tangent(x->normal, x->tangent);
                x->f0 = (float)w->c->f0;
                brdf_solve_texel(w->s->s + w->s->first[i], w->s->first[i + 1] - w->s->first[i],
                                 &brdf_texel_limits, x);
                if (!ap_brdf_texel_valid(x)) {
                        *x = (struct ap_brdf_texel){.flags = AP_BRDF_MASKED};
                        w->invalid++;
                }
        }
        return NULL;
}

void brdf_run_threads(int n, void *(*fn)(void *), void *args, size_t size)
{
        pthread_t th[16];
        bool started[16] = {false};

        for (int k = 1; k < n; k++)
                started[k] = pthread_create(&th[k], NULL, fn, (char *)args + k * size) == 0;
        for (int k = 0; k < n; k++) /* the first's share, and any a thread did not start for */
                if (!started[k])
                        fn((char *)args + k * size);
        for (int k = 1; k < n; k++)
                if (started[k])
                        pthread_join(th[k], NULL);
}

static int fit_texels(const struct brdf_ctx *c, const struct brdf_samples *s,
                      struct ap_brdf_model *m)
{
        struct worker w[16];
        int n = c->o->threads;

        m->texels = calloc(s->n_texels, sizeof(*m->texels));
        if (!m->texels)
                return -ENOMEM;
        for (int k = 0; k < n; k++)
                w[k] = (struct worker){c, s, m, k, n, 0};
        brdf_run_threads(n, work, w, sizeof(w[0]));
        for (int k = 1; k < n; k++)
                w[0].invalid += w[k].invalid;
        if (w[0].invalid)
                brdf_note(m->notes, sizeof(m->notes),
                          "%zu texels masked: their solve gave no valid parameters", w[0].invalid);
        return 0;
}

/* The fallbacks taken and the samples left out, into m's notes. */
static void summarise(const struct brdf_samples *s, struct ap_brdf_model *m)
{
        size_t diffuse = 0, masked = 0, sat = 0, n = s->n_texels;

        for (size_t i = 0; i < n; i++) {
                diffuse += (m->texels[i].flags & AP_BRDF_DIFFUSE_ONLY) != 0;
                masked += (m->texels[i].flags & AP_BRDF_MASKED) != 0;
                sat += (m->texels[i].flags & AP_BRDF_DIFFUSE_ONLY) && s->n_sat_near[i] > 0;
        }
        if (masked)
                brdf_note(m->notes, sizeof(m->notes),
                          "%zu of %zu texels masked (fewer than %d samples seen, lit and "
                          "unsaturated)",
                          masked, n, AP_BRDF_MIN_SAMPLES);
        if (diffuse)
                brdf_note(m->notes, sizeof(m->notes),
                          "%zu texels diffuse only (fewer than %d usable samples near a highlight)",
                          diffuse, AP_BRDF_MIN_NEAR);
        if (sat)
                brdf_note(m->notes, sizeof(m->notes),
                          "%zu of them had their highlight samples saturated", sat);
        if (s->n_sat)
                brdf_note(m->notes, sizeof(m->notes), "%zu saturated samples left out", s->n_sat);
        if (s->n_shadowed)
                brdf_note(m->notes, sizeof(m->notes), "%zu samples in shadow left out",
                          s->n_shadowed);
}

static void ctx_free(struct brdf_ctx *c)
{
        ap_geometry_free(c->g);
        ap_atlas_free(&c->atlas);
        free(c->points);
        free(c->normals);
}

static int check_opts(const struct ap_brdf_fit_opts *o, char *err, size_t errlen)
{
        if (o->name && o->name[0] && !strchr(o->name, '/') && o->name[0] != '.' &&
            strlen(o->name) < AP_NAME_MAX && o->texels >= 16 && o->texels <= ((size_t)1 << 26) &&
            o->threads >= 1 && o->threads <= 16 && o->saturation > 0 && o->f0 >= 0 && o->f0 <= 1 &&
            o->background >= 0 && o->background < 1 && o->kind <= AP_BRDF_FIT_VIEW)
                return 0;
        snprintf(err, errlen,
                 "bad options: name '%s', %zu texels, %d threads, saturation %g, f0 %g, "
                 "background %g",
                 o->name ? o->name : "", o->texels, o->threads, o->saturation, o->f0,
                 o->background);
        return -EINVAL;
}

/* The texel kind: the mesh and its atlas, the samples of every texel, their fits. */
static int fit_texel_kind(struct brdf_ctx *c, struct ap_brdf_model *m, char *err, size_t errlen)
{
        struct brdf_samples s = {0};
        int r = atlas_setup(c, m, err, errlen);

        if (r == 0 && (r = brdf_samples_read(c, &s)) < 0)
                snprintf(err, errlen, "%s", c->err[0] ? c->err : strerror(-r));
        if (r == 0)
                r = fit_texels(c, &s, m);
        if (r == 0) {
                summarise(&s, m);
                m->kind = AP_BRDF_KIND_TEXEL;
                m->atlas = c->atlas;
                c->atlas = (struct ap_atlas){0};
                m->read_seconds = s.read_seconds;
        }
        brdf_samples_free(&s);
        return r;
}

/* The kind o asks for, or without a mesh (o->kind AP_BRDF_FIT_AUTO) the view kind. */
static int fit_kind(struct brdf_ctx *c, struct ap_brdf_model *m, char *err, size_t errlen)
{
        int r = -ENOENT;

        if (c->o->kind != AP_BRDF_FIT_VIEW)
                r = fit_texel_kind(c, m, err, errlen);
        if (r == -ENOENT && c->o->kind == AP_BRDF_FIT_AUTO)
                brdf_note(m->notes, sizeof(m->notes), "%s: fitted per pixel of each view", err);
        if (r != -ENOENT || c->o->kind == AP_BRDF_FIT_TEXEL)
                return r;
        if ((r = brdf_view_fit(c, m)) < 0)
                snprintf(err, errlen, "%s", c->err[0] ? c->err : strerror(-r));
        return r;
}

int ap_brdf_fit(struct ds *d, const struct ap_brdf_fit_opts *o, struct ap_brdf_model **ret,
                char *err, size_t errlen)
{
        struct brdf_ctx c = {.o = o, .dir = d ? ds_path(d) : NULL};
        struct ap_brdf_model *m = calloc(1, sizeof(*m));
        struct timespec t0, t1;
        int r = m ? check_opts(o, err, errlen) : -ENOMEM;

        clock_gettime(CLOCK_MONOTONIC, &t0);
        gsl_set_error_handler_off();
        if (r == 0)
                r = ap_geometry_read(d, o->calibration, o->backends, &c.g, err, errlen);
        if (r == 0) {
                snprintf(m->notes, sizeof(m->notes), "%s", c.g->notes);
                c.exposure_ref =
                        c.g->shots[0].row->exposure_us > 0 ? c.g->shots[0].row->exposure_us : 1;
                c.gain_ref = c.g->shots[0].row->gain > 0 ? c.g->shots[0].row->gain : 1;
                sensor_and_material(&c, m);
                r = fit_kind(&c, m, err, errlen);
        }
        if (r == 0) {
                snprintf(m->name, sizeof(m->name), "%s", o->name);
                m->response = c.response;
                clock_gettime(CLOCK_MONOTONIC, &t1);
                m->fit_seconds = (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
                *ret = TAKE_PTR(m);
        }
        ctx_free(&c);
        ap_brdf_model_free(m);
        return r;
}
