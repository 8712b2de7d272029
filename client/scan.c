/* scan.c - gonioctl scan --from DATASET: a dataset's laser captures reconstructed offline
 * (calib/scan.h) with its rig file's nominal calibration, the summary as text or JSON
 * (docs/scanning.md, "gonioctl scan --from"). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "calib/scan.h"
#ifdef GONIOCTL_CALIB
#include "calib/scan_cal.h"
#endif
#include "client/cmd.h"
#include "client/scan.h"
#include "client/scan_capture.h"
#include "common/cleanup.h"
#include "dataset/ds.h"
#include "drivers/registry.h"

#define WHAT "scan"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);

/* The calibration to triangulate with: the sections of the calibration file (--calibration,
 * else the dataset's calibration.yaml) for the camera and the rig's laser, or NULL (the rig
 * file's nominal geometry) when the dataset has no calibration file or with --calibration
 * nominal. How it was chosen goes to
 * *source. Returns 0, or EXIT_INVALID after printing why a file given or found cannot serve. */
static int pick_calib(const struct args *a, struct out *o, struct ds *d,
                      const struct rig_config *rc, struct scan_calib *cal,
                      const struct scan_calib **use, const char **source)
{
#ifdef GONIOCTL_CALIB
        _cleanup_free_ struct cal_file *f = calloc(1, sizeof(*f));
        const char *camera = a->camera;
        char path[4096], err[1024] = "";
        int r;

        snprintf(path, sizeof(path), "%s/calibration.yaml", ds_path(d));
        if (a->calib)
                snprintf(path, sizeof(path), "%s", a->calib);
        *use = NULL;
        *source = "nominal: the rig file's geometry (no calibration file)";
        if (a->calib && strcmp(a->calib, "nominal") == 0) {
                *source = "nominal: the rig file's geometry (--calibration nominal)";
                return 0;
        }
        if (!f)
                return EXIT_PROTOCOL;
        r = cal_file_read(path, f, err, sizeof(err));
        if (r == -ENOENT && !a->calib)
                return 0;
        for (size_t i = 0; r >= 0 && !camera && i < rc->n_cameras; i++)
                if (cal_file_turntable(f, rc->cameras[i].name))
                        camera = rc->cameras[i].name;
        if (r >= 0)
                r = scan_calib_from_file(f, rc, camera ?: rc->cameras[0].name, cal, err,
                                         sizeof(err));
        if (r < 0) {
                out_error(o, WHAT, "calibration %s: %s", path, *err ? err : strerror(-r));
                return EXIT_INVALID;
        }
        *use = cal;
        *source = a->calib ? a->calib : "calibration.yaml";
#else
        *use = NULL;
        *source = "nominal: the rig file's geometry (gonioctl built without OpenCV)";
#endif
        return 0;
}

/* Each laser's points, and how well the lasers agree (null with fewer than two). */
static json_t *lasers_json(const struct scan_result *s, const struct rig_config *rc,
                           const struct scan_calib *cal)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < rc->n_lasers && i < SEC_MAX_LASERS; i++)
                json_array_append_new(
                        a, json_pack("{s:s,s:I,s:o,s:b}", "name", rc->lasers[i].name, "points",
                                     (json_int_t)s->laser_points[i], "offset_mm",
                                     isnan(s->agree_rms_mm) ? json_null()
                                                            : json_real(s->agree_offset_mm[i]),
                                     "nominal", !cal || (cal->nominal >> i & 1)));
        return json_pack("{s:o,s:o,s:I}", "each", a, "agree_rms_mm",
                         isnan(s->agree_rms_mm) ? json_null() : json_real(s->agree_rms_mm),
                         "agree_pairs", (json_int_t)s->agree_pairs);
}

static json_t *summary_json(const struct scan_result *s, const struct scan_opts *o, const char *dir)
{
        json_t *rows = json_pack(
                "{s:I,s:I,s:I,s:I,s:I,s:I,s:{s:I,s:I,s:I,s:I}}", "laser", (json_int_t)s->laser_rows,
                "used", (json_int_t)s->used, "paired", (json_int_t)s->paired, "alone",
                (json_int_t)(s->used - s->paired), "textured", (json_int_t)s->textured, "no_line",
                (json_int_t)s->no_line, "skipped", "unreadable", (json_int_t)s->unreadable,
                "wrong_size", (json_int_t)s->wrong_size, "other_view", (json_int_t)s->other_view,
                "shared", (json_int_t)s->shared);

        return json_pack("{s:s,s:s,s:I,s:I,s:I,s:I,s:I,s:I,s:f,s:I,s:b,s:o,s:f,s:[sss]}", "dataset",
                         dir, "camera", s->camera, "points", (json_int_t)s->points, "rejected",
                         (json_int_t)s->rejected, "unvouched", (json_int_t)s->unvouched,
                         "triangles", (json_int_t)s->triangles, "triangles_simplified",
                         (json_int_t)s->triangles_simplified, "target", (json_int_t)o->triangles,
                         "error_mm", s->error_mm, "folds", (json_int_t)s->folds, "seam_closed",
                         s->seams_closed > 0, "rows", rows, "seconds", s->seconds, "files",
                         SCAN_FILE_POINTS, SCAN_FILE_MESH_PLY, SCAN_FILE_MESH_OBJ);
}

int scan_reconstruct(const struct args *a, struct out *o, json_t **ret)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        struct scan_opts opts;
        struct scan_result res;
        struct scan_calib cal;
        const struct scan_calib *use;
        const char *source;
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
        if ((r = pick_calib(a, o, d, rc, &cal, &use, &source)) != 0)
                return r;
        if ((r = scan_dataset(d, rc, &opts, use, &res, err, sizeof(err))) < 0) {
                out_error(o, WHAT, "%s", err);
                return cmd_exit_for_errno(r);
        }
        *ret = summary_json(&res, &opts, ds_path(d));
        if (*ret) {
                json_object_set_new(*ret, "calibration", json_string(source));
                json_object_set_new(*ret, "lasers", lasers_json(&res, rc, use));
        }
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

static json_int_t num(json_t *o, const char *key)
{
        return json_integer_value(json_object_get(o, key));
}

/* Each laser's points, and the lasers' agreement when there are two or more. */
static void print_lasers(json_t *lasers)
{
        json_t *each = json_object_get(lasers, "each"), *l;
        json_t *rms = json_object_get(lasers, "agree_rms_mm");
        size_t i;

        json_array_foreach(each, i, l)
                printf("  laser %s: %lld points%s\n", json_string_value(json_object_get(l, "name")),
                       num(l, "points"),
                       json_is_true(json_object_get(l, "nominal")) ? " (nominal plane)" : "");
        if (json_is_number(rms))
                printf("  lasers agree: %.3f mm RMS between their surfaces (%lld points "
                       "matched)\n",
                       json_number_value(rms), num(lasers, "agree_pairs"));
        else if (json_array_size(each) > 1)
                printf("  lasers agree: not measured (their surfaces do not overlap)\n");
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
               "angle, %lld with lasers lit together\n",
               num(skip, "unreadable"), num(skip, "wrong_size"), num(skip, "other_view"),
               num(skip, "shared"));
        printf("  centres left out: %lld at a line's ends or steps, %lld without a usable ray\n",
               num(res, "unvouched"), num(res, "rejected"));
        print_lasers(json_object_get(res, "lasers"));
        printf("  mesh: %lld triangles over the grid%s, %lld after simplification (target %lld, "
               "error %.3f mm, %lld folds dropped)\n",
               num(res, "triangles"),
               json_is_true(json_object_get(res, "seam_closed")) ? " (closed round the turn)" : "",
               num(res, "triangles_simplified"), num(res, "target"),
               json_real_value(json_object_get(res, "error_mm")), num(res, "folds"));
        printf("  calibration: %s\n", json_string_value(json_object_get(res, "calibration")));
        printf("  %.1f s\n", json_real_value(json_object_get(res, "seconds")));
        json_array_foreach(json_object_get(res, "files"), i, f)
                printf("written to %s/%s\n", dir, json_string_value(f));
}

int scan_command(const struct args *a, struct out *o, json_t **ret)
{
        struct args rebuild = *a;
        json_t *capture = NULL, *scan = NULL;
        int r;

        if (a->nwords < 2)
                return scan_reconstruct(a, o, ret);
        if (a->from) {
                args_usage_error(WHAT, "--from DIR rebuilds a dataset's scan: give no DATASET "
                                       "(the capture's first angle is --start)");
                return EXIT_USAGE;
        }
        if ((r = scan_capture(a, o, &capture)) != EXIT_OK)
                return r;
        if (a->given & ARG_NO_MESH) {
                *ret = capture;
                return EXIT_OK;
        }
        rebuild.from = json_string_value(json_object_get(capture, "path"));
        rebuild.given |= ARG_FORCE; /* the capture's rows are new: its old scan files are not */
        r = scan_reconstruct(&rebuild, o, &scan);
        if (r != EXIT_OK)
                out_error(o, WHAT,
                          "the capture is stored in %s: rebuild with gonioctl scan --from %s",
                          a->words[1], rebuild.from ?: "DIR");
        *ret = json_pack("{s:o,s:o*}", "capture", capture, "scan", scan);
        return r;
}

void scan_command_print(json_t *result)
{
        json_t *capture = json_object_get(result, "capture");

        if (!capture)
                return scan_print(result);
        scan_capture_print(capture);
        scan_print(json_object_get(result, "scan"));
}
