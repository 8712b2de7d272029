/* doctor.h - gonioctl doctor [SESSION-FILE]: what stands between the operator and a capture
 * (client/doctor.c; docs/gonioctl.md, "doctor"). */
#pragma once

#include <jansson.h>

#include "client/args.h"
#include "client/output.h"

/* Checks the socket (there, a socket, its group one of the user's), goniod's answer, the
 * fault, every device (open, axes homed), and the room on the data root, against what the
 * session file a->words names would store. Prints each check; the result {ok, checks: [{name,
 * status: ok|warn|fail, detail, hint?}]} into *ret. Returns EXIT_OK, or EXIT_CONNECT (no
 * goniod to ask), EXIT_DEVICE (a device fails or a fault is latched), EXIT_STORAGE (no room
 * for the session), the report printed either way. */
int doctor_command(const struct args *a, struct out *o, json_t **ret);

/* Prints doctor's result for people. */
void doctor_print(json_t *result);
