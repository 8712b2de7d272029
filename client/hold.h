/* hold.h - gonioctl's hold mode of `laser on` and `lamp on` (docs/gonioctl.md): stays
 * connected while the switch is on, so that goniod switches it off when gonioctl goes. */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/conn.h"
#include "client/output.h"

/* After method (laser.set or lamp.set) with params answered res: when res says the switches
 * went on and go off when this client disconnects (off_on_disconnect), or --for was given,
 * stays connected until SIGINT/SIGTERM (intr_fd, from cmd_intr_fd() before the request),
 * --for SEC, or one of them going off (another client, max_on_s, a fault), then switches them
 * off with method. Returns an enum gonioctl_exit: EXIT_OK, EXIT_INTERRUPTED when they went
 * off before the hold ended, or the failure's. */
int hold_switch(const struct args *a, struct out *o, struct conn *conn, const char *method,
                json_t *params, json_t *res, int intr_fd);
