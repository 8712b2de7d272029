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

/* gonioctl model render MODEL (--light X,Y,Z | --dir X,Y,Z | --envmap FILE) --view AZ,EL
 * [--distance MM] [--mode pixel|object] [--size WxH] [--intensity I] [--gain G] -o OUT.png:
 * argv[0] is "render", the options and MODEL (DATASET/models/NAME) follow in any order.
 * Renders the model (appearance/render.h) on its dataset's mesh and writes an 8-bit linear
 * RGB PNG (client/model_render.c). Returns an enum gonioctl_exit value: EXIT_USAGE for a
 * bad command line, EXIT_INVALID for a missing or malformed model, a bad environment map or
 * a view farther than 30 degrees from the views the model covers, EXIT_STORAGE when the
 * image cannot be written; the cause is printed to stderr. */
int model_render_command(int argc, char **argv);

/* gonioctl model export --web DIR MODEL [--envmap FILE]... and gonioctl model view MODEL
 * [--bind ADDR] [--port N] [--envmap FILE]...: argv[0] is "export" or "view". Writes the
 * relighting viewer of MODEL (appearance/webexport.h) into DIR, or into a temporary folder
 * served over HTTP on ADDR (default 127.0.0.1) and port N (default 0: a free one, printed)
 * until SIGINT or SIGTERM (client/model_web.c). Returns an enum gonioctl_exit value. */
int model_web_command(int argc, char **argv);
