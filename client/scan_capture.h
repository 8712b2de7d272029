/* scan_capture.h - gonioctl scan DATASET: the capture of a laser scan on the rig, in
 * continuous rotation (goniod's scan.continuous) or stop-and-go (a generated session file,
 * so it resumes after faults like any session); docs/scanning.md, "Capture". */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* gonioctl scan DATASET [--mode continuous|stop] [--start A --end B --step S] [--camera NAME]
 * [--exposure US] [--gain G] [--lamps L1,L2]: opens (or creates) DATASET and captures the
 * scan into it. Returns an enum gonioctl_exit value with the summary in *ret (the scan's result,
 * or the session's status); on failure the cause is printed with out_error. */
int scan_capture(const struct args *a, struct out *o, json_t **ret);

/* Prints the summary of scan_capture for people. */
void scan_capture_print(json_t *result);
