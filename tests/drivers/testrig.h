/* testrig.h - a small test rig for the driver-vs-emulator tests: a rig file written into
 * a fresh temp dir (the emulator's pty symlinks go there too), loaded with rigconf_load,
 * with gonio-sim's Modbus emulators running on it. */
#pragma once

#include "common/rigconf.h"
#include "drivers/axis/axis.h"
#include "drivers/bus/bus.h"
#include "sim/modbus_emu.h"

/* Emulated motion runs this many times faster than real time. */
#define TESTRIG_TIME_SCALE 20.0

struct testrig {
        char dir[64];
        struct rig_config *rc;
        struct sim_emu *emu;
};

/* Writes yaml (with every "@DIR@" replaced by the temp dir) to DIR/rig.yaml, loads it and
 * starts the emulators; TCP buses get their listening port filled in. Exits on failure. */
void testrig_start(struct testrig *t, const char *yaml);

/* Stops the emulators, frees the config, removes the temp dir. */
void testrig_stop(struct testrig *t);

/* The bus configuration named name (exits when absent). */
const struct rig_bus_conf *testrig_bus(const struct testrig *t, const char *name);

/* Seconds on CLOCK_MONOTONIC. */
double testrig_now(void);

/* Sleeps for s seconds. */
void testrig_sleep(double s);

/* Creates and opens the axis of rc->axes[index] on bus b; exits unless it opens enabled. */
struct axis *testrig_axis_open(struct testrig *t, struct bus *b, int index);

/* Polls until the axis's move has ended (moving clear); returns the seconds it took. Exits
 * after timeout_s. */
double testrig_wait_stopped(struct axis *ax, double timeout_s);

/* Waits for the end of the move and the drive's in-position flag, without a fault. */
void testrig_wait_in_position(struct axis *ax);

/* Checks that moves of ax just past its soft limits (and NAN) are refused with -ERANGE
 * before any request on its bus, and that it is still at pos (within tol). */
void testrig_check_limits(struct axis *ax, double pos, double tol);

/* Homes the axes ax[0..n) at once, waits until each is in position and checks that each is
 * homed and at 0 deg (within tol; 360 counts as 0 on continuous axes). */
void testrig_home_all(struct axis *const *ax, int n, double tol);
