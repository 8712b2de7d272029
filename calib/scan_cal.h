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

/* Fills out from the sections of camera and of each laser of rig rc in f: plane i from
 * lasers.<name of laser i>, or the rig's nominal plane (scan_nominal_calib) for a laser the
 * file has no section of (its bit set in out->nominal). Returns 0, or -ENOENT with the
 * missing section named in err ("no section turntables.c0: calibrate the turntable"; a
 * laser's when the file has none of the rig's lasers, or the rig no such camera or no laser)
 * or -EINVAL (a section of another image size than the camera's intrinsics, or a laser
 * calibrated through another camera). */
int scan_calib_from_file(const struct cal_file *f, const struct rig_config *rc, const char *camera,
                         struct scan_calib *out, char *err, size_t errlen);
