/* motion.c - trapezoidal motion profiles of emulated axis drives (see motion.h). */
#include <errno.h>
#include <math.h>

#include "sim/motion.h"

void motion_rest(struct motion *m, double t, double pos)
{
        *m = (struct motion){.t0 = t, .from = pos, .dir = 1.0, .accel = 1.0};
}

int motion_plan(struct motion *m, double t0, double from, double to, double vmax, double accel)
{
        if (!(vmax > 0.0) || !(accel > 0.0))
                return -EINVAL;

        double dist = fabs(to - from);
        /* Distance covered while accelerating to vmax and braking again. */
        double v = vmax;
        if (v * v / accel > dist)
                v = sqrt(dist * accel); /* triangular: never reaches vmax */
        double t_acc = v / accel;
        double d_cruise = dist - v * t_acc;

        *m = (struct motion){
                .t0 = t0,
                .from = from,
                .dir = to >= from ? 1.0 : -1.0,
                .dist = dist,
                .v_peak = v,
                .accel = accel,
                .t_acc = t_acc,
                .t_total = dist > 0.0 ? 2.0 * t_acc + d_cruise / v : 0.0,
        };
        return 0;
}

/* Distance covered after tau seconds into the profile, 0 <= tau <= t_total. */
static double covered(const struct motion *m, double tau)
{
        if (tau <= 0.0)
                return 0.0;
        if (tau >= m->t_total)
                return m->dist;
        if (tau < m->t_acc)
                return 0.5 * m->accel * tau * tau;
        double t_dec = m->t_total - m->t_acc;
        if (tau <= t_dec)
                return 0.5 * m->v_peak * m->t_acc + m->v_peak * (tau - m->t_acc);
        double rest = m->t_total - tau;
        return m->dist - 0.5 * m->accel * rest * rest;
}

double motion_position(const struct motion *m, double t)
{
        return m->from + m->dir * covered(m, t - m->t0);
}

double motion_velocity(const struct motion *m, double t)
{
        double tau = t - m->t0;
        if (tau <= 0.0 || tau >= m->t_total)
                return 0.0;
        double v = m->v_peak;
        if (tau < m->t_acc)
                v = m->accel * tau;
        else if (tau > m->t_total - m->t_acc)
                v = m->accel * (m->t_total - tau);
        return m->dir * v;
}

double motion_end_time(const struct motion *m)
{
        return m->t0 + m->t_total;
}

double motion_time_at(const struct motion *m, double dist)
{
        double d_acc = 0.5 * m->accel * m->t_acc * m->t_acc, tau;

        if (dist <= 0.0)
                return m->t0;
        if (dist >= m->dist)
                return m->t0 + m->t_total;
        if (dist < d_acc)
                tau = sqrt(2.0 * dist / m->accel);
        else if (dist <= m->dist - d_acc)
                tau = m->t_acc + (dist - d_acc) / m->v_peak;
        else
                tau = m->t_total - sqrt(2.0 * (m->dist - dist) / m->accel);
        return m->t0 + tau;
}

double motion_target(const struct motion *m)
{
        return m->from + m->dir * m->dist;
}

bool motion_moving(const struct motion *m, double t)
{
        return t < motion_end_time(m);
}

void motion_halt(struct motion *m, double t)
{
        motion_rest(m, t, motion_position(m, t));
}

double motion_duration(double dist, double vmax, double accel)
{
        struct motion m;

        if (motion_plan(&m, 0.0, 0.0, fabs(dist), vmax, accel) < 0)
                return 0.0;
        return m.t_total;
}
