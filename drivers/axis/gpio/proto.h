/* proto.h - the "gpio-stepper" axis backend: a stepper driver on GPIO lines (step, dir, enable)
 * with home and limit switches as inputs. Its rig-file map and the pure parts: the trapezoidal step
 * schedule and the degree/step conversions. No I/O. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/axis/axis.h"

/* The lines of a GPIO stepper, in the order of its map's keys (gpst_line_keys). */
enum gpst_line {
        GPST_STEP,      /* output: one rising edge per step */
        GPST_DIR,       /* output: 1 while stepping upwards (positive degrees) */
        GPST_ENABLE,    /* output: 1 while the driver may energise the motor */
        GPST_HOME,      /* input: 1 while the home switch is made */
        GPST_LIMIT_MIN, /* input: 1 at the lower end of travel */
        GPST_LIMIT_MAX, /* input: 1 at the upper end of travel */
        GPST_N_LINES,
};

/* Fault codes of struct axis_state.fault_code. */
enum gpst_fault {
        GPST_FAULT_NONE,
        GPST_FAULT_LIMIT_MIN = 1,    /* the lower limit switch stopped a move */
        GPST_FAULT_LIMIT_MAX = 2,    /* the upper limit switch stopped a move */
        GPST_FAULT_HOME_MISSING = 3, /* homing travelled its whole range without the switch */
        GPST_FAULT_IO = 4,           /* a line could not be written or read while stepping */
};

/* The map's key of each line: "step", "dir", "enable", "home", "limit_min", "limit_max". */
extern const char *const gpst_line_keys[GPST_N_LINES];

/* What the backend reads from an axis's map "gpio-stepper: { bus: io, chip: gonio-gpio, step: 0,
 * dir: dir, ..., steps_per_deg: 100 }". */
struct gpst_conf {
        char chip[RIG_PATH_MAX];                /* name, path, number or label */
        char lines[GPST_N_LINES][RIG_NAME_MAX]; /* offset or name; "" when not wired */
        bool active_low[GPST_N_LINES];          /* from the list "active_low: [enable, home]" */
        double steps_per_deg;                   /* > 0, microsteps and gearing included */
        int home_dir;                           /* -1: the home switch lies below, +1 above */
        double home_speed;                      /* deg/s; 0: half the axis's max_speed */
};

/* A trapezoidal schedule of n steps: accelerate at a, cruise at v, decelerate at a. */
struct gpst_profile {
        long n;
        double v, a;       /* steps/s, steps/s^2 (a <= 0 or infinite: no ramps) */
        double ramp_steps; /* steps of each ramp */
        double t_ramp;     /* seconds of each ramp */
        double total;      /* seconds from start to step n */
};

/* The backend (api.c), registered in drivers/registry.c as "gpio-stepper" when built with libgpiod.
 */
extern const struct axis_ops gpst_ops;
extern const struct rig_backend gpst_backend;

/* Parses the backend map m into conf (a struct gpst_conf): chip, step, dir and steps_per_deg
 * are required; unknown keys, unknown names in active_low, two roles on one line and a
 * home_dir other than -1/1 are errors at their key's line. addr gets no address (lines are
 * checked by the kernel at open: a line held twice is -EBUSY). Returns 0 or -EINVAL. Pure. */
int gpst_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);

/* Fills p for n >= 0 steps at speed v > 0 (steps/s) and acceleration a (steps/s^2). Returns 0,
 * or -EINVAL for a speed that is not > 0 or a negative n. Pure. */
int gpst_profile_init(struct gpst_profile *p, long n, double v, double a);

/* Seconds from the start of p to step k (1..n): the moment the position reaches k. Step n
 * comes at p->total, which equals axis_move_time() for the same distance. Pure. */
double gpst_step_time(const struct gpst_profile *p, long k);

/* Degrees to steps, rounded. Returns 0, or -ERANGE beyond +-2^53 or for a non-finite value. */
int gpst_deg_to_steps(double steps_per_deg, double deg, int64_t *ret);

/* Steps to degrees; modulo 360 into [0, 360) when continuous. */
double gpst_steps_to_deg(double steps_per_deg, int64_t steps, bool continuous);

/* The step target delta_deg away from the step counter cur (continuous axes: the travel
 * the axis class chose). Returns 0 or -ERANGE beyond the counter. */
int gpst_travel_steps(double steps_per_deg, int64_t cur, double delta_deg, int64_t *ret);
