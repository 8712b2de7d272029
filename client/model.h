/* model.h - gonioctl model: the appearance model of a dataset (docs/appearance.md), without
 * goniod: `model fit DATASET ...` (client/model.c, appearance/fit.h) and `model render MODEL
 * ...` (client/model_render.c). The words after `model` are not parsed by args.c: each
 * subcommand parses its own options. */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* gonioctl model SUBCOMMAND ...: runs fit (or render) on a->words after "model". Returns an
 * enum gonioctl_exit value with the result in *ret (fit) or the error printed. */
int model_command(const struct args *a, struct out *o, json_t **ret);

/* Prints the result of model_command for people. */
void model_print(json_t *result);

/* gonioctl model render MODEL ...: argv[0] is "render". Returns an enum gonioctl_exit value,
 * the error printed to stderr. Implemented in client/model_render.c. */
int model_render_command(int argc, char **argv);
