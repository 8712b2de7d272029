/* calibrate.h - gonioctl calibrate camera|turntable|laser: the solves of calib/ on a
 * dataset's calibration captures, their summaries and the calibration file they are written
 * into (docs/calibration.md, docs/gonioctl.md). */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* gonioctl calibrate camera --from DATASET --board SPEC [--camera NAME] [--calibration FILE]
 * [--force]: solves the camera's intrinsics from the dataset's board views, writes them into
 * the calibration file (DATASET/calibration.yaml unless --calibration; never over a better
 * result unless --force) and returns the summary in *ret. Returns an enum gonioctl_exit
 * value; on failure the cause is printed with out_error. */
int calibrate_camera(const struct args *a, struct out *o, json_t **ret);

/* gonioctl calibrate turntable: as calibrate_camera, the turntable axis and the camera's pose
 * (calib/turntable.h) from the board on the turntable at several angles; the camera's
 * intrinsics come from the calibration file's cameras section (exit 6 without). */
int calibrate_turntable(const struct args *a, struct out *o, json_t **ret);

/* gonioctl calibrate laser [--laser NAME]: as calibrate_turntable, the laser plane
 * (calib/laserplane.h) from laser-on/off pairs of the board, written in the turntable frame:
 * the file must hold the camera's turntable section (exit 6 without). */
int calibrate_laser(const struct args *a, struct out *o, json_t **ret);

/* Print the summaries of the commands above for people. */
void calibrate_print_camera(json_t *result);
void calibrate_print_turntable(json_t *result);
void calibrate_print_laser(json_t *result);
