/* web_internal.h - what export_web.c (the page, the SH model's data) and export_web_brdf.c
 * (the BRDF model's environment mode) share. Private to appearance/. */
#pragma once

#include <jansson.h>
#include <stddef.h>

#include "appearance/brdf.h"
#include "appearance/envmap.h"
#include "appearance/mesh.h"
#include "appearance/model.h"
#include "appearance/spheres.h"
#include "appearance/views.h"
#include "appearance/webexport.h"

struct web {
        const struct ap_web_opts *o;
        struct ap_model *m;
        struct ap_mesh mesh;
        struct ap_views *views;
        struct ap_brdf_model *brdf; /* NULL: the model folder holds none */
        struct ap_spheres sp;       /* the BRDF model's sphere set */
        json_t *brdf_man;           /* the manifest's "brdf" object (borrowed from it) */
        const char *dir;            /* the temporary folder being filled */
        char *err;
        size_t errlen;
};

/* Writes "what: strerror(-r)" into w's error buffer. Returns r. */
int web_fail(struct web *w, int r, const char *what);

/* Writes data/NAME.js (gonio.chunk("NAME", "base64 of gzip(data)")) and names it in entry
 * ("chunk", "bytes", "raw_bytes"). Returns 0 or -errno with the sentence in w. */
int web_write_chunk(struct web *w, const char *name, const void *data, size_t len, json_t *entry);

/* Reads the BRDF model beside the SH model in model_dir, if any, into w->brdf (a view-kind
 * model, which has no mesh, counts as none). Returns 0 (none is fine) or -EBADMSG / -errno
 * with a sentence in w. */
int web_brdf_load(struct web *w, const char *model_dir);

/* Writes the BRDF model's mesh, texels and sphere set, and the manifest's "brdf" object into
 * man. Nothing without a BRDF model. Returns 0 or -errno with a sentence in w. */
int web_brdf_write(struct web *w, json_t *man);

/* Writes environment map i's data for the BRDF model (prefilter, visibility, the map). Nothing
 * without a BRDF model. Returns 0 or -errno with a sentence in w. */
int web_brdf_env(struct web *w, size_t i, const char *name, const struct ap_envmap *env);

/* Frees what web_brdf_load and web_brdf_write made. */
void web_brdf_free(struct web *w);
