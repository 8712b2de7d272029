/* model.h - gonioctl model: the appearance model of a dataset (appearance/), offline, without
 * goniod (docs/appearance.md). */
#pragma once

/* gonioctl model render MODEL (--light X,Y,Z | --dir X,Y,Z | --envmap FILE) --view AZ,EL
 * [--distance MM] [--mode pixel|object] [--size WxH] [--intensity I] [--gain G] -o OUT.png:
 * argv[0] is the word "render", the options and MODEL (DATASET/models/NAME) follow in any
 * order. Renders the model (appearance/render.h) on its dataset's mesh and writes an 8-bit
 * linear RGB PNG. Returns an enum gonioctl_exit value (client/cmd.h): EXIT_USAGE for a bad
 * command line, EXIT_INVALID for a missing or malformed model, a bad environment map or a
 * view farther than 30 degrees from the views the model covers, EXIT_STORAGE when the image
 * cannot be written; the cause is printed to stderr. */
int model_render_command(int argc, char **argv);
