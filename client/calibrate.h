/* calibrate.h - gonioctl calibrate: offline solves of a dataset's calibration captures
 * (calib/), without goniod. */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* gonioctl calibrate camera --from DATASET --board SPEC [--camera NAME] [--force]: solves
 * the camera's intrinsics from the dataset's board views, writes them into the dataset's
 * calibration.yaml (never over a better result unless --force) and returns the summary in
 * *ret. Returns an enum gonioctl_exit value; on failure the cause is printed with out_error. */
int calibrate_camera(const struct args *a, struct out *o, json_t **ret);

/* Prints the summary of calibrate_camera for people. */
void calibrate_print_camera(json_t *result);
