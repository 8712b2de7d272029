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

/* gonioctl scan: without a DATASET word, scan_reconstruct (--from DIR); with one,
 * scan_capture (client/scan_capture.h) and then, unless --no-mesh, scan_reconstruct of the
 * captured dataset. Returns an enum gonioctl_exit value. */
int scan_command(const struct args *a, struct out *o, json_t **ret);

/* Prints the result of scan_command: a reconstruction's or a capture's summary. */
void scan_command_print(json_t *result);
