/* io_internal.h - what the writers and readers of models/<name>/ share (model_io.c: the SH
 * model; brdf_io.c: the BRDF model): a new file written and synced, a temporary directory
 * installed in one rename, files read with every problem named by file. Private to
 * appearance/. */
#pragma once

#include <stddef.h>

/* Writes a new file name in dfd with buf and fsyncs it. Returns 0 or -errno. */
int ap_io_put_file(int dfd, const char *name, const void *buf, size_t len);

#define AP_IO_BRDF_DIR "brdf" /* models/<name>/brdf/: the BRDF model beside the SH model */

/* Renames directory tmp to final, exchanging it with an older final (then removed), and
 * syncs the parent. Returns 0 or -errno. */
int ap_io_install_dir(const char *tmp, const char *final);

/* Where a read is, for messages: the model's directory and the error buffer. */
struct ap_io_rd {
        const char *dir;
        char *err;
        size_t errlen;
};

/* Writes "DIR/FILE: message" into rd's buffer. Returns -EBADMSG. */
int ap_io_bad(const struct ap_io_rd *rd, const char *file, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* Reads file of rd's directory whole into *buf, of exactly want bytes (0: any). Returns 0,
 * -EBADMSG (missing, or another size, with the sentence) or -errno. */
int ap_io_slurp(const struct ap_io_rd *rd, const char *file, size_t want, void **buf, size_t *len);
