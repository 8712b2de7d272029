/* io_internal.h - what the writers and readers of models/<name>/ share (model_io.c: the SH
 * model; brdf_io.c: the BRDF model): a new file written and synced, a temporary directory
 * installed in one rename, files read with every problem named by file. Private to
 * appearance/. */
#pragma once

#include <jansson.h>
#include <stddef.h>

#include "appearance/model.h"

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
        const char *json; /* the JSON file read, for messages; NULL: "model.json" */
};

/* Writes "DIR/FILE: message" into rd's buffer. Returns -EBADMSG. */
int ap_io_bad(const struct ap_io_rd *rd, const char *file, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* Reads file of rd's directory whole into *buf, of exactly want bytes (0: any). Returns 0,
 * -EBADMSG (missing, or another size, with the sentence) or -errno. */
int ap_io_slurp(const struct ap_io_rd *rd, const char *file, size_t want, void **buf, size_t *len);

/* A JSON array of the n numbers v (NULL on allocation failure). */
json_t *ap_io_json_vec(const double *v, size_t n);

/* Camera c as JSON: width, height, fx, fy, cx, cy, dist (5), R (9), t (3). */
json_t *ap_io_camera_json(const struct ap_camera *c);

/* Reads the n numbers of array key of object o into v; where names o in messages. Returns 0
 * or -EBADMSG with the sentence. */
int ap_io_get_vec(const struct ap_io_rd *rd, json_t *o, const char *key, double *v, size_t n,
                  const char *where);

/* Reads camera o (ap_io_camera_json's) into c. Returns 0 or -EBADMSG with the sentence. */
int ap_io_get_camera(const struct ap_io_rd *rd, json_t *o, struct ap_camera *c, const char *where);
