/* camera_file.c - the cameras.<camera> sections of the calibration file (calfile.h,
 * docs/calibration.md): a camera's intrinsics with their error figures and the views left
 * out, never replacing a better section by a worse one unless forced (camera.h). */
#include <errno.h>
#include <libfyaml.h>
#include <stdio.h>
#include <string.h>

#include "calib/calfile.h"
#include "common/cleanup.h"

/* The camera's section (calfile.h, cal_emit_fn). */
static void camera_yaml(FILE *f, const void *obj)
{
        const struct cal_camera *c = obj;

        fprintf(f, "solved: %s\n", c->solved);
        cal_yaml_str(f, "dataset", c->dataset);
        cal_yaml_board(f, &c->board);
        fprintf(f, "width: %d\nheight: %d\n", c->width, c->height);
        fprintf(f, "fx: %.10g\nfy: %.10g\ncx: %.10g\ncy: %.10g\n", c->k.fx, c->k.fy, c->k.cx,
                c->k.cy);
        fprintf(f, "dist: [%.9g, %.9g, %.9g, %.9g, %.9g]\n", c->k.dist[0], c->k.dist[1],
                c->k.dist[2], c->k.dist[3], c->k.dist[4]);
        fprintf(f, "std_px: [%.4g, %.4g, %.4g, %.4g]\n", c->std[0], c->std[1], c->std[2],
                c->std[3]);
        fprintf(f, "rms_px: %.4f\nviews_used: %zu\nviews_rejected: %zu\n", c->rms, c->n_used,
                c->n_views - c->n_used);
        if (c->n_used < c->n_views)
                fprintf(f, "rejected:\n");
        for (size_t i = 0; i < c->n_views; i++) {
                if (c->views[i].used)
                        continue;
                fprintf(f, "  - ");
                cal_yaml_str(f, "file", c->views[i].file);
                fprintf(f, "    ");
                cal_yaml_str(f, "reason", c->views[i].reason);
        }
}

int cal_camera_write(const char *path, const struct cal_camera *c, bool force, char *err,
                     size_t errlen)
{
        char what[DS_NAME_MAX + 8];

        snprintf(what, sizeof(what), "camera %s", c->camera);
        return cal_file_put(path,
                            &(struct cal_section){"cameras", c->camera, what, "rms_px", "px",
                                                  c->rms, "views_used", "views", (long)c->n_used},
                            camera_yaml, c, force, err, errlen);
}

int cal_camera_from_yaml(struct yconf *yc, struct fy_node *m, const char *name,
                         struct cal_camera *out)
{
        static const char *const keys[] = {"fx", "fy", "cx", "cy", "rms_px"};
        double *const v[] = {&out->k.fx, &out->k.fy, &out->k.cx, &out->k.cy, &out->rms};
        long w = 0, h = 0, used = 0, rejected = 0;
        int r;

        snprintf(out->camera, sizeof(out->camera), "%s", name);
        if ((r = yconf_str(yc, m, "solved", out->solved, sizeof(out->solved))) < 0 ||
            (r = yconf_str(yc, m, "dataset", out->dataset, sizeof(out->dataset))) < 0 ||
            (r = cal_yaml_read_board(yc, m, &out->board)) < 0 ||
            (r = cal_yaml_numbers(yc, m, keys, v, ELEMENTSOF(keys))) < 0 ||
            (r = yconf_doubles(yc, m, "dist", out->k.dist, 5, 5, NULL)) < 0 ||
            (r = yconf_doubles(yc, m, "std_px", out->std, 4, 4, NULL)) < 0 ||
            (r = yconf_int(yc, m, "width", 0, 1 << 20, &w)) < 0 ||
            (r = yconf_int(yc, m, "height", 0, 1 << 20, &h)) < 0 ||
            (r = yconf_int(yc, m, "views_used", 0, 1L << 30, &used)) < 0 ||
            (r = yconf_int(yc, m, "views_rejected", 0, 1L << 30, &rejected)) < 0)
                return r;
        out->width = (int)w;
        out->height = (int)h;
        out->n_used = (size_t)used;
        out->n_views = (size_t)(used + rejected);
        return 0;
}

int cal_camera_read(const char *path, const char *name, struct cal_camera *out, char *err,
                    size_t errlen)
{
        _cleanup_(cal_file_closep) struct yconf yc = {0};
        struct fy_node *m;
        int r;

        memset(out, 0, sizeof(*out));
        r = cal_file_open(&yc, path, false, err, errlen);
        if (r < 0)
                return r;
        m = yconf_get(yconf_get(yconf_root(&yc), "cameras"), name);
        if (!m) {
                snprintf(err, errlen, "%s: no calibration of camera %s", path, name);
                return -ENOENT;
        }
        return cal_camera_from_yaml(&yc, m, name, out) < 0 ? -EBADMSG : 0;
}
