/* model_render.h - what the two renderers of gonioctl model render share: the parsed command
 * line, the output camera's placement and the image writer (client/model_render.c renders
 * the SH model, client/model_render_brdf.c the BRDF model). */
#pragma once

#include <stdbool.h>

#include "appearance/brdf.h"
#include "appearance/envmap.h"
#include "appearance/render.h"
#include "appearance/views.h"

enum render_reflectance {
        REFLECTANCE_AUTO, /* the BRDF model under --envmap when the folder has one, else SH */
        REFLECTANCE_SH,
        REFLECTANCE_BRDF,
};

struct render_opts {
        const char *model, *out, *envmap;
        enum ap_light_kind kind;
        enum render_reflectance reflectance;
        int n_lights;
        double light[3], az, el, distance, intensity, gain, focal, ground;
        bool have_view;
        enum ap_view_mode mode;
        int width, height, spheres, pairs;
};

/* The unit view direction of o's --view (azimuth, elevation) in the object frame into d. */
void render_view_dir(const struct render_opts *o, double d[3]);

/* The output camera: intr's intrinsics with its principal point centred, at distance dist
 * from centre c along o's view direction, looking at c. Returns 0 or EXIT_INVALID. */
int render_place_camera(const struct render_opts *o, const double c[3], double dist,
                        struct ap_camera intr, struct ap_camera *cam);

/* Whether o's --view is within MAX_OUTSIDE_DEG of the views vs cover: 0, or EXIT_INVALID
 * with the cause printed. */
int render_check_view(const struct render_opts *o, const struct ap_views *vs);

/* The output camera near a sampled view (near): its intrinsics (scaled to --size, or --focal)
 * at --distance (else near's distance from c) from centre c along o's view direction. Returns
 * 0 or EXIT_INVALID. */
int render_camera_near(const struct render_opts *o, const double c[3], const struct ap_camera *near,
                       struct ap_camera *cam);

/* Loads o's --envmap into e, saying why it cannot (EXIT_INVALID, EXIT_STORAGE) and noting a
 * map without HDR range on stderr. Returns 0 or the exit code. */
int render_load_envmap(const struct render_opts *o, struct ap_envmap *e);

/* Writes rgb (linear, 3 floats a pixel) times gain to path: a PFM (float) when path ends in
 * .pfm, else an 8-bit RGB PNG clamped to [0, 1]. Returns 0 or -errno. */
int render_write_image(const char *path, const float *rgb, int w, int h, double gain);

/* Renders BRDF model m under o's environment map or light (appearance/render_env.h; of the
 * view kind, appearance/brdf_render.h: not under an environment map) into o->out.
 * Returns an enum gonioctl_exit value, the cause printed to stderr. */
int model_render_brdf(const struct render_opts *o, const struct ap_brdf_model *m);
