/* scan_cal.h - the calibration a scan triangulates with (calib/scan.h), taken from a
 * calibration file (calib/calfile.h): the camera's intrinsics (cameras.<camera>), its pose in
 * the turntable frame (turntables.<camera>) and the laser's plane in that frame
 * (lasers.<laser>). Only where OpenCV is (calfile.h needs it). docs/scanning.md. */
#pragma once

#include <stddef.h>

#include "calib/calfile.h"
#include "calib/scan.h"

/* Fills out with camera's intrinsics and pose in the turntable frame from f (for a scan, the
 * lamps' solve). Returns 0, or -ENOENT with the missing section named in err ("no section
 * cameras.c0 ...: run gonioctl calibrate camera"). */
int scan_cal_camera(const struct cal_file *f, const char *camera, struct sec_camera *out, char *err,
                    size_t errlen);

/* Fills out from the sections of camera and laser in f. Returns 0, or -ENOENT with the
 * missing section named in err ("no section turntables.c0: calibrate the turntable") or
 * -EINVAL (a section of another image size than the camera's intrinsics). */
int scan_calib_from_file(const struct cal_file *f, const char *camera, const char *laser,
                         struct scan_calib *out, char *err, size_t errlen);
