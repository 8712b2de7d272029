/* calibrate.c - gonioctl calibrate camera --from DATASET: the offline solve of a camera's
 * intrinsics (calib/camera.h) from a dataset's board views, its summary, and the dataset's
 * calibration.yaml (docs/calibration.md). Built with calib/ only where OpenCV is. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "client/calibrate.h"
#include "client/cmd.h"
#include "common/cleanup.h"

#define WHAT "calibrate camera"

#ifdef GONIOCTL_CALIB
#include "calib/camera.h"
#include "dataset/ds.h"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);

static json_t *summary_json(const struct cal_camera *c, const char *file)
{
        json_t *rej = json_array(), *r;

        for (size_t i = 0; rej && i < c->n_views; i++)
                if (!c->views[i].used)
                        json_array_append_new(rej,
                                              json_pack("{s:s,s:s,s:o?}", "file", c->views[i].file,
                                                        "reason", c->views[i].reason, "rms_px",
                                                        isnan(c->views[i].rms)
                                                                ? NULL
                                                                : json_real(c->views[i].rms)));
        r = json_pack("{s:s,s:i,s:i,s:f,s:f,s:f,s:f,s:[fffff],s:[ffff],s:f,s:i,s:i,s:o,s:s}",
                      "camera", c->camera, "width", c->width, "height", c->height, "fx", c->k.fx,
                      "fy", c->k.fy, "cx", c->k.cx, "cy", c->k.cy, "dist", c->k.dist[0],
                      c->k.dist[1], c->k.dist[2], c->k.dist[3], c->k.dist[4], "std_px", c->std[0],
                      c->std[1], c->std[2], c->std[3], "rms_px", c->rms, "views_used",
                      (int)c->n_used, "views_rejected", (int)(c->n_views - c->n_used), "rejected",
                      rej, "file", file);
        return r;
}

/* The exit code of a failed solve or write. */
static int exit_for(int r)
{
        return r == -ENODATA || r == -ENOENT || r == -EINVAL || r == -EEXIST || r == -EBADMSG
                       ? EXIT_INVALID
                       : EXIT_STORAGE;
}

int calibrate_camera(const struct args *a, struct out *o, json_t **ret)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        struct cal_camera_opts opts = {.camera = a->camera};
        struct cal_camera c = {0};
        char err[1024], file[4096];
        int r;

        if (!a->from || !a->board || cal_board_parse(a->board, &opts.board) < 0) {
                args_usage_error(WHAT, "needs --from DATASET and --board chessboard:XxY:SQUARE "
                                       "or charuco:XxY:SQUARE:MARKER (squares, mm)");
                return EXIT_USAGE;
        }
        r = ds_open(a->from, &d);
        if (r < 0) {
                out_error(o, WHAT, "cannot open dataset %s: %s", a->from, strerror(-r));
                return EXIT_INVALID;
        }
        r = cal_camera_solve(d, &opts, &c, err, sizeof(err));
        snprintf(file, sizeof(file), "%s/calibration.yaml", ds_path(d));
        if (r >= 0)
                r = cal_camera_write(file, &c, a->given & ARG_FORCE, err, sizeof(err));
        if (r >= 0)
                *ret = summary_json(&c, file);
        cal_camera_clear(&c);
        if (r < 0) {
                out_error(o, WHAT, "%s", err);
                return exit_for(r);
        }
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}
#else
int calibrate_camera(const struct args *a, struct out *o, json_t **ret)
{
        out_error(o, WHAT, "gonioctl was built without OpenCV (-Dopencv=disabled)");
        return EXIT_INVALID;
}
#endif

void calibrate_print_camera(json_t *res)
{
        json_t *rej = json_object_get(res, "rejected"), *v;
        size_t i;

        printf("camera %s: %lldx%lld, %lld views used, %lld rejected\n",
               json_string_value(json_object_get(res, "camera")),
               json_integer_value(json_object_get(res, "width")),
               json_integer_value(json_object_get(res, "height")),
               json_integer_value(json_object_get(res, "views_used")),
               json_integer_value(json_object_get(res, "views_rejected")));
        printf("  fx %.3f  fy %.3f  cx %.3f  cy %.3f px\n",
               json_real_value(json_object_get(res, "fx")),
               json_real_value(json_object_get(res, "fy")),
               json_real_value(json_object_get(res, "cx")),
               json_real_value(json_object_get(res, "cy")));
        printf("  dist k1 k2 p1 p2 k3:");
        json_array_foreach(json_object_get(res, "dist"), i, v) printf(" %.5g", json_real_value(v));
        printf("\n  reprojection RMS %.3f px\n", json_real_value(json_object_get(res, "rms_px")));
        json_array_foreach(rej, i, v)
                printf("  rejected %s: %s\n", json_string_value(json_object_get(v, "file")),
                       json_string_value(json_object_get(v, "reason")));
        printf("written to %s\n", json_string_value(json_object_get(res, "file")));
}
