/* api.c - the "gcode" axis backend: one axis (X, Y or Z) of a serial G-code controller,
 * the Horus/Ciclop board or GRBL 1.1 (docs/gcode.md), through the line session shared
 * with the other devices of the board (link.h). Runs on the bus worker.
 *
 * BEWARE: the Horus firmware answers a move only when it has ended; the move is sent
 * asynchronously and its "ok" read by later polls. GRBL answers as soon as the move is
 * queued, and only its status reports say when it has ended. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "common/log.h"
#include "drivers/axis/gcode/link.h"
#include "drivers/axis/gcode/proto.h"
#include "drivers/transport/transport.h"

/* Feed in deg/min when the rig file gives no max_speed. */
#define GCAX_FEED_DEFAULT 600.0

struct gcax {
        const struct gcax_conf *conf; /* borrowed from the rig config */
        struct gclink *link;
        bool stopped; /* the last move or homing was stopped: not in position */
};

static const struct opt_desc gcax_opts[] = {
        {OPT_POSITION, OPT_GET | OPT_SET, .unit = "deg"},
        {OPT_HOME, OPT_SET},
        {OPT_STOP, OPT_SET},
};

static struct gcax *priv(const struct axis *ax)
{
        return ax->priv;
}

/* A failed link call: its cause, kept for the class's message. Returns r. */
static int link_result(struct axis *ax, int r)
{
        if (r >= 0)
                return r;
        return axis_set_cause(ax, r, "%s", gclink_cause(priv(ax)->link));
}

static int command(struct axis *ax, const char *line)
{
        if (!ax->priv)
                return -ENOTCONN;
        return link_result(ax, gclink_command(priv(ax)->link, line));
}

static bool is_horus(const struct axis *ax)
{
        return priv(ax)->conf->flavor == GC_FLAVOR_HORUS;
}

static int gcax_open(struct axis *ax)
{
        const struct gcax_conf *c = ax->conf->backend.conf;
        struct gcax *m;
        int r;

        if (!c)
                return axis_set_cause(ax, SYNTHETIC_ERRNO(EINVAL),
                                      "no G-code settings (not loaded from a rig file)");
        if (!ax->priv) {
                m = calloc(1, sizeof(*m));
                if (!m)
                        return -ENOMEM;
                *m = (struct gcax){.conf = c};
                r = gclink_attach(ax->bus, c->flavor, &m->link);
                if (r < 0) {
                        free(m);
                        return axis_set_cause(ax, r, "%s", transport_cause(bus_transport(ax->bus)));
                }
                ax->priv = m;
        }
        return link_result(ax, gclink_sync(priv(ax)->link));
}

static void gcax_close(struct axis *ax)
{
        struct gcax *m = ax->priv;

        if (!m)
                return;
        free(m);
        ax->priv = NULL;
}

/* Horus: powers the stepper (M17) unless it is on since the last reset. */
static int motor_on(struct axis *ax)
{
        struct gclink *l = priv(ax)->link;
        int r;

        if (!is_horus(ax) || l->motor_on)
                return 0;
        r = command(ax, "M17");
        if (r >= 0)
                l->motor_on = true;
        return r;
}

/* Horus has no homing switch: G50 makes the current position the origin. GRBL runs its
 * homing cycle ($H), answered when it has ended. */
static int gcax_home(struct axis *ax)
{
        int r;

        if (!ax->priv)
                return -ENOTCONN;
        priv(ax)->stopped = false;
        if (!is_horus(ax))
                return link_result(ax, gclink_command_async(priv(ax)->link, "$H", true));
        r = motor_on(ax);
        if (r >= 0)
                r = command(ax, "G50");
        if (r >= 0)
                priv(ax)->link->homed = true;
        return r;
}

/* The target in the controller's linear coordinate: for a continuous axis, where it is
 * plus the travel the axis class chose. */
static int target_of(struct axis *ax, double deg, double *ret)
{
        struct gc_status st;
        int r;

        *ret = deg;
        if (!ax->conf->continuous)
                return 0;
        r = link_result(ax, gclink_status(priv(ax)->link, &st));
        if (r >= 0)
                *ret = st.mpos[priv(ax)->conf->axis] +
                       axis_travel(ax->conf, st.mpos[priv(ax)->conf->axis], deg);
        return r;
}

static int gcax_move_abs(struct axis *ax, double deg)
{
        double feed = ax->speed > 0 ? ax->speed * 60.0 : GCAX_FEED_DEFAULT;
        char line[GC_LINE_MAX];
        double target;
        int r;

        if (!ax->priv)
                return -ENOTCONN;
        r = motor_on(ax);
        if (r >= 0)
                r = target_of(ax, deg, &target);
        if (r < 0)
                return r;
        r = gc_format_move(line, sizeof(line), priv(ax)->conf->axis, target, feed);
        if (r < 0)
                return axis_set_cause(ax, r, "cannot write a move to %.3f deg", target);
        priv(ax)->stopped = false;
        if (is_horus(ax))
                return link_result(ax, gclink_command_async(priv(ax)->link, line, false));
        return command(ax, line);
}

/* GRBL: waits for the feed hold to complete (Hold:0) or the axis to be idle, within the
 * time to brake from full speed plus the reply timeout; *held: motion was stopped. */
static int wait_held(struct axis *ax, bool *held)
{
        double brake_s = ax->accel > 0 ? ax->speed / ax->accel : 1.0;
        int64_t deadline = transport_deadline((int)(brake_s * 1000.0) + 1000);
        struct gc_status st;
        int r;

        do {
                r = link_result(ax, gclink_status(priv(ax)->link, &st));
                if (r < 0)
                        return r;
                *held = *held || st.state == GC_ST_HELD || st.state == GC_ST_HOLD ||
                        st.state == GC_ST_HOME;
                /* a hold does not stop homing: the reset below does (in alarm) */
                if (st.state == GC_ST_HELD || st.state == GC_ST_IDLE || st.state == GC_ST_ALARM ||
                    st.state == GC_ST_HOME)
                        return 0;
        } while (transport_deadline(0) < deadline);
        return 0; /* the reset below stops it anyway, in alarm */
}

/* GRBL: feed hold, then reset once held (no alarm, position kept). Horus has no hold
 * that keeps its "ok" protocol usable: reset, then unlock the alarm the reset of a move
 * raises ($X). */
static int gcax_stop(struct axis *ax)
{
        struct gclink *l;
        bool held;
        int r = 0;

        if (!ax->priv)
                return -ENOTCONN;
        l = priv(ax)->link;
        /* a stop at rest leaves the axis in position */
        held = ax->state.moving || l->owed > 0;
        if (!is_horus(ax)) {
                r = link_result(ax, gclink_realtime(l, GC_RT_HOLD));
                if (r >= 0)
                        r = wait_held(ax, &held);
        }
        priv(ax)->stopped = priv(ax)->stopped || held;
        if (r >= 0)
                r = link_result(ax, gclink_reset(l));
        if (r >= 0 && is_horus(ax) && l->alarm)
                r = command(ax, "$X");
        return r;
}

static int gcax_reset(struct axis *ax)
{
        struct gclink *l;
        int r;

        if (!ax->priv)
                return -ENOTCONN;
        l = priv(ax)->link;
        r = link_result(ax, gclink_reset(l));
        if (r >= 0 && is_horus(ax) && l->alarm)
                r = command(ax, "$X");
        return r;
}

static bool state_moving(enum gc_state s)
{
        return s == GC_ST_RUN || s == GC_ST_HOLD || s == GC_ST_HOME;
}

static int gcax_poll(struct axis *ax, struct axis_state *st)
{
        struct gc_status gs;
        struct gclink *l;
        double pos;
        int r;

        if (!ax->priv)
                return -ENOTCONN;
        l = priv(ax)->link;
        r = link_result(ax, gclink_sync(l));
        if (r >= 0)
                r = link_result(ax, gclink_status(l, &gs));
        if (r < 0)
                return r;
        pos = gs.mpos[priv(ax)->conf->axis];
        *st = (struct axis_state){
                .position_deg = ax->conf->continuous ? gc_wrap(pos) : pos,
                .enabled = !is_horus(ax) || l->motor_on,
                .homed = l->homed,
                .moving = l->owed > 0 || state_moving(gs.state),
                .fault = l->async_error < 0 || l->alarm_code != 0,
        };
        st->fault_code = st->fault ? (l->alarm_code > 0 ? l->alarm_code : 1) : 0;
        st->in_position = !st->moving && gs.state == GC_ST_IDLE && !priv(ax)->stopped && !st->fault;
        return 0;
}

const struct rig_backend gcax_backend = {
        .name = "gcode",
        .cls = RIG_CLASS_AXIS,
        .bus_types = 1u << RIG_BUS_SERIAL,
        .conf_size = sizeof(struct gcax_conf),
        .parse_conf = gcax_parse_conf,
        .ops = &gcax_ops,
};

const struct axis_ops gcax_ops = {
        .name = "gcode",
        .opts = gcax_opts,
        .n_opts = ELEMENTSOF(gcax_opts),
        .open = gcax_open,
        .close = gcax_close,
        .home = gcax_home,
        .move_abs = gcax_move_abs,
        .stop = gcax_stop,
        .reset = gcax_reset,
        .poll = gcax_poll,
};
