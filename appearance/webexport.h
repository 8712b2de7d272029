/* webexport.h - the appearance model as a static web folder: one page (WebGL2) that relights
 * the object on its mesh for a point light the user drags, a directional light or an
 * environment map, from any view, in the per-pixel and per-object view modes of render.h,
 * computing what ap_render computes. Works offline: every file is in the folder, the data in
 * script files (base64 of gzip) so that the page also runs from file://. docs/viewer.md. */
#pragma once

#include <stddef.h>

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
};

/* Writes the viewer of the model in model_dir (DATASET/models/NAME) on its dataset's mesh
 * into out_dir, which must not exist or be empty (written into a temporary folder, then
 * renamed). Returns 0, -ENOENT (no model, no mesh), -EBADMSG (a malformed model), -EEXIST
 * (out_dir not empty) or -errno, with a sentence in err. */
int ap_web_export(const char *model_dir, const char *out_dir, const struct ap_web_opts *o,
                  char *err, size_t errlen);
