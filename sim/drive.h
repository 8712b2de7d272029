/* drive.h - the physics of an emulated axis drive, with no protocol in it: trapezoidal
 * moves (sim/motion.h), homing to a switch, stop, settle and in-position, the home
 * switch, and drive faults (a stall that latches a fault code, a move that ends short of
 * its target without a fault). The Modbus emulator (modbus_emu.c) maps registers onto it;
 * a G-code emulator can map its commands onto the same model.
 *
 * Positions: "physical" is the axis angle in the world (what the renderer sees);
 * "drive" positions count from the drive's reference, which is arbitrary at power-on and
 * physical 0 (the home switch) after homing. Times are emulated seconds on the caller's
 * clock; the functions taking now first apply what happened up to now (a scheduled halt,
 * the end of homing). Not thread-safe: the caller serialises access. */
#pragma once

#include <stdbool.h>

#include "common/rigconf.h"
#include "sim/motion.h"

/* Fault code latched by a stall. */
#define SIM_DRIVE_FAULT_STALL 1
/* How far before its target a move ends under SIM_DRIVE_SHORT (at most half the move). */
#define SIM_DRIVE_SHORT_DEG 3.0

enum sim_drive_fault {
        SIM_DRIVE_OK,    /* clears a pending fault (a latched fault code stays until reset) */
        SIM_DRIVE_STALL, /* the move stops half-way (in time) and latches fault code 1 */
        SIM_DRIVE_SHORT, /* the move stops SIM_DRIVE_SHORT_DEG before its target: not moving,
                          * not in position, no fault code */
};

struct sim_drive {
        const struct rig_axis_conf *conf;
        struct motion mo; /* physical position over emulated time */
        double offset;    /* physical position at drive position 0 */
        double settle_s;
        bool homed, homing;
        bool aborted;               /* the last move ended early (stop, stall, short) */
        int fault_code;             /* 0: none */
        enum sim_drive_fault armed; /* applies to the next move or homing */
        double halt_at;             /* emulated time of a scheduled halt, NAN if none */
        int halt_fault;             /* fault code latched by that halt (0 for a short) */
};

struct sim_drive_status {
        bool moving;
        bool in_position; /* at rest, settled, the last move completed, no fault */
        bool homed;
        bool fault;       /* fault_code != 0 */
        bool home_switch; /* within 0.5 deg of physical 0 (modulo 360) */
};

/* Powers the drive of axis c on at time 0, at rest at an arbitrary but deterministic
 * position (derived from the axis name), unhomed. c must outlive d. Never fails. */
void sim_drive_init(struct sim_drive *d, const struct rig_axis_conf *c);

/* Like sim_drive_init() but at rest at physical angle physical: an axis with no reference
 * whose power-on position defines the world's zero (a Ciclop turntable). */
void sim_drive_init_at(struct sim_drive *d, const struct rig_axis_conf *c, double physical);

/* The physical angle at time now (not wrapped). */
double sim_drive_physical(struct sim_drive *d, double now);

/* The physical angle at time now, wrapped to [0, 360) for continuous axes: the pose. */
double sim_drive_angle(struct sim_drive *d, double now);

/* The position in drive coordinates at time now. */
double sim_drive_position(struct sim_drive *d, double now);

/* The status at time now. */
struct sim_drive_status sim_drive_status(struct sim_drive *d, double now);

/* Whether a move or homing with these limits would be accepted at time now: 0, -EIO
 * while a fault code is latched, -EINVAL for non-positive vmax or accel. */
int sim_drive_check_move(struct sim_drive *d, double now, double vmax, double accel);

/* Starts a move to target (drive coordinates) at time now, from where the axis is, from
 * rest. Returns 0 or the errors of sim_drive_check_move (nothing changes then). */
int sim_drive_move(struct sim_drive *d, double now, double target, double vmax, double accel);

/* Starts homing: a move to the home switch at physical 0 (the nearest turn for continuous
 * axes); when it completes the drive position there becomes 0 and the drive is homed.
 * Returns as sim_drive_move. */
int sim_drive_home(struct sim_drive *d, double now, double vmax, double accel);

/* Halts at once (emergency stop); a scheduled fault halt is cancelled. Never fails. */
void sim_drive_stop(struct sim_drive *d, double now);

/* Makes the position at time now drive position 0, homed or not (a G-code controller's
 * G50: "this is the origin"). Never fails. */
void sim_drive_set_origin(struct sim_drive *d, double now);

/* Clears the latched fault code. Never fails. */
void sim_drive_reset(struct sim_drive *d);

/* Injects fault at time now: into the current move if the axis moves, else into the next
 * move or homing. SIM_DRIVE_OK cancels a pending or scheduled fault. Never fails. */
void sim_drive_inject(struct sim_drive *d, double now, enum sim_drive_fault fault);
