/* validate.h - gonioctl validate FILE [--rig RIG-FILE]: checks a rig file or a session file
 * with the loaders goniod uses (common/rigconf.h, common/sessconf.h), without goniod
 * (docs/gonioctl.md, "validate"). */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* Loads a->words[1]: a session file when --rig names its rig or when it has a `dataset` or
 * `sweep` key (then --rig is required: EXIT_USAGE without), else a rig file. Returns EXIT_OK
 * with {file, kind, valid, ...} in *ret, or EXIT_INVALID after printing the loader's
 * "FILE:LINE: key 'k': reason" to stderr (its parts in o->error_detail for --json). */
int validate_command(const struct args *a, struct out *o, json_t **ret);

/* Prints the result of validate_command for people. */
void validate_print(json_t *result);
