/* motion.h - the timing model of an emulated axis drive: a trapezoidal (or, for
 * short moves, triangular) velocity profile from rest to rest.
 *
 * Pure functions of time; no clock is read here. Times are in seconds of
 * emulated time, positions in degrees, speeds in deg/s, accelerations in deg/s^2. */
#pragma once

#include <stdbool.h>

struct motion {
        double t0;      /* start time */
        double from;    /* start position */
        double dir;     /* +1 or -1 */
        double dist;    /* absolute distance */
        double v_peak;  /* reached speed (< vmax for a triangular profile) */
        double accel;   /* acceleration and deceleration */
        double t_acc;   /* duration of the acceleration phase (= deceleration) */
        double t_total; /* duration of the whole profile */
};

/* A profile standing still at pos from time t on. Never fails. */
void motion_rest(struct motion *m, double t, double pos);

/* Plans a move from 'from' at time t0 to 'to' with speed limit vmax and acceleration
 * accel (both > 0). Returns 0, or -EINVAL (m untouched) for non-positive vmax/accel. */
int motion_plan(struct motion *m, double t0, double from, double to, double vmax, double accel);

/* Position along the profile at time t (clamped to the start and end positions). */
double motion_position(const struct motion *m, double t);

/* Signed velocity along the profile at time t. */
double motion_velocity(const struct motion *m, double t);

/* Time when the profile ends. */
double motion_end_time(const struct motion *m);

/* The time at which the profile has covered dist degrees (clamped to [0, its distance]). */
double motion_time_at(const struct motion *m, double dist);

/* Target of the profile. */
double motion_target(const struct motion *m);

/* True while t is before the end of the profile. */
bool motion_moving(const struct motion *m, double t);

/* Stops the profile dead at time t (emergency stop): the axis rests where it is then. */
void motion_halt(struct motion *m, double t);

/* Duration of a move over dist degrees with the given limits (0 for dist 0). */
double motion_duration(double dist, double vmax, double accel);
