/* axis.h - the rotary axis device class: turntable, light arm, camera arm.
 *
 * Ops are blocking and run on the axis's bus worker (or the owner of a sync
 * bus). Positions are in degrees; a continuous axis reports [0, 360) and moves
 * the shortest way round. Cached state changes only after the drive confirms. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/bus/bus.h"
#include "drivers/opt.h"

struct bus;
struct axis;

/* What the drive itself reports. in_position is the drive's own flag, never derived from
 * the position: a move is done only when moving is clear and in_position set. A drive
 * may stop short (moving clear, in_position clear, no fault): that move failed. */
struct axis_state {
        double position_deg;
        bool enabled, homed, moving, in_position, fault;
        int fault_code; /* drive-specific, 0 when none */
};

struct axis_ops {
        const char *name; /* backend name as written in the rig file */
        const struct opt_desc *opts;
        int n_opts;
        int (*open)(struct axis *ax); /* probe the drive, load speed/accel */
        void (*close)(struct axis *ax);
        int (*home)(struct axis *ax);                 /* start homing */
        int (*move_abs)(struct axis *ax, double deg); /* start a move, limits already checked */
        int (*stop)(struct axis *ax);                 /* immediate stop */
        int (*reset)(struct axis *ax);                /* clear a drive fault */
        int (*poll)(struct axis *ax, struct axis_state *st);
        /* Optional: writes the speed (deg/s) and acceleration (deg/s^2) of the following moves
         * to the drive, limits already checked. Backends without it read ax->speed and
         * ax->accel at each move (a G-code feed rate, a step/dir profile). */
        int (*set_rates)(struct axis *ax, double deg_s, double accel);
};

struct axis {
        const struct axis_ops *ops;
        const struct rig_axis_conf *conf; /* borrowed from the rig config */
        struct bus *bus;                  /* borrowed */
        void *priv;                       /* backend state */
        struct axis_state state;          /* last confirmed state */
        /* The rates of the following moves, deg/s and deg/s^2: the rig file's max_speed and
         * accel until axis_set_rates() (bus worker). */
        double speed, accel;
        /* The last message the class logged at warning level or worse, whole ("axis
         * 'turntable' [modbus@drives#1]: Failed to read the drive state: read position (reg
         * 0x0102): Connection timed out after 200 ms"), for operators; "" when none. Written
         * by the ops' thread: read it in the job's done callback or on the sync owner. */
        char last_error[DEV_ERROR_MAX];
        char cause[DEV_ERROR_MAX]; /* detail of the op in progress, see axis_set_cause() */
};

/* Creates the axis for conf with the backend named there (drivers/registry.c).
 * Returns 0, -ENOENT for an unknown backend, or -errno. Does no I/O. */
int axis_new(const struct rig_axis_conf *conf, struct bus *bus, struct axis **ret);

/* Closes and frees; NULL is a no-op. Returns NULL. */
struct axis *axis_free(struct axis *ax);

/* Checks target against the soft limits; for continuous axes normalises it to [0, 360).
 * Returns 0 or -ERANGE. Pure. */
int axis_check_target(const struct axis *ax, double *deg);

/* Wrappers that call the op (on the worker) and log failures once, as "axis 'NAME'
 * [backend@port#unit]: Failed to OPERATION: CAUSE" (CAUSE: what the backend gave with
 * axis_set_cause(), else strerror), also kept in ax->last_error. Each returns 0 or
 * -errno. */
int axis_open(struct axis *ax);
int axis_home(struct axis *ax);
int axis_move_abs(struct axis *ax, double deg); /* checks limits first: -ERANGE */
int axis_stop(struct axis *ax);
int axis_reset(struct axis *ax);
int axis_poll(struct axis *ax); /* refreshes ax->state */
/* Sets the cruise speed and acceleration of the following moves (0: the rig file's max_speed,
 * accel) in ax->speed and ax->accel, written to the drive where its backend has set_rates;
 * -ERANGE above max_speed or axis_max_accel(). */
int axis_set_rates(struct axis *ax, double deg_s, double accel);

/* The most acceleration axis_set_rates() allows: the rig file's max_accel (its accel when a
 * config built by hand has none). Pure. */
double axis_max_accel(const struct rig_axis_conf *c);

/* Logs "axis 'NAME' [BACKEND@PORT#UNIT]: message" at level (GN_LOG_*); %m prints err.
 * Returns -abs(err). At warning level or worse also fills last_error: the ops' thread. */
int axis_log_full(struct axis *ax, int level, int err, const char *fmt, ...)
        __attribute__((format(printf, 4, 5)));

/* For backends: records the detail of the current op's failure ("read position (reg
 * 0x0102): Connection timed out after 200 ms") for the wrapper's message, without
 * logging. %m prints err. Returns -abs(err). */
int axis_set_cause(struct axis *ax, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* The signed travel in degrees from pos to target, decided once for every backend: on a
 * continuous axis the way round the rig file allows (the shortest, a tie going up, or
 * always up or always down: direction), else target - pos. Backends add it to their own
 * raw position. Pure. */
double axis_travel(const struct rig_axis_conf *c, double pos, double target);

/* Where to command a move from pos to target first, with the backlash of c: target when the
 * move already ends in the direction of the backlash (or there is none), else the point
 * backlash short of target, so the final approach always comes from the same side.
 * Continuous axes compare the shortest way round. Pure. */
double axis_takeup_target(const struct rig_axis_conf *c, double pos, double target);

/* True when pos is within c's deadband of target (always, with no deadband). Pure. */
bool axis_within_deadband(const struct rig_axis_conf *c, double pos, double target);

/* Estimated duration of a move of delta degrees with a trapezoidal profile, in seconds. */
double axis_move_time(double delta_deg, double max_speed, double accel);
