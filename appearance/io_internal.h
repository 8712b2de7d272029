/* io_internal.h - what the writers of models/<name>/ share (model_io.c: the SH model;
 * brdf_io.c: the BRDF model): a new file written and synced, a temporary directory installed
 * in one rename. Private to appearance/. */
#pragma once

#include <stddef.h>

/* Writes a new file name in dfd with buf and fsyncs it. Returns 0 or -errno. */
int ap_io_put_file(int dfd, const char *name, const void *buf, size_t len);

/* Renames directory tmp to final, exchanging it with an older final (then removed), and
 * syncs the parent. Returns 0 or -errno. */
int ap_io_install_dir(const char *tmp, const char *final);
