/* model_render.c - gonioctl model render MODEL: an image of an appearance model (appearance/
 * render.h) under a point light, a directional light or an environment map, from a view
 * direction around the object, written as an 8-bit linear RGB PNG (docs/appearance.md,
 * "Rendering"). Offline: reads the model and its dataset's mesh, never talks to goniod. */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "appearance/envmap.h"
#include "appearance/mesh.h"
#include "appearance/render.h"
#include "appearance/render_env.h"
#include "appearance/spheres.h"
#include "appearance/views.h"
#include "client/cmd.h"
#include "client/model.h"
#include "client/model_render.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/pfm.h"
#include "dataset/ds_png.h"
#include "drivers/registry.h"

#define MAX_OUTSIDE_DEG 30.0 /* farthest a view may be from the views the model covers */

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_renderer *, ap_renderer_free);

static int usage_error(const char *fmt, const char *arg)
{
        fprintf(stderr, "gonioctl: model render: ");
        fprintf(stderr, fmt, arg);
        fprintf(stderr,
                "\nusage: gonioctl model render MODEL (--light X,Y,Z | --dir X,Y,Z | "
                "--envmap FILE) --view AZ,EL [--distance MM] [--mode pixel|object] "
                "[--size WxH] [--intensity I] [--gain G] [--reflectance sh|brdf] "
                "[--spheres N] [--pairs N] [--ground MM] [--focal PX] -o OUT.png|OUT.pfm\n");
        return EXIT_USAGE;
}

/* n comma-separated finite numbers of s into v. */
static bool parse_list(const char *s, int n, double *v)
{
        char *end;

        for (int i = 0; i < n; i++) {
                v[i] = strtod(s, &end);
                if (end == s || !isfinite(v[i]) || *end != (i + 1 < n ? ',' : '\0'))
                        return false;
                s = end + 1;
        }
        return true;
}

static int parse_light(struct render_opts *o, int c, const char *arg)
{
        o->n_lights++;
        if (c == 'e') {
                o->kind = AP_LIGHT_ENV;
                o->envmap = arg;
                return 0;
        }
        o->kind = c == 'l' ? AP_LIGHT_POINT : AP_LIGHT_DIRECTIONAL;
        return parse_list(arg, 3, o->light) ? 0
                                            : usage_error("bad light '%s': expected X,Y,Z", arg);
}

/* --spheres N (0..AP_SPHERES_MAX, 0: no shadows), --pairs N (1..256) or --ground MM (0:
 * no ground). */
static int parse_count(struct render_opts *o, int c, const char *arg)
{
        char *end;
        double v = strtod(arg, &end);

        if (end == arg || *end || !(v >= (c == 'P')) || !isfinite(v) ||
            (c != 'G' && (v != floor(v) || v > (c == 'S' ? AP_SPHERES_MAX : 256))))
                return usage_error(c == 'S'   ? "bad sphere count '%s': expected 0 to 1024"
                                   : c == 'P' ? "bad normal pair count '%s': expected 1 to 256"
                                              : "bad ground radius '%s': expected 0 or more mm",
                                   arg);
        if (c == 'G')
                o->ground = v;
        else
                *(c == 'S' ? &o->spheres : &o->pairs) = (int)v;
        return 0;
}

static int parse_option(struct render_opts *o, int c, const char *arg)
{
        double v[2];
        char *end;

        switch (c) {
        case 'l':
        case 'd':
        case 'e':
                return parse_light(o, c, arg);
        case 'v':
                if (!parse_list(arg, 2, v))
                        return usage_error("bad view '%s': expected AZ,EL in degrees", arg);
                o->az = v[0], o->el = v[1], o->have_view = true;
                return 0;
        case 'm':
                if (strcmp(arg, "pixel") && strcmp(arg, "object"))
                        return usage_error("bad mode '%s': expected pixel or object", arg);
                o->mode = arg[0] == 'p' ? AP_VIEW_PIXEL : AP_VIEW_OBJECT;
                return 0;
        case 's':
                if (sscanf(arg, "%dx%d", &o->width, &o->height) != 2 || o->width < 1 ||
                    o->height < 1 || o->width > AP_RENDER_MAX_SIDE ||
                    o->height > AP_RENDER_MAX_SIDE)
                        return usage_error("bad size '%s': expected WxH, 1 to 8192", arg);
                return 0;
        case 'o':
                o->out = arg;
                return 0;
        case 'r':
                if (strcmp(arg, "sh") && strcmp(arg, "brdf"))
                        return usage_error("bad reflectance '%s': expected sh or brdf", arg);
                o->reflectance = arg[0] == 's' ? REFLECTANCE_SH : REFLECTANCE_BRDF;
                return 0;
        case 'S':
        case 'P':
        case 'G':
                return parse_count(o, c, arg);
        }
        v[0] = strtod(arg, &end);
        if (end == arg || *end || !(v[0] > 0) || !isfinite(v[0]))
                return usage_error("bad value '%s': expected a positive number", arg);
        *(c == 'D'   ? &o->distance
          : c == 'i' ? &o->intensity
          : c == 'F' ? &o->focal
                     : &o->gain) = v[0];
        return 0;
}

static int parse_args(int argc, char **argv, struct render_opts *o)
{
        static const struct option opts[] = {{"light", required_argument, NULL, 'l'},
                                             {"dir", required_argument, NULL, 'd'},
                                             {"envmap", required_argument, NULL, 'e'},
                                             {"view", required_argument, NULL, 'v'},
                                             {"distance", required_argument, NULL, 'D'},
                                             {"mode", required_argument, NULL, 'm'},
                                             {"size", required_argument, NULL, 's'},
                                             {"output", required_argument, NULL, 'o'},
                                             {"intensity", required_argument, NULL, 'i'},
                                             {"gain", required_argument, NULL, 'g'},
                                             {"reflectance", required_argument, NULL, 'r'},
                                             {"spheres", required_argument, NULL, 'S'},
                                             {"pairs", required_argument, NULL, 'P'},
                                             {"ground", required_argument, NULL, 'G'},
                                             {"focal", required_argument, NULL, 'F'},
                                             {NULL, 0, NULL, 0}};
        int c, r;

        *o = (struct render_opts){.gain = 1,
                                  .mode = AP_VIEW_PIXEL,
                                  .spheres = AP_ENV_SPHERES,
                                  .pairs = AP_ENV_PAIRS,
                                  .ground = -1};
        optind = 0;
        opterr = 0;
        while ((c = getopt_long(argc, argv, "+o:", opts, NULL)) != -1 || optind < argc) {
                if (c == -1) { /* a positional word: the model, then options may follow */
                        if (o->model)
                                return usage_error("unexpected argument '%s'", argv[optind]);
                        o->model = argv[optind++];
                        continue;
                }
                if (c == '?' || c == ':')
                        return usage_error("bad option '%s'", argv[optind - 1]);
                if ((r = parse_option(o, c, optarg)) != 0)
                        return r;
        }
        if (!o->model || !o->out || !o->have_view)
                return usage_error("%s", "MODEL, --view and -o are required");
        if (o->n_lights != 1)
                return usage_error("%s", "give one of --light, --dir or --envmap");
        if (o->el < -90 || o->el > 90)
                return usage_error("view elevation out of range: %s", "expected -90 to 90");
        return 0;
}

void render_view_dir(const struct render_opts *o, double d[3])
{
        d[0] = cos(o->el * M_PI / 180) * cos(o->az * M_PI / 180);
        d[1] = cos(o->el * M_PI / 180) * sin(o->az * M_PI / 180);
        d[2] = sin(o->el * M_PI / 180);
}

int render_place_camera(const struct render_opts *o, const double c[3], double dist,
                        struct ap_camera intr, struct ap_camera *cam)
{
        double d[3], eye[3];

        render_view_dir(o, d);
        intr.cx = intr.width / 2.0 - 0.5;
        intr.cy = intr.height / 2.0 - 0.5;
        for (int i = 0; i < 3; i++)
                eye[i] = c[i] + (o->distance > 0 ? o->distance : dist) * d[i];
        return ap_camera_look_at(&intr, eye, c, cam) < 0 ? EXIT_INVALID : 0;
}

int render_check_view(const struct render_opts *o, const struct ap_views *vs)
{
        double d[3], s;

        render_view_dir(o, d);
        s = ap_views_outside_angle(vs, d) * 180 / M_PI;
        if (s <= MAX_OUTSIDE_DEG)
                return 0;
        fprintf(stderr,
                "gonioctl: model render: view %g,%g is %.0f deg away from the views the model "
                "covers (at most %.0f)\n",
                o->az, o->el, s, MAX_OUTSIDE_DEG);
        return EXIT_INVALID;
}

int render_camera_near(const struct render_opts *o, const double c[3], const struct ap_camera *near,
                       struct ap_camera *cam)
{
        struct ap_camera intr = *near;
        double dist = 0, s;

        for (int i = 0; i < 3; i++) {
                double e = -(intr.R[i] * intr.t[0] + intr.R[3 + i] * intr.t[1] +
                             intr.R[6 + i] * intr.t[2]) -
                           c[i];
                dist += e * e;
        }
        s = o->width ? (double)o->width / intr.width : 1;
        intr = (struct ap_camera){o->width ?: intr.width, o->height ?: intr.height,
                                  o->focal > 0 ? o->focal : intr.fx * s,
                                  o->focal > 0 ? o->focal : intr.fy * s};
        return render_place_camera(o, c, sqrt(dist), intr, cam);
}

/* The SH model's output camera: the intrinsics of the sampled view nearest the direction
 * (scaled to --size, or --focal), at --distance (else that view's) from the mesh centre. */
static int make_camera(const struct render_opts *o, const struct ap_model *m,
                       const struct ap_renderer *r, struct ap_camera *cam)
{
        double d[3], c[3], best = -2;
        const struct ap_view *near = NULL;
        int e;

        if ((e = render_check_view(o, ap_renderer_views(r))) != 0)
                return e;
        render_view_dir(o, d);
        ap_renderer_centre(r, c);
        for (size_t i = 0; i < m->n_views; i++) {
                const double *v = m->views[i].dir;
                if (v[0] * d[0] + v[1] * d[1] + v[2] * d[2] > best)
                        best = v[0] * d[0] + v[1] * d[1] + v[2] * d[2], near = &m->views[i];
        }
        return render_camera_near(o, c, &near->cam, cam);
}

int render_load_envmap(const struct render_opts *o, struct ap_envmap *e)
{
        char err[1024];
        int r = ap_envmap_load(o->envmap, e, err, sizeof(err));

        if (r < 0) {
                fprintf(stderr, "gonioctl: model render: %s\n", err);
                return r == -ENOMEM ? EXIT_STORAGE : EXIT_INVALID;
        }
        if (e->ldr)
                fprintf(stderr,
                        "gonioctl: model render: note: %s has no HDR range (a PNG): light "
                        "brighter than its white is clipped; a PFM keeps it\n",
                        o->envmap);
        return 0;
}

static int make_light(const struct render_opts *o, const struct ap_model *m, struct ap_light *l,
                      double *env)
{
        struct ap_envmap e;
        int r;

        *l = (struct ap_light){o->kind, {o->light[0], o->light[1], o->light[2]}, o->intensity, env};
        if (o->kind != AP_LIGHT_ENV)
                return 0;
        if ((r = render_load_envmap(o, &e)) != 0)
                return r;
        ap_envmap_project(&e, m->order, env);
        ap_envmap_free(&e);
        return 0;
}

int render_write_image(const char *path, const float *rgb, int w, int h, double gain)
{
        struct gn_frame f = {0};
        _cleanup_free_ void *buf = NULL;
        _cleanup_free_ float *hdr = NULL;
        size_t len, n = 3 * (size_t)w * h;
        const char *dot = strrchr(path, '.');
        int r;

        if (dot && !strcasecmp(dot, ".pfm")) {
                if (!(hdr = malloc(n * sizeof(float))))
                        return -ENOMEM;
                for (size_t i = 0; i < n; i++)
                        hdr[i] = (float)(rgb[i] * gain);
                r = gn_pfm_encode(hdr, w, h, &buf, &len);
                return r < 0 ? r : gn_write_atomic(AT_FDCWD, path, buf, len, NULL);
        }
        if ((r = gn_frame_alloc(&f, w, h, 3, 8)) < 0)
                return r;
        for (int y = 0; y < h; y++)
                for (int i = 0; i < 3 * w; i++) {
                        double v = rgb[(size_t)y * 3 * w + i] * gain;
                        f.data[(size_t)y * f.stride + i] = (uint8_t)lrint(255 * (v < 0   ? 0
                                                                                 : v > 1 ? 1
                                                                                         : v));
                }
        r = ds_png_encode(&f, DS_PNG_LEVEL_DEFAULT, &buf, &len);
        gn_frame_free_data(&f);
        return r < 0 ? r : gn_write_atomic(AT_FDCWD, path, buf, len, NULL);
}

static int load(const struct render_opts *o, struct ap_model **m, struct ap_mesh *mesh, char *src,
                size_t srclen)
{
        char err[1024] = "", ds[PATH_MAX];
        int r = ap_model_read(o->model, m, err, sizeof(err));

        if (r < 0) {
                fprintf(stderr, "gonioctl: model render: %s: %s\n", o->model,
                        err[0]         ? err
                        : r == -ENOENT ? "no model there"
                                       : strerror(-r));
                return cmd_exit_for_errno(r == -ENOENT ? -EINVAL : r);
        }
        ap_model_dataset(o->model, ds, sizeof(ds));
        if ((r = ap_mesh_for_dataset(ds, registry_backends, mesh, src, srclen, err, sizeof(err))) <
            0) {
                fprintf(stderr, "gonioctl: model render: %s\n", err);
                return cmd_exit_for_errno(r == -ENOENT ? -EINVAL : r);
        }
        return 0;
}

static int render_to_file(const struct render_opts *o, const struct ap_model *m,
                          struct ap_renderer *r, const char *src)
{
        struct ap_camera cam;
        struct ap_light l;
        _cleanup_free_ double *env = malloc(3 * (size_t)m->n_coef * sizeof(double));
        _cleanup_free_ float *rgb = NULL;
        _cleanup_free_ uint8_t *mask = NULL;
        size_t n, covered = 0;
        int e;

        if (!env)
                return EXIT_STORAGE;
        if ((e = make_camera(o, m, r, &cam)) != 0 || (e = make_light(o, m, &l, env)) != 0)
                return e;
        n = (size_t)cam.width * cam.height;
        rgb = malloc(3 * n * sizeof(float));
        mask = malloc(n);
        if (!rgb || !mask)
                return EXIT_STORAGE;
        if ((e = ap_render(r, &cam, &l, o->mode, 2, rgb, mask)) < 0 ||
            (e = render_write_image(o->out, rgb, cam.width, cam.height, o->gain)) < 0) {
                fprintf(stderr, "gonioctl: model render: %s: %s\n", o->out, strerror(-e));
                return cmd_exit_for_errno(e);
        }
        for (size_t i = 0; i < n; i++)
                covered += mask[i];
        printf("rendered %s: %dx%d, %zu pixels of the object, view %g,%g (%s), mesh: %s\n", o->out,
               cam.width, cam.height, covered, o->az, o->el,
               o->mode == AP_VIEW_PIXEL ? "per pixel" : "per object", src);
        return EXIT_OK;
}

static int render_sh(const struct render_opts *o)
{
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        _cleanup_(ap_renderer_freep) struct ap_renderer *r = NULL;
        struct ap_mesh mesh = {0};
        char src[PATH_MAX + 64] = "";
        int e;

        if ((e = load(o, &m, &mesh, src, sizeof(src))))
                return e;
        if ((e = ap_renderer_new(m, &mesh, &r)) < 0) {
                fprintf(stderr, "gonioctl: model render: %s: cannot render: %s\n", o->model,
                        strerror(-e));
                ap_mesh_free(&mesh);
                return cmd_exit_for_errno(e);
        }
        e = render_to_file(o, m, r, src);
        ap_renderer_free(TAKE_PTR(r));
        ap_mesh_free(&mesh);
        return e;
}

/* The BRDF model of the folder when o asks for it (or, unless o says sh, under --envmap
 * when there is one of the texel kind; --light and --dir take the SH model unless asked): 1
 * with it in *ret, 0 for the SH model, or an exit code. */
static int want_brdf(const struct render_opts *o, struct ap_brdf_model **ret)
{
        char err[1024] = "";
        int r;

        if (o->reflectance == REFLECTANCE_SH ||
            (o->reflectance == REFLECTANCE_AUTO && o->kind != AP_LIGHT_ENV))
                return 0;
        r = ap_brdf_read(o->model, ret, err, sizeof(err));
        if (r == 0 && (*ret)->kind == AP_BRDF_KIND_VIEW && o->reflectance == REFLECTANCE_AUTO) {
                *ret = ap_brdf_model_free(*ret); /* no mesh: no environment lighting */
                return 0;
        }
        if (r == -ENOENT && o->reflectance == REFLECTANCE_AUTO)
                return 0;
        if (r < 0) {
                fprintf(stderr, "gonioctl: model render: %s: %s\n", o->model,
                        r == -ENOENT ? "no BRDF model there (gonioctl model fit --brdf)"
                        : err[0]     ? err
                                     : strerror(-r));
                return cmd_exit_for_errno(r == -ENOENT ? -EINVAL : r);
        }
        return 1;
}

int model_render_command(int argc, char **argv)
{
        struct ap_brdf_model *bm = NULL;
        struct render_opts o;
        int e;

        if ((e = parse_args(argc, argv, &o)) != 0)
                return e;
        if ((e = want_brdf(&o, &bm)) == 0)
                return render_sh(&o);
        if (e == 1) {
                e = model_render_brdf(&o, bm);
                ap_brdf_model_free(bm);
        }
        return e;
}
