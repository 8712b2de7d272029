/* calcopy.h - the rig's calibration file in goniod (rig file key `calibration`,
 * docs/calibration.md): checked at start (a warning when missing or unreadable), reported by
 * describe, and copied into each dataset captured into, so that a dataset carries the
 * calibration it was captured with. goniod never parses its sections (calib/ does). */
#pragma once

#include <jansson.h>

#include "common/rigconf.h"
#include "server.h"

struct manager;

/* The state of rc's calibration file as {path, state, message}: state "none" (the rig file
 * names none), "ok", "missing", "unreadable" or "invalid" (not a calibration file); message
 * says why when not ok. Reads the file: call on a worker, or at start before the loop
 * serves. New reference, NULL without memory. */
json_t *calcopy_check(const struct rig_config *rc);

/* Logs a warning when rc names a calibration file that is not ok (at start). */
void calcopy_warn(const struct rig_config *rc);

/* Copies rc's calibration file into the dataset directory ds_dir as calibration.yaml,
 * atomically (common/fileio). Nothing when rc names none. A file that cannot be read or
 * written is logged as a warning and the dataset's own calibration.yaml, if any, kept.
 * Returns 0 or -errno. Worker thread (blocking I/O). */
int calcopy_into(const struct rig_config *rc, const char *ds_dir);

/* Answers describe (the rig's describe object d, stolen) with its "calibration" member
 * (calcopy_check) filled on the dataset worker. Returns 0 (answered later) or -errno. Loop
 * thread. */
int calcopy_describe(struct manager *m, struct srv_req *req, json_t *d);
