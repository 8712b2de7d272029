/* webexport.h - the appearance model as a static web folder: one page (WebGL2) that relights
 * the object on its mesh for a point light the user drags, a directional light or an
 * environment map, from any view, in the per-pixel and per-object view modes of render.h,
 * computing what ap_render computes; where the model folder also holds a BRDF model (brdf.h),
 * its environment mode can shade with it instead, computing what ap_env_render computes
 * (render_env.h) for the scene ap_web_env_scene makes. Works offline: every file is in the folder,
 * the data in script files (base64 of gzip) so that the page also runs from file://.
 * docs/viewer.md. */
#pragma once

#include <stddef.h>

#include "appearance/render_env.h"

struct rig_backend;

#define AP_WEB_FORMAT "gonio-web 1"

/* One file of the page, built into the program (webassets.c, from appearance/web/). */
struct ap_web_asset {
        const char *name;
        const unsigned char *data;
        size_t len;
};

/* The page's own files; a NULL name ends the list. */
extern const struct ap_web_asset ap_web_assets[];

struct ap_web_opts {
        const char *const *envmaps; /* lat-long maps (envmap.h) for the environment mode,
                                     * NULL-terminated; NULL or empty: a built-in sky */
        const struct rig_backend *const *backends; /* to find the mesh (mesh.h) */
        int spheres; /* the BRDF model's sphere set (1..AP_SPHERES_MAX); 0: AP_ENV_SPHERES */
};

#define AP_WEB_PF_WIDTH      48   /* and its maps' width (model render: 96; here the page's data) */
#define AP_WEB_ENV_MAX_WIDTH 1024 /* wider maps are halved (box) for the page's background */

/* The sphere set of the BRDF model m's shadows, n spheres (ap_spheres_fit on its atlas mesh).
 * Returns as ap_spheres_fit. */
int ap_web_spheres(const struct ap_brdf_model *m, int n, struct ap_spheres *out);

/* The scene the page shows the BRDF model m in under env: env prefiltered into *pf (free with
 * ap_prefilter_free) with ap_brdf_prefilter_params, AP_ENV_PAIRS and AP_WEB_PF_WIDTH; sp's
 * shadows; a ground disc as gonioctl model render's (AP_WEB_GROUND_*: none when the mesh does
 * not stand on z = 0); the model's response as the scale. sc borrows m, env, pf and sp. Returns
 * as ap_prefilter_build. */
int ap_web_env_scene(const struct ap_brdf_model *m, const struct ap_envmap *env,
                     const struct ap_spheres *sp, struct ap_prefilter *pf, struct ap_env_scene *sc);

/* Writes the viewer of the model in model_dir (DATASET/models/NAME) on its dataset's mesh
 * into out_dir, which must not exist or be empty (written into a temporary folder, then
 * renamed). Returns 0, -ENOENT (no model, no mesh), -EBADMSG (a malformed model), -EEXIST
 * (out_dir not empty) or -errno, with a sentence in err. */
int ap_web_export(const char *model_dir, const char *out_dir, const struct ap_web_opts *o,
                  char *err, size_t errlen);
