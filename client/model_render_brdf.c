/* model_render_brdf.c - gonioctl model render of a BRDF model (appearance/brdf.h) under an
 * environment map, as appearance/render_env.h relights it: the map prefiltered per
 * representative normal with the model's NDF, soft shadows from a sphere set fitted to its
 * mesh, on the object and on a ground disc at z = 0 (docs/appearance.md, "Environment
 * relighting"); or under a point or directional light, the same shadows. The camera looks at the
 * mesh's centre from --view at --distance (default four bounding radii) with --focal (default: the
 * bounding sphere fills 80% of the shorter side). A model of the view kind (no mesh:
 * appearance/brdf_render.h) under a point or directional light only, from its captured view's
 * own camera at that view's direction, else the nearest view's (as the SH model's). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "appearance/brdf_render.h"
#include "appearance/render_env.h"
#include "client/cmd.h"
#include "client/model_render.h"
#include "common/cleanup.h"

#define PF_WIDTH     96  /* each prefiltered map's width */
#define CAPTURED_DEG 0.1 /* a --view this near a captured view's direction is that view */
#define THREADS      2

struct brdf_scene {
        struct ap_envmap env;
        struct ap_prefilter pf;
        struct ap_spheres sp;
        struct ap_env_light light;
        struct ap_env_scene sc;
        double centre[3], radius;
};

static void scene_free(struct brdf_scene *s)
{
        ap_spheres_free(&s->sp);
        ap_prefilter_free(&s->pf);
        ap_envmap_free(&s->env);
}

/* The centre and radius of the mesh's bounding box. */
static void mesh_bounds(const struct ap_mesh *m, double c[3], double *radius)
{
        double lo[3], hi[3];

        ap_mesh_bounds(m, lo, hi);
        for (int i = 0; i < 3; i++)
                c[i] = (lo[i] + hi[i]) / 2;
        *radius = hypot(hypot(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]) / 2;
}

/* Loads the map and builds the prefilter, the sphere set and the scene of m. Returns 0 or an
 * exit code, the cause printed. */
static int scene_build(const struct render_opts *o, const struct ap_brdf_model *m,
                       struct brdf_scene *s)
{
        struct ap_prefilter_params pp = {.pairs = o->pairs, .width = PF_WIDTH, .threads = THREADS};
        int r;

        mesh_bounds(&m->atlas.mesh, s->centre, &s->radius);
        if (o->kind == AP_LIGHT_ENV && (r = render_load_envmap(o, &s->env)) != 0)
                return r;
        ap_brdf_prefilter_params(m, &pp);
        if ((o->kind == AP_LIGHT_ENV && (r = ap_prefilter_build(&s->env, &pp, &s->pf)) < 0) ||
            (o->spheres > 0 &&
             (r = ap_spheres_fit(&m->atlas.mesh, o->spheres, AP_ENV_SPHERE_GRID, &s->sp)) < 0)) {
                fprintf(stderr, "gonioctl: model render: %s: %s\n", o->model,
                        r == -EINVAL ? "the mesh is not closed: no sphere set (--spheres 0)"
                                     : strerror(-r));
                return r == -ENOMEM ? EXIT_STORAGE : EXIT_INVALID;
        }
        s->light =
                (struct ap_env_light){o->kind == AP_LIGHT_POINT,
                                      {(float)o->light[0], (float)o->light[1], (float)o->light[2]},
                                      (float)(o->intensity > 0 ? o->intensity : 1)};
        s->sc = (struct ap_env_scene){
                .m = m,
                .env = &s->env,
                .pf = &s->pf,
                .light = o->kind == AP_LIGHT_ENV ? NULL : &s->light,
                .sp = o->spheres > 0 ? &s->sp : NULL,
                .ground_albedo = {AP_ENV_GROUND_ALBEDO, AP_ENV_GROUND_ALBEDO, AP_ENV_GROUND_ALBEDO},
                .ground_radius =
                        o->ground >= 0 ? (float)o->ground : ap_env_default_ground(&m->atlas.mesh),
                .scale = (float)(m->response *
                                 (o->kind == AP_LIGHT_ENV && o->intensity > 0 ? o->intensity : 1)),
        };
        return 0;
}

/* The camera: --size (default 640x480), --focal or the bounding sphere at 80%. */
static int scene_camera(const struct render_opts *o, const struct brdf_scene *s,
                        struct ap_camera *cam)
{
        int w = o->width ?: 640, h = o->height ?: 480;
        double dist = o->distance > 0 ? o->distance : 4 * s->radius, f = o->focal;

        if (!(f > 0))
                f = 0.4 * MIN(w, h) / tan(asin(fmin(s->radius / dist, 0.99)));
        return render_place_camera(o, s->centre, dist, (struct ap_camera){w, h, f, f}, cam);
}

static int render(const struct render_opts *o, const struct brdf_scene *s,
                  struct ap_env_renderer *r, const struct ap_camera *cam)
{
        size_t n = (size_t)cam->width * cam->height, count[3] = {0};
        _cleanup_free_ float *rgb = malloc(3 * n * sizeof(float));
        _cleanup_free_ uint8_t *mask = malloc(n);
        int e;

        if (!rgb || !mask)
                return EXIT_STORAGE;
        if ((e = ap_env_render(r, cam, THREADS, rgb, mask)) < 0 ||
            (e = render_write_image(o->out, rgb, cam->width, cam->height, o->gain)) < 0) {
                fprintf(stderr, "gonioctl: model render: %s: %s\n", o->out, strerror(-e));
                return cmd_exit_for_errno(e);
        }
        for (size_t i = 0; i < n; i++)
                count[mask[i]]++;
        printf("rendered %s: %dx%d, %zu pixels of the object, %zu of the ground, view %g,%g; ",
               o->out, cam->width, cam->height, count[1], count[2], o->az, o->el);
        if (o->kind == AP_LIGHT_ENV)
                printf("BRDF model under %s: %d normal pairs prefiltered at ax %.3f ay %.3f",
                       o->envmap, s->pf.p.pairs, s->pf.p.ax, s->pf.p.ay);
        else
                printf("BRDF model under the %s light %g,%g,%g",
                       o->kind == AP_LIGHT_POINT ? "point" : "directional", o->light[0],
                       o->light[1], o->light[2]);
        printf(", %d spheres\n", s->sc.sp ? s->sp.n : 0);
        return EXIT_OK;
}

/* The view kind's camera: the captured view's own where --view is its direction and no
 * --size, --focal or --distance asks otherwise (*captured its index, else -1); else near the
 * nearest view. Returns 0 or an exit code. */
static int view_kind_camera(const struct render_opts *o, const struct ap_brdf_model *m,
                            struct ap_camera *cam, long *captured)
{
        double d[3], best = -2;
        size_t near = 0;

        render_view_dir(o, d);
        for (size_t i = 0; i < m->n_views; i++) {
                const double *v = m->views[i].dir;
                if (v[0] * d[0] + v[1] * d[1] + v[2] * d[2] > best)
                        best = v[0] * d[0] + v[1] * d[1] + v[2] * d[2], near = i;
        }
        *captured = -1;
        if (best < cos(CAPTURED_DEG * M_PI / 180) || o->width || o->focal > 0 || o->distance > 0)
                return render_camera_near(o, m->centre, &m->views[near].cam, cam);
        *cam = m->views[near].cam;
        *captured = (long)near;
        return 0;
}

/* Renders view-kind model m under o's light, the views triangulated in vs. */
static int render_view_kind(const struct render_opts *o, const struct ap_brdf_model *m,
                            const struct ap_views *vs)
{
        struct ap_env_light L = {o->kind == AP_LIGHT_POINT,
                                 {(float)o->light[0], (float)o->light[1], (float)o->light[2]},
                                 (float)(o->intensity > 0 ? o->intensity : 1)};
        _cleanup_free_ float *rgb = NULL;
        _cleanup_free_ uint8_t *mask = NULL;
        struct ap_camera cam;
        size_t n, covered = 0;
        long captured;
        int e;

        if ((e = render_check_view(o, vs)) != 0 || (e = view_kind_camera(o, m, &cam, &captured)))
                return e;
        n = (size_t)cam.width * cam.height;
        if (!(rgb = malloc(3 * n * sizeof(float))) || !(mask = malloc(n)))
                return EXIT_STORAGE;
        if ((e = ap_brdf_view_render(m, vs, &cam, &L, rgb, mask)) < 0 ||
            (e = render_write_image(o->out, rgb, cam.width, cam.height, o->gain)) < 0) {
                fprintf(stderr, "gonioctl: model render: %s: %s\n", o->out, strerror(-e));
                return cmd_exit_for_errno(e);
        }
        for (size_t i = 0; i < n; i++)
                covered += mask[i];
        printf("rendered %s: %dx%d, %zu pixels of the object, view %g,%g; BRDF model of the view "
               "kind (no mesh): ",
               o->out, cam.width, cam.height, covered, o->az, o->el);
        if (captured >= 0)
                printf("captured view %ld\n", captured);
        else
                printf("the captured views around it blended\n");
        return EXIT_OK;
}

/* A model of the view kind: refused under an environment map, else rendered. */
static int model_render_view_kind(const struct render_opts *o, const struct ap_brdf_model *m)
{
        struct ap_views *vs = NULL;
        int e;

        if (o->kind == AP_LIGHT_ENV) {
                fprintf(stderr,
                        "gonioctl: model render: %s: the BRDF model is of the view kind (fitted "
                        "without a mesh): no environment lighting without a mesh (its shadows "
                        "and normals off the views); use --light or --dir, or scan the object "
                        "and fit again\n",
                        o->model);
                return EXIT_INVALID;
        }
        if ((e = ap_brdf_views_new(m, &vs)) < 0) {
                fprintf(stderr, "gonioctl: model render: %s: cannot render: %s\n", o->model,
                        strerror(-e));
                return cmd_exit_for_errno(e);
        }
        e = render_view_kind(o, m, vs);
        ap_views_free(vs);
        return e;
}

int model_render_brdf(const struct render_opts *o, const struct ap_brdf_model *m)
{
        struct brdf_scene s = {0};
        struct ap_env_renderer *r = NULL;
        struct ap_camera cam;
        int e;

        if (m->kind == AP_BRDF_KIND_VIEW)
                return model_render_view_kind(o, m);
        if ((e = scene_build(o, m, &s)) == 0 && (e = scene_camera(o, &s, &cam)) == 0) {
                if ((e = ap_env_renderer_new(&s.sc, &r)) < 0) {
                        fprintf(stderr, "gonioctl: model render: %s: cannot render: %s\n", o->model,
                                strerror(-e));
                        e = cmd_exit_for_errno(e);
                } else
                        e = render(o, &s, r, &cam);
        }
        ap_env_renderer_free(r);
        scene_free(&s);
        return e;
}
