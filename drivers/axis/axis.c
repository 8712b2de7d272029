/* axis.c - the rotary axis class: backend lookup, soft limits, logging wrappers and the
 * trapezoidal move-time model. Backends live in drivers/axis/<backend>/. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "common/log.h"
#include "drivers/axis/axis.h"
#include "drivers/bus/bus.h"
#include "drivers/registry.h"

int axis_log_full(struct axis *ax, int level, int err, const char *fmt, ...)
{
        const struct bus_dev_ref ref = {"axis",         ax->conf->name,
                                        ax->ops->name,  &ax->conf->backend.addr,
                                        ax->last_error, sizeof(ax->last_error)};
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_log_dev(ax->bus, &ref, level, err, fmt, ap);
        va_end(ap);
        return r;
}

int axis_set_cause(struct axis *ax, int err, const char *fmt, ...)
{
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_dev_cause(ax->cause, sizeof(ax->cause), err, fmt, ap);
        va_end(ap);
        return r;
}

/* Logs the failure of the op WHAT with the backend's cause, or strerror(r). */
static int fail(struct axis *ax, int r, const char *what)
{
        if (ax->cause[0])
                return axis_log_full(ax, GN_LOG_ERR, r, "Failed to %s: %s", what, ax->cause);
        return axis_log_full(ax, GN_LOG_ERR, r, "Failed to %s: %m", what);
}

int axis_new(const struct rig_axis_conf *conf, struct bus *bus, struct axis **ret)
{
        const struct axis_ops *ops;
        struct axis *ax;

        if (!conf || !bus || !ret)
                return -EINVAL;
        ops = registry_axis(conf->backend.name);
        if (!ops)
                return log_error_errno(SYNTHETIC_ERRNO(ENOENT), "axis '%s': Unknown backend '%s'",
                                       conf->name, conf->backend.name);
        ax = calloc(1, sizeof(*ax));
        if (!ax)
                return -ENOMEM;
        *ax = (struct axis){.ops = ops,
                            .conf = conf,
                            .bus = bus,
                            .speed = conf->max_speed,
                            .accel = conf->accel};
        *ret = ax;
        return 0;
}

struct axis *axis_free(struct axis *ax)
{
        if (!ax)
                return NULL;
        if (ax->ops->close)
                ax->ops->close(ax);
        free(ax);
        return NULL;
}

int axis_check_target(const struct axis *ax, double *deg)
{
        const struct rig_axis_conf *c = ax->conf;
        double d = *deg;

        if (!isfinite(d))
                return -ERANGE;
        if (c->continuous) {
                d = fmod(d, 360.0);
                if (d < 0)
                        d += 360.0;
                *deg = d >= 360.0 ? 0.0 : d;
                return 0;
        }
        return d < c->min_deg || d > c->max_deg ? -ERANGE : 0;
}

/* Runs one argument-less op and logs its failure as "Failed to WHAT: cause". */
static int call(struct axis *ax, int (*op)(struct axis *ax), const char *what)
{
        int r;

        if (!op)
                return axis_log_full(ax, GN_LOG_ERR, SYNTHETIC_ERRNO(EOPNOTSUPP),
                                     "Cannot %s: not supported by the backend", what);
        ax->cause[0] = '\0';
        r = op(ax);
        if (r < 0)
                return fail(ax, r, what);
        log_debug("axis '%s': %s", ax->conf->name, what);
        return 0;
}

int axis_open(struct axis *ax)
{
        int r;

        r = call(ax, ax->ops->open, "open");
        if (r < 0)
                return r;
        return axis_poll(ax);
}

int axis_home(struct axis *ax)
{
        return call(ax, ax->ops->home, "start homing");
}

int axis_stop(struct axis *ax)
{
        return call(ax, ax->ops->stop, "stop");
}

int axis_reset(struct axis *ax)
{
        return call(ax, ax->ops->reset, "reset the drive fault");
}

int axis_move_abs(struct axis *ax, double deg)
{
        double target = deg;
        int r;

        if (axis_check_target(ax, &target) < 0)
                return axis_log_full(ax, GN_LOG_ERR, SYNTHETIC_ERRNO(ERANGE),
                                     "Target %.3f deg outside the soft limits [%.3f, %.3f]", deg,
                                     ax->conf->min_deg, ax->conf->max_deg);
        ax->cause[0] = '\0';
        r = ax->ops->move_abs(ax, target);
        if (r < 0) {
                char what[64];
                snprintf(what, sizeof(what), "start a move to %.3f deg", target);
                return fail(ax, r, what);
        }
        log_debug("axis '%s': moving to %.3f deg", ax->conf->name, target);
        return 0;
}

int axis_poll(struct axis *ax)
{
        struct axis_state st = {};
        int r;

        ax->cause[0] = '\0';
        r = ax->ops->poll(ax, &st);
        if (r < 0)
                return fail(ax, r, "read the drive state");
        ax->state = st;
        return 0;
}

double axis_max_accel(const struct rig_axis_conf *c)
{
        return c->max_accel > 0 ? c->max_accel : c->accel;
}

int axis_set_rates(struct axis *ax, double deg_s, double accel)
{
        char what[96];
        int r = 0;

        deg_s = deg_s > 0 ? deg_s : ax->conf->max_speed;
        accel = accel > 0 ? accel : ax->conf->accel;
        if (deg_s > ax->conf->max_speed || accel > axis_max_accel(ax->conf))
                return -ERANGE;
        ax->cause[0] = '\0';
        if (ax->ops->set_rates)
                r = ax->ops->set_rates(ax, deg_s, accel);
        if (r < 0) {
                snprintf(what, sizeof(what),
                         "set the speed to %.3f deg/s, acceleration %.3f deg/s^2", deg_s, accel);
                return fail(ax, r, what);
        }
        ax->speed = deg_s;
        ax->accel = accel;
        return 0;
}

double axis_travel(const struct rig_axis_conf *c, double pos, double target)
{
        double d;

        if (!c->continuous)
                return target - pos;
        d = remainder(target - pos, 360.0); /* [-180, 180] */
        if (d <= -180.0)
                d += 360.0;
        if (c->direction > 0 && d < 0)
                d += 360.0;
        else if (c->direction < 0 && d > 0)
                d -= 360.0;
        return d;
}

double axis_takeup_target(const struct rig_axis_conf *c, double pos, double target)
{
        double d = axis_travel(c, pos, target), t;

        if (c->backlash_deg == 0 || (d > 0) == (c->backlash_deg > 0) || d == 0)
                return target;
        t = target - c->backlash_deg;
        if (c->continuous)
                t = fmod(fmod(t, 360.0) + 360.0, 360.0);
        return c->continuous ? t : fmin(fmax(t, c->min_deg), c->max_deg);
}

bool axis_within_deadband(const struct rig_axis_conf *c, double pos, double target)
{
        return c->deadband_deg <= 0 || fabs(axis_travel(c, pos, target)) <= c->deadband_deg;
}

double axis_move_time(double delta_deg, double max_speed, double accel)
{
        double d = fabs(delta_deg);

        if (!(max_speed > 0))
                return d > 0 ? INFINITY : 0.0;
        if (!(accel > 0) || isinf(accel))
                return d / max_speed;
        if (d >= max_speed * max_speed / accel) /* reaches full speed */
                return d / max_speed + max_speed / accel;
        return 2.0 * sqrt(d / accel);
}
