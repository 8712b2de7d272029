/* scan.h - goniod's continuous laser scan (docs/protocol.md, scan.continuous): the
 * turntable turns at a constant speed (step x the camera's frame rate) while one camera
 * streams frames with the laser on; each frame's turntable angle is interpolated from the
 * drive's read-backs at the frame's mid-exposure time, and the frames inside the scanned
 * range are stored through the capture pipeline into the open dataset.
 *
 * One scan at a time, and not while a session runs. While it runs it owns the rig: the
 * other methods that move, switch, capture or change the dataset are refused with -EBUSY.
 * A fault, stop, a camera error or the requesting client's disconnect ends it with the
 * laser off and motion stopped. */
#pragma once

#include <stdbool.h>

#include "drivers/camera/camera.h"

struct manager;
struct scan;
struct srv_req;

/* What to scan: angles from, from + step, ... up to to (to included when a step lands on
 * it, dropped when it comes round to from on a continuous turntable: a full turn). */
struct scan_params {
        int cam; /* camera index */
        double from, to, step;
        struct cam_request req;
};

/* Creates the scanner of m (idle). Returns 0 or -ENOMEM. */
int scan_new(struct manager *m, struct scan **ret);

/* Forgets a running scan (goniod is exiting: the rig's safe state follows). NULL is a no-op;
 * returns NULL. */
struct scan *scan_free(struct scan *s);

/* Ends a running scan (stop was called): its reply is -ECANCELED. */
void scan_cancel(struct scan *s);

/* True while a scan runs. */
bool scan_active(const struct scan *s);

/* Why other clients' operations are refused now ("a continuous scan ... is running"), or
 * NULL. */
const char *scan_busy_reason(const struct scan *s);

/* Starts the scan of p for req, which it answers (srv_reply or srv_fail) once it ended and
 * every frame was stored. Returns 0 (req taken), or -EBUSY, -ESTALE, -EPERM, -ERANGE,
 * -EOPNOTSUPP, -ENOENT with msg (req not answered). */
int scan_start(struct scan *s, struct srv_req *req, const struct scan_params *p, char *msg,
               size_t len);
