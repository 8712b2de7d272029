/* export.h - gonioctl dataset export DATASET --format F -o DIR [--model NAME]
 * [--calibration FILE|nominal]: the dataset in a format other tools read (appearance/export.h,
 * docs/exports.md), without goniod. The words after `dataset export` are not parsed by
 * args.c: this command parses its own options. */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* Runs the export of a->words after "dataset export". Returns an enum gonioctl_exit value:
 * EXIT_USAGE for a bad command line, EXIT_INVALID for an unknown format, a destination that
 * is not empty or a dataset that lacks what the format needs, EXIT_STORAGE when writing
 * failed; the cause printed. The result ({dataset, format, dir}) in *ret. */
int export_command(const struct args *a, struct out *o, json_t **ret);

/* Prints the result of export_command for people. */
void export_print(json_t *result);
