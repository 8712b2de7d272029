/* drive.c - the physics of an emulated axis drive (see drive.h). */
#include <errno.h>
#include <math.h>
#include <stdint.h>

#include "common/cleanup.h"
#include "sim/drive.h"

#define DRIVE_HOME_SWITCH 0.5 /* deg: half width of the home switch's cam */

static double wrap360(double deg)
{
        double w = fmod(deg, 360.0);
        return w < 0.0 ? w + 360.0 : w;
}

/* A deterministic, arbitrary power-on position: the drive does not know it until homed. */
static double start_position(const struct rig_axis_conf *c)
{
        uint32_t h = 2166136261u;
        for (const char *p = c->name; *p; p++)
                h = (h ^ (uint8_t)*p) * 16777619u;
        double f = (h % 10007) / 10007.0;
        if (c->continuous)
                return 360.0 * f - 180.0;
        return 0.5 * (c->min_deg + f * (c->max_deg - c->min_deg));
}

void sim_drive_init_at(struct sim_drive *d, const struct rig_axis_conf *c, double physical)
{
        *d = (struct sim_drive){
                .conf = c,
                .offset = physical,
                .settle_s = c->settle_ms / 1000.0,
                .halt_at = NAN,
        };
        motion_rest(&d->mo, 0.0, d->offset);
}

void sim_drive_init(struct sim_drive *d, const struct rig_axis_conf *c)
{
        sim_drive_init_at(d, c, start_position(c));
}

/* Applies what happened up to now: a scheduled halt, the end of homing. */
static void update(struct sim_drive *d, double now)
{
        if (!isnan(d->halt_at) && now >= d->halt_at) {
                motion_halt(&d->mo, d->halt_at);
                if (d->halt_fault)
                        d->fault_code = d->halt_fault;
                d->aborted = true;
                d->homing = false;
                d->halt_at = NAN;
        }
        if (d->homing && !motion_moving(&d->mo, now)) {
                d->offset = motion_target(&d->mo);
                d->homed = true;
                d->homing = false;
        }
}

double sim_drive_physical(struct sim_drive *d, double now)
{
        update(d, now);
        return motion_position(&d->mo, now);
}

double sim_drive_angle(struct sim_drive *d, double now)
{
        double pos = sim_drive_physical(d, now);

        return d->conf->continuous ? wrap360(pos) : pos;
}

double sim_drive_position(struct sim_drive *d, double now)
{
        return sim_drive_physical(d, now) - d->offset;
}

struct sim_drive_status sim_drive_status(struct sim_drive *d, double now)
{
        double w = wrap360(sim_drive_physical(d, now) + DRIVE_HOME_SWITCH);
        bool moving = motion_moving(&d->mo, now);

        return (struct sim_drive_status){
                .moving = moving,
                .in_position = !moving && !d->aborted && !d->fault_code &&
                               now >= motion_end_time(&d->mo) + d->settle_s,
                .homed = d->homed,
                .fault = d->fault_code != 0,
                .home_switch = w < 2 * DRIVE_HOME_SWITCH,
        };
}

/* Schedules the halt of fault in the profile just planned (or running), no earlier than
 * now: a stall half-way in time, a short stop SIM_DRIVE_SHORT_DEG before the target. */
static void schedule(struct sim_drive *d, double now, enum sim_drive_fault fault)
{
        const struct motion *m = &d->mo;

        if (fault == SIM_DRIVE_STALL) {
                d->halt_at = MAX(now, m->t0 + 0.5 * m->t_total);
                d->halt_fault = SIM_DRIVE_FAULT_STALL;
        } else {
                double short_deg = MIN(SIM_DRIVE_SHORT_DEG, 0.5 * m->dist);
                d->halt_at = MAX(now, motion_time_at(m, m->dist - short_deg));
                d->halt_fault = 0;
        }
}

int sim_drive_check_move(struct sim_drive *d, double now, double vmax, double accel)
{
        update(d, now);
        if (d->fault_code)
                return -EIO;
        return vmax > 0.0 && accel > 0.0 ? 0 : -EINVAL;
}

/* Plans a move to physical position to; homing says whether it is a homing run. */
static int start(struct sim_drive *d, double now, double to, double vmax, double accel, bool homing)
{
        int r = sim_drive_check_move(d, now, vmax, accel);
        if (r < 0)
                return r;
        (void)motion_plan(&d->mo, now, motion_position(&d->mo, now), to, vmax, accel);
        d->homing = homing;
        d->aborted = false;
        d->halt_at = NAN;
        if (d->armed != SIM_DRIVE_OK && d->mo.t_total > 0.0) {
                schedule(d, now, d->armed);
                d->armed = SIM_DRIVE_OK;
        }
        return 0;
}

int sim_drive_move(struct sim_drive *d, double now, double target, double vmax, double accel)
{
        return start(d, now, target + d->offset, vmax, accel, false);
}

int sim_drive_home(struct sim_drive *d, double now, double vmax, double accel)
{
        double pos = sim_drive_physical(d, now);

        return start(d, now, d->conf->continuous ? pos - remainder(pos, 360.0) : 0.0, vmax, accel,
                     true);
}

void sim_drive_stop(struct sim_drive *d, double now)
{
        update(d, now);
        motion_halt(&d->mo, now);
        d->aborted = true;
        d->homing = false;
        d->halt_at = NAN;
}

void sim_drive_reset(struct sim_drive *d)
{
        d->fault_code = 0;
}

void sim_drive_set_origin(struct sim_drive *d, double now)
{
        update(d, now);
        d->offset = sim_drive_physical(d, now);
}

void sim_drive_inject(struct sim_drive *d, double now, enum sim_drive_fault fault)
{
        update(d, now);
        if (fault == SIM_DRIVE_OK) {
                d->armed = SIM_DRIVE_OK;
                d->halt_at = NAN;
        } else if (motion_moving(&d->mo, now))
                schedule(d, now, fault);
        else
                d->armed = fault;
}
