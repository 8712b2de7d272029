/* calibrate.h - gonioctl calibrate camera|turntable|laser|lamps: the solves of calib/ on a
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

/* gonioctl calibrate lamps --sphere DIAMETER [--from DATASET] [--lamp-radius MM]: the lamps'
 * positions (calib/lamps.h) from a mirror sphere on the turntable seen by every camera of the
 * dataset, each with each lamp lit alone; the cameras' intrinsics and poses from the file
 * (exit 6 naming the missing section). Each solved lamp is written as lamps.<lamp> (over a
 * nominal one, else never over a better one unless --force); when a lamp fails, the summary
 * of the others is printed, then why (exit 6). With --nominal (RIG-FILE or --from DATASET):
 * each lamp's position of the rig file, written with no observations, not over a measured
 * one unless --force. */
int calibrate_lamps(const struct args *a, struct out *o, json_t **ret);

/* Print the summaries of the commands above for people. */
void calibrate_print_camera(json_t *result);
void calibrate_print_turntable(json_t *result);
void calibrate_print_laser(json_t *result);
void calibrate_print_lamps(json_t *result);
