/* scan_cal.c - a scan's calibration (and a camera's, for the lamps) from a calibration
 * file's sections (scan_cal.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "calib/scan_cal.h"

/* -ENOENT with what to calibrate first. */
static int missing(char *err, size_t errlen, const char *section, const char *name,
                   const char *what)
{
        snprintf(err, errlen, "no section %s.%s in the calibration file: run gonioctl calibrate %s",
                 section, name, what);
        return -ENOENT;
}

int scan_cal_camera(const struct cal_file *f, const char *camera, struct sec_camera *out, char *err,
                    size_t errlen)
{
        const struct cal_camera *c = cal_file_camera(f, camera);
        const struct cal_file_turntable *t = cal_file_turntable(f, camera);

        if (!c)
                return missing(err, errlen, "cameras", camera, "camera");
        if (!t)
                return missing(err, errlen, "turntables", camera, "turntable");
        *out = (struct sec_camera){.k = c->k, .width = c->width, .height = c->height};
        memcpy(out->R, t->tt.R, sizeof(out->R));
        memcpy(out->t, t->tt.t, sizeof(out->t));
        return 0;
}

/* Plane i of out from the section of laser `laser` in f, calibrated through camera. Returns
 * 0, -ENOENT (no section) or -EINVAL (another camera's), with err set. */
static int laser_plane(const struct cal_file *f, const char *camera, const char *laser, int i,
                       struct scan_calib *out, char *err, size_t errlen)
{
        const struct cal_file_laser *l = cal_file_laser(f, laser);

        if (!l)
                return missing(err, errlen, "lasers", laser, "laser");
        if (strcmp(l->camera, camera) != 0) {
                snprintf(err, errlen,
                         "laser %s was calibrated through camera %s, not %s: its plane "
                         "is in that camera's turntable frame",
                         laser, l->camera, camera);
                return -EINVAL;
        }
        for (int k = 0; k < 3; k++) { /* the plane n.x + d = 0 through p = -d n */
                out->plane_n[i][k] = l->plane.n[k];
                out->plane_p[i][k] = -l->plane.d * l->plane.n[k];
        }
        return 0;
}

int scan_calib_from_file(const struct cal_file *f, const struct rig_config *rc, const char *camera,
                         struct scan_calib *out, char *err, size_t errlen)
{
        struct sec_camera cam;
        int r = scan_cal_camera(f, camera, &cam, err, errlen), found = 0;

        if (r < 0)
                return r;
        if ((r = scan_nominal_calib(rc, camera, NAN, out)) < 0) {
                snprintf(err, errlen, "the rig has %s",
                         r == -ENOENT ? "no such camera" : "no laser");
                return r;
        }
        out->cam = cam;
        for (int i = 0; i < out->n_lasers; i++) {
                r = laser_plane(f, camera, rc->lasers[i].name, i, out, err, errlen);
                if (r == -EINVAL)
                        return r;
                found += r == 0;
                out->nominal |= (uint32_t)(r < 0) << i;
        }
        return found ? 0 : -ENOENT; /* err: the last laser's missing section */
}
