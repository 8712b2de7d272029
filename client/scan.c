/* scan.c - gonioctl scan --from DATASET: a dataset's laser captures reconstructed offline
 * (calib/scan.h) with its rig file's nominal calibration, the summary as text or JSON
 * (docs/scanning.md, "gonioctl scan --from"). */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "calib/scan.h"
#include "client/cmd.h"
#include "client/scan.h"
#include "common/cleanup.h"
#include "dataset/ds.h"
#include "drivers/registry.h"

#define WHAT "scan"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);

static json_t *summary_json(const struct scan_result *s, const struct scan_opts *o, const char *dir)
{
        json_t *rows = json_pack(
                "{s:I,s:I,s:I,s:I,s:I,s:I,s:{s:I,s:I,s:I}}", "laser", (json_int_t)s->laser_rows,
                "used", (json_int_t)s->used, "paired", (json_int_t)s->paired, "alone",
                (json_int_t)(s->used - s->paired), "textured", (json_int_t)s->textured, "no_line",
                (json_int_t)s->no_line, "skipped", "unreadable", (json_int_t)s->unreadable,
                "wrong_size", (json_int_t)s->wrong_size, "other_view", (json_int_t)s->other_view);

        return json_pack("{s:s,s:s,s:I,s:I,s:I,s:I,s:I,s:f,s:I,s:b,s:o,s:f,s:[sss]}", "dataset",
                         dir, "camera", s->camera, "points", (json_int_t)s->points, "rejected",
                         (json_int_t)s->rejected, "triangles", (json_int_t)s->triangles,
                         "triangles_simplified", (json_int_t)s->triangles_simplified, "target",
                         (json_int_t)o->triangles, "error_mm", s->error_mm, "folds",
                         (json_int_t)s->folds, "seam_closed", s->seams_closed > 0, "rows", rows,
                         "seconds", s->seconds, "files", SCAN_FILE_POINTS, SCAN_FILE_MESH_PLY,
                         SCAN_FILE_MESH_OBJ);
}

/* The exit code of a failed reconstruction. */
static int exit_for(int r)
{
        return r == -ENODATA || r == -ENOENT || r == -EINVAL || r == -EEXIST || r == -EBADMSG
                       ? EXIT_INVALID
                       : EXIT_STORAGE;
}

int scan_reconstruct(const struct args *a, struct out *o, json_t **ret)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        struct scan_opts opts;
        struct scan_result res;
        char err[1024];
        int r;

        if (!a->from) {
                args_usage_error(WHAT, "needs --from DATASET (the reconstruction of a dataset)");
                return EXIT_USAGE;
        }
        scan_opts_default(&opts);
        opts.camera = a->camera;
        opts.force = a->given & ARG_FORCE;
        if (a->given & ARG_TRIANGLES)
                opts.triangles = (size_t)a->triangles;
        if ((r = ds_open(a->from, &d)) < 0) {
                out_error(o, WHAT, "cannot open dataset %s: %s", a->from, strerror(-r));
                return EXIT_INVALID;
        }
        if ((r = scan_load_rig(d, registry_backends, &rc, err, sizeof(err))) < 0) {
                out_error(o, WHAT, "cannot read the rig file of dataset %s: %s", a->from, err);
                return EXIT_INVALID;
        }
        if ((r = scan_dataset(d, rc, &opts, NULL, &res, err, sizeof(err))) < 0) {
                out_error(o, WHAT, "%s", err);
                return exit_for(r);
        }
        *ret = summary_json(&res, &opts, ds_path(d));
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

static json_int_t num(json_t *o, const char *key)
{
        return json_integer_value(json_object_get(o, key));
}

void scan_print(json_t *res)
{
        json_t *rows = json_object_get(res, "rows"), *skip = json_object_get(rows, "skipped"), *f;
        const char *dir = json_string_value(json_object_get(res, "dataset"));
        size_t i;

        printf("scan of camera %s: %lld points from %lld of %lld laser frames\n",
               json_string_value(json_object_get(res, "camera")), num(res, "points"),
               num(rows, "used"), num(rows, "laser"));
        printf("  %lld on minus off, %lld alone; %lld coloured from a lamp frame; %lld without a "
               "line\n",
               num(rows, "paired"), num(rows, "alone"), num(rows, "textured"),
               num(rows, "no_line"));
        printf("  skipped: %lld unreadable, %lld of another size, %lld at another camera-arm "
               "angle\n",
               num(skip, "unreadable"), num(skip, "wrong_size"), num(skip, "other_view"));
        printf("  mesh: %lld triangles over the grid%s, %lld after simplification (target %lld, "
               "error %.3f mm, %lld folds dropped)\n",
               num(res, "triangles"),
               json_is_true(json_object_get(res, "seam_closed")) ? " (closed round the turn)" : "",
               num(res, "triangles_simplified"), num(res, "target"),
               json_real_value(json_object_get(res, "error_mm")), num(res, "folds"));
        printf("  %.1f s\n", json_real_value(json_object_get(res, "seconds")));
        json_array_foreach(json_object_get(res, "files"), i, f)
                printf("written to %s/%s\n", dir, json_string_value(f));
}
