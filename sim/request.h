/* request.h - one request on gonio-sim's line-based JSON socket (docs/sim.md, "Frame
 * socket"): typed access to its fields, and the message of its error reply. Shared by the
 * frame server (render) and the control module (state, geometry, inject). */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#include <jansson.h>

#include "common/cleanup.h"
#include "common/rigconf.h"

struct sim_req {
        json_t *req;   /* the request object, borrowed */
        char msg[256]; /* message of the error reply, "" for strerror() */
};

/* Records the message of an error reply in rq. Returns -err. */
int sim_req_fail(struct sim_req *rq, int err, const char *fmt, ...) _printf_(3, 4);

/* Reads the optional integer field key into *out (kept when absent). Returns 1 when
 * present, 0 when absent, -EINVAL (recorded) when not an integer in [min, max]. */
int sim_req_int(struct sim_req *rq, const char *key, long min, long max, long *out);

/* As sim_req_int for a number in [min, max]. */
int sim_req_num(struct sim_req *rq, const char *key, double min, double max, double *out);

/* As sim_req_int for a boolean. */
int sim_req_bool(struct sim_req *rq, const char *key, bool *out);

/* The index in rc->cameras of the camera named by the field "camera" into *ci. Returns 0,
 * -EINVAL (not a string) or -ENOENT (no such camera), recorded. */
int sim_req_camera(struct sim_req *rq, const struct rig_config *rc, int *ci);

/* The error reply {"ok": false, "error": NAME, "message": ...} for r < 0 (a new
 * reference; NULL when out of memory). */
json_t *sim_req_error_json(const struct sim_req *rq, int r);
