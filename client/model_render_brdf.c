/* model_render_brdf.c - gonioctl model render of a BRDF model (appearance/brdf.h) under an
 * environment map, as appearance/render_env.h relights it: the map prefiltered per
 * representative normal with the model's NDF, soft shadows from a sphere set fitted to its
 * mesh, on the object and on a ground disc at z = 0 (docs/appearance.md, "Environment
 * relighting"); or under a point or directional light, the same shadows. The camera looks at the
 * mesh's centre from --view at --distance (default four bounding radii) with --focal (default: the
 * bounding sphere fills 80% of the shorter side). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "appearance/render_env.h"
#include "client/cmd.h"
#include "client/model_render.h"
#include "common/cleanup.h"

#define PF_WIDTH      96   /* each prefiltered map's width */
#define SPHERE_GRID   32   /* cells along the mesh's longest side for the sphere fit */
#define GROUND_ALBEDO 0.5f /* the ground disc's (a grey turntable) */
#define GROUND_TOUCH  2.0  /* mm: the mesh stands on z = 0 when its lowest point is this near */
#define GROUND_RADII  3.0  /* the default ground's radius, in the mesh's bounding radii */
#define THREADS       2

struct brdf_scene {
        struct ap_envmap env;
        struct ap_prefilter pf;
        struct ap_spheres sp;
        struct ap_env_light light;
        struct ap_env_scene sc;
        double centre[3], radius, zmin;
};

static void scene_free(struct brdf_scene *s)
{
        ap_spheres_free(&s->sp);
        ap_prefilter_free(&s->pf);
        ap_envmap_free(&s->env);
}

/* The centre and radius of the mesh's bounding box, and its lowest z. */
static void mesh_bounds(const struct ap_mesh *m, double c[3], double *radius, double *zmin)
{
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};

        for (size_t v = 0; v < m->nv; v++)
                for (int i = 0; i < 3; i++) {
                        lo[i] = fmin(lo[i], m->pos[3 * v + i]);
                        hi[i] = fmax(hi[i], m->pos[3 * v + i]);
                }
        for (int i = 0; i < 3; i++)
                c[i] = (lo[i] + hi[i]) / 2;
        *radius = hypot(hypot(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]) / 2;
        *zmin = lo[2];
}

/* Loads the map and builds the prefilter, the sphere set and the scene of m. Returns 0 or an
 * exit code, the cause printed. */
static int scene_build(const struct render_opts *o, const struct ap_brdf_model *m,
                       struct brdf_scene *s)
{
        struct ap_prefilter_params pp = {.pairs = o->pairs, .width = PF_WIDTH, .threads = THREADS};
        int r;

        mesh_bounds(&m->atlas.mesh, s->centre, &s->radius, &s->zmin);
        if (o->kind == AP_LIGHT_ENV && (r = render_load_envmap(o, &s->env)) != 0)
                return r;
        ap_brdf_prefilter_params(m, &pp);
        if ((o->kind == AP_LIGHT_ENV && (r = ap_prefilter_build(&s->env, &pp, &s->pf)) < 0) ||
            (o->spheres > 0 &&
             (r = ap_spheres_fit(&m->atlas.mesh, o->spheres, SPHERE_GRID, &s->sp)) < 0)) {
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
                .ground_albedo = {GROUND_ALBEDO, GROUND_ALBEDO, GROUND_ALBEDO},
                .ground_radius = (float)(o->ground >= 0                  ? o->ground
                                         : fabs(s->zmin) <= GROUND_TOUCH ? GROUND_RADII * s->radius
                                                                         : 0),
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

int model_render_brdf(const struct render_opts *o, const struct ap_brdf_model *m)
{
        struct brdf_scene s = {0};
        struct ap_env_renderer *r = NULL;
        struct ap_camera cam;
        int e;

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
