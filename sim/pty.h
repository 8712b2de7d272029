/* pty.h - the serial line of an emulated controller: a pseudo-terminal in raw mode whose
 * slave is reachable at the port path of the rig file through a symlink. No framing and
 * no protocol here: the Modbus emulator (modbus_emu.c) reads requests from the master,
 * and so can a G-code emulator.
 *
 * The slave stays open for the pty's lifetime, so the master never sees a hangup when
 * a client closes the port; the master is non-blocking. */
#pragma once

#include <stdbool.h>

#include "common/rigconf.h"

struct sim_pty {
        int master; /* -1 when closed */
        int slave;
        char path[RIG_PATH_MAX]; /* the slave, /dev/pts/N */
        char link[RIG_PATH_MAX]; /* the symlink made to it, "" for none */
};

/* A closed pty, for initialisation. */
#define SIM_PTY_NULL ((struct sim_pty){.master = -1, .slave = -1})

/* Opens a pty in raw mode and, unless link is NULL, points link at its slave (replacing
 * a stale symlink; any other file there is -EEXIST; the directory must exist). who names
 * the owner in log messages. On error returns -errno, logged, with p partly set up:
 * sim_pty_close() it. */
int sim_pty_open(struct sim_pty *p, const char *link, const char *who);

/* Removes the symlink if it still points at this pty and closes both ends. A closed pty
 * is a no-op. */
void sim_pty_close(struct sim_pty *p);
