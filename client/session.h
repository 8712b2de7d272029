/* session.h - gonioctl's session commands: the session file sent to goniod, and the
 * follower of a running session (progress bar with count, rate and ETA on a terminal,
 * JSON events with --json), with their exit codes (docs/gonioctl.md). */
#pragma once

#include <jansson.h>

#include "client/conn.h"
#include "client/output.h"

/* Reads the session file at path into params as {file, text}. Returns 0, or -errno after
 * printing why (a missing file, one over the protocol's size). */
int csession_file_params(const char *path, json_t *params);

/* Follows the session whose status (borrowed) a run, resume or status call returned, until it
 * ends or pauses; SIGINT/SIGTERM on intr_fd pause it (and wait for the pause). Returns the exit
 * code: 0 done, EXIT_CANCELED aborted or paused by a client, else that of the error that
 * paused it. */
int csession_follow(struct out *o, struct conn *conn, int intr_fd, json_t *status);

/* Human printers of session.plan and session.status results. */
void out_print_session_plan(json_t *r);
void out_print_session_status(json_t *r);
