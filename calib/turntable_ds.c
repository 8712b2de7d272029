/* turntable_ds.c - the turntable and laser solves (turntable.h, laserplane.h) on a camera's
 * captures read through the dataset library: rows of kind "image", bracket 0; the turntable
 * angle from each row's pose; each laser-on row paired with the nearest laser-off row of the
 * same pose. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>

#include "calib/laserplane.h"
#include "calib/turntable.h"
#include "common/cleanup.h"

#define POSE_TOL_DEG 0.01 /* a laser-on and a laser-off row of one pose: angles this close */

/* A camera's image rows and, once loaded, their frames. */
struct rows {
        const char *camera;
        size_t n;
        struct ds_capture *c;
        struct gn_frame *f;
};

/* The camera's images (bracket 0) and laser frames (a session's have no bracket: -1). */
static bool keep_row(const struct ds_capture *c, void *userdata)
{
        const char *camera = userdata;

        return !strcmp(c->camera, camera) &&
               (!c->kind[0] || !strcmp(c->kind, "image") || !strcmp(c->kind, "laser")) &&
               c->bracket <= 0;
}

static void rows_free(struct rows *r)
{
        for (size_t i = 0; r->f && i < r->n; i++)
                gn_frame_free_data(&r->f[i]);
        free(r->f);
        free(r->c);
}

/* Reads the rows of camera r->camera and their images. */
static int rows_load(struct ds *d, struct rows *r, char *err, size_t errlen)
{
        int e = ds_rows_collect(d, keep_row, (void *)r->camera, &r->c, &r->n);

        if (e < 0) {
                snprintf(err, errlen, "cannot read dataset %s: %s", ds_name(d), ds_last_error(d));
                return e;
        }
        if (!r->n) {
                snprintf(err, errlen, "dataset %s has no images of camera %s", ds_name(d),
                         r->camera);
                return -ENOENT;
        }
        r->f = calloc(r->n, sizeof(*r->f));
        if (!r->f)
                return -ENOMEM;
        for (size_t i = 0; i < r->n; i++)
                if ((e = ds_load_image(d, r->c[i].file, &r->f[i])) < 0) {
                        snprintf(err, errlen, "cannot read %s: %s", r->c[i].file, strerror(-e));
                        return e;
                }
        return 0;
}

/* Loads r->camera's rows and images into r and room for one view (view_size bytes) per row
 * into *views. */
static int load_views(struct ds *d, struct rows *r, size_t view_size, void **views, char *err,
                      size_t errlen)
{
        int e;

        if (!r->camera)
                return -EINVAL;
        if ((e = rows_load(d, r, err, errlen)) < 0)
                return e;
        return (*views = calloc(r->n, view_size)) ? 0 : -ENOMEM;
}

static double angle_of(const struct ds_capture *c)
{
        double a = c->pose.deg[GN_ROLE_TURNTABLE];

        return isnan(a) ? 0 : a;
}

int cal_turntable_solve_ds(struct ds *d, const char *camera, const struct cal_tt_opts *o,
                           struct cal_turntable *out, char *err, size_t errlen)
{
        _cleanup_(rows_free) struct rows r = {.camera = camera};
        _cleanup_free_ struct cal_tt_view *v = NULL;
        size_t n = 0;
        int e;

        memset(out, 0, sizeof(*out));
        if ((e = load_views(d, &r, sizeof(*v), (void **)&v, err, errlen)) < 0)
                return e;
        for (size_t i = 0; i < r.n; i++) {
                const struct gn_frame *f = &r.f[i];
                if (r.c[i].pose.lasers)
                        continue;
                v[n++] = (struct cal_tt_view){
                        {f->data, f->width, f->height, f->channels, f->bits, f->stride},
                        angle_of(&r.c[i])};
        }
        return cal_turntable_solve(v, n, o, out, err, errlen);
}

/* True when rows a and b were taken at the same angles, and with the same lamps unless
 * any_light. */
static bool same_pose(const struct ds_capture *a, const struct ds_capture *b, bool any_light)
{
        for (int k = 0; k < GN_ROLE_COUNT; k++) {
                double x = a->pose.deg[k], y = b->pose.deg[k];
                if (isnan(x) != isnan(y) || (!isnan(x) && fabs(x - y) > POSE_TOL_DEG))
                        return false;
        }
        return any_light ? b->pose.lamps != 0 : a->pose.lamps == b->pose.lamps;
}

/* The laser-off row nearest to laser-on row i (the board may move between poses of one
 * turntable angle, never between a pose's frames) of the same pose, or with any_light of
 * the same angles and a lamp lit; -1 when none. */
static ssize_t partner(const struct rows *r, size_t i, bool any_light)
{
        for (size_t k = 1; k < r->n; k++) {
                if (k <= i && !r->c[i - k].pose.lasers &&
                    same_pose(&r->c[i], &r->c[i - k], any_light))
                        return i - k;
                if (i + k < r->n && !r->c[i + k].pose.lasers &&
                    same_pose(&r->c[i], &r->c[i + k], any_light))
                        return i + k;
        }
        return -1;
}

/* The view of laser row i: on minus its laser-off partner, or a dark laser frame alone with
 * the board from a lit frame of the same angles. Returns false when there is neither. */
static bool laser_view(const struct rows *r, size_t i, struct cal_lp_view *v)
{
        ssize_t j = partner(r, i, false);

        if (j >= 0) {
                *v = (struct cal_lp_view){.off = &r->f[j], .on = &r->f[i]};
                return true;
        }
        j = r->c[i].pose.lamps ? -1 : partner(r, i, true);
        if (j >= 0)
                *v = (struct cal_lp_view){.on = &r->f[i], .board = &r->f[j]};
        return j >= 0;
}

int cal_laser_solve_ds(struct ds *d, const char *camera, const struct cal_lp_opts *o,
                       struct cal_laser *out, char *err, size_t errlen)
{
        _cleanup_(rows_free) struct rows r = {.camera = camera};
        _cleanup_free_ struct cal_lp_view *v = NULL;
        size_t n = 0, on = 0;
        int e;

        memset(out, 0, sizeof(*out));
        if ((e = load_views(d, &r, sizeof(*v), (void **)&v, err, errlen)) < 0)
                return e;
        for (size_t i = 0; i < r.n; i++) {
                if (!r.c[i].pose.lasers || (o->lasers && r.c[i].pose.lasers != o->lasers))
                        continue;
                on++;
                n += laser_view(&r, i, &v[n]);
        }
        if (!n) {
                snprintf(err, errlen,
                         "none of the %zu images of camera %s has the laser on with a laser-off "
                         "image of the same pose (%zu with the laser on): capture each pose with "
                         "the laser off and on",
                         r.n, camera, on);
                return -ENODATA;
        }
        return cal_laser_solve(v, n, o, out, err, errlen);
}
