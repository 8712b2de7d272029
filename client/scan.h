/* scan.h - gonioctl scan --from DATASET: the offline reconstruction of a dataset's laser
 * captures into a point cloud and a mesh (calib/scan.h), without goniod. */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* gonioctl scan --from DATASET [--camera NAME] [--triangles N] [--force]: reconstructs the
 * scan of the dataset with the nominal calibration of its rig file, writes scan.ply,
 * mesh.ply and mesh.obj into it (an existing scan only with --force) and returns the
 * summary in *ret. Returns an enum gonioctl_exit value: EXIT_USAGE without --from,
 * EXIT_INVALID for a dataset that cannot be opened or scanned (no laser frames, no such
 * camera, a scan there already), EXIT_STORAGE when a file cannot be written; the cause is
 * printed with out_error. */
int scan_reconstruct(const struct args *a, struct out *o, json_t **ret);

/* Prints the summary of scan_reconstruct for people. */
void scan_print(json_t *result);
