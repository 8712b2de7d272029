/* export_nerf.c - the dataset as nerfstudio's transforms.json (export.h, docs/exports.md):
 * per frame the image, its camera-to-world matrix in the OpenGL convention (x right, y up,
 * looking down -z; the object frame as the world, mm), its intrinsics and OpenCV distortion
 * and the lit lamp's position and intensity; the split by frame into train (8 in 10), val
 * and test (1 in 10 each) as nerfstudio's *_filenames keys and as transforms_<split>.json. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/export_internal.h"
#include "common/cleanup.h"
#include "common/fileio.h"

#define SPLIT_EVERY 10 /* frame j: test when j % 10 == 9, val when j % 10 == 4 */

static const char *const splits[] = {"train", "val", "test"};

static int split_of(size_t j)
{
        return j % SPLIT_EVERY == SPLIT_EVERY - 1 ? 2 : j % SPLIT_EVERY == SPLIT_EVERY / 2 - 1;
}

/* The OpenGL camera-to-world matrix of camera k (x_cam = R x + t, OpenCV axes). */
static json_t *c2w_json(const struct ap_camera *k)
{
        json_t *m = json_array();

        for (int r = 0; r < 4; r++) {
                json_t *row = json_array();
                for (int c = 0; c < 4 && r < 3; c++) {
                        /* columns 0..2: R^T with y and z flipped; column 3: -R^T t */
                        double v = c < 3 ? k->R[3 * c + r] * (c == 0 ? 1 : -1)
                                         : -(k->R[r] * k->t[0] + k->R[3 + r] * k->t[1] +
                                             k->R[6 + r] * k->t[2]);
                        json_array_append_new(row, json_real(v));
                }
                for (int c = 0; c < 4 && r == 3; c++)
                        json_array_append_new(row, json_real(c == 3));
                json_array_append_new(m, row);
        }
        return m;
}

/* Sets camera k's intrinsics and distortion on object o (pixel centres at +0.5). */
static void intrinsics(json_t *o, const struct ap_camera *k)
{
        json_object_set_new(o, "fl_x", json_real(k->fx));
        json_object_set_new(o, "fl_y", json_real(k->fy));
        json_object_set_new(o, "cx", json_real(k->cx + 0.5));
        json_object_set_new(o, "cy", json_real(k->cy + 0.5));
        json_object_set_new(o, "w", json_integer(k->width));
        json_object_set_new(o, "h", json_integer(k->height));
        json_object_set_new(o, "k1", json_real(k->dist[0]));
        json_object_set_new(o, "k2", json_real(k->dist[1]));
        json_object_set_new(o, "p1", json_real(k->dist[2]));
        json_object_set_new(o, "p2", json_real(k->dist[3]));
        json_object_set_new(o, "k3", json_real(k->dist[4]));
}

static json_t *frame_json(const struct ap_geometry *g, const struct ap_shot *s)
{
        char path[300];
        json_t *f = json_object();

        snprintf(path, sizeof(path), "images/%s", exp_image_name(s->row));
        json_object_set_new(f, "file_path", json_string(path));
        json_object_set_new(f, "transform_matrix", c2w_json(&g->cameras[s->view]));
        intrinsics(f, &g->cameras[s->view]);
        json_object_set_new(f, "camera", json_string(s->row->camera));
        json_object_set_new(f, "lamp", json_string(s->row->lamps));
        json_object_set_new(f, "light_position",
                            json_pack("[f,f,f]", s->lamp[0], s->lamp[1], s->lamp[2]));
        json_object_set_new(f, "light_intensity", json_real(s->intensity));
        json_object_set_new(f, "exposure_us", json_integer(s->row->exposure_us));
        return f;
}

/* The header shared by every transforms file: the model, the first camera's intrinsics. */
static json_t *header_json(const struct ap_geometry *g)
{
        json_t *t = json_object();

        json_object_set_new(t, "camera_model", json_string("OPENCV"));
        intrinsics(t, &g->cameras[g->shots[0].view]);
        json_object_set_new(t, "units", json_string("mm"));
        json_object_set_new(t, "frames", json_array());
        return t;
}

static int put_json(const char *dir, const char *name, json_t *t, char *err, size_t errlen)
{
        _cleanup_free_ char *text = json_dumps(t, JSON_INDENT(1) | JSON_REAL_PRECISION(17));
        char path[4300];
        int r;

        snprintf(path, sizeof(path), "%s/%s", dir, name);
        r = text ? gn_write_atomic(AT_FDCWD, path, text, strlen(text), NULL) : -ENOMEM;
        if (r < 0)
                snprintf(err, errlen, "cannot write %s: %s", path, strerror(-r));
        return r;
}

/* transforms.json (every frame, the split's file lists) and transforms_<split>.json. */
static int write_transforms(const struct ap_geometry *g, const char *dir, char *err, size_t errlen)
{
        _cleanup_(json_decrefp) json_t *all = header_json(g);
        json_t *part[3];
        int r = 0;

        for (int s = 0; s < 3; s++) {
                char key[32];
                part[s] = header_json(g);
                snprintf(key, sizeof(key), "%s_filenames", splits[s]);
                json_object_set_new(all, key, json_array());
        }
        for (size_t j = 0; j < g->n_shots; j++) {
                json_t *f = frame_json(g, &g->shots[j]);
                char key[32];
                snprintf(key, sizeof(key), "%s_filenames", splits[split_of(j)]);
                json_array_append(json_object_get(all, key), json_object_get(f, "file_path"));
                json_array_append(json_object_get(part[split_of(j)], "frames"), f);
                json_array_append_new(json_object_get(all, "frames"), f);
        }
        r = put_json(dir, "transforms.json", all, err, errlen);
        for (int s = 0; s < 3; s++) {
                char name[64];
                snprintf(name, sizeof(name), "transforms_%s.json", splits[s]);
                if (r == 0)
                        r = put_json(dir, name, part[s], err, errlen);
                json_decref(part[s]);
        }
        return r;
}

int ap_export_nerfstudio(struct ds *d, const char *ds_dir, const char *dir,
                         const struct ap_export_opts *o, char *err, size_t errlen)
{
        _cleanup_(ap_geometry_freep) struct ap_geometry *g = NULL;
        int r = exp_geometry(d, o, &g, err, errlen);

        if (r == 0)
                r = write_transforms(g, dir, err, errlen);
        if (r == 0)
                r = exp_link_images(g, ds_dir, dir, err, errlen);
        return r;
}
