/* rig.c - the assembled rig inside goniod, driven asynchronously.
 *
 * DESIGN: the loop thread owns all rig state. An operation becomes a job on the
 * device's bus worker (drivers/bus); the job calls the blocking driver op and
 * the result returns to the loop. Moves and homing are then followed by poll
 * jobs on a per-axis one-shot timer until the drive reports in position, then a
 * settle timer. A stop bumps the axis's generation counter first, so a move job
 * still queued behind it is dropped on the worker instead of moving the axis
 * after the stop; the stopped axis is then followed until it stands still. Idle
 * drives are read back once a second, so motion nobody commanded (a drive still
 * moving when goniod restarted, a jog on the drive's panel) is seen and stopped.
 * Any device error latches a fault and sends the rig to its safe state (every
 * axis stopped, lamps and laser off). Exposures live in rig_expose.c, status and
 * describe in rig_json.c. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/registry.h"
#include "rig_internal.h"

#define POLL_USEC          (20 * 1000)
#define TRACK_POLL_USEC    (2 * 1000) /* a tracked axis: about as often as a bus answers */
#define NOTIFY_USEC        (100 * 1000)
#define IDLE_POLL_USEC     (1000 * 1000)
#define TIMER_ACCURACY     1000 /* usec: sd-event's default (250 ms) would delay every move */
#define OPEN_WAIT_USEC     (15 * 1000 * 1000ULL)
#define STOP_WAIT_USEC     (30 * 1000 * 1000ULL)
#define SHORT_GRACE_USEC   (200 * 1000) /* a drive may take this long to start moving */
#define SHORT_DEADBAND_DEG 0.05         /* farther than this from the target at rest: short */

static bool is_axis_job(enum job_kind kind)
{
        return kind <= J_RATES;
}

bool rig_is_camera_job(enum job_kind kind)
{
        return kind >= J_OPEN_CAM;
}

void rig_emit(struct rig *rig, const struct rig_event *ev)
{
        if (rig->notify)
                rig->notify(rig->notify_ud, ev);
}

void rig_update_state(struct rig *rig)
{
        const char *s = rig_state(rig);

        if (s != rig->last_state) {
                rig->last_state = s;
                rig_emit(rig, &(struct rig_event){.type = RIG_EVENT_STATE, .state = s});
        }
}

struct rig_switch *rig_switch_slot(struct rig *rig, int i)
{
        return i < 0 ? &rig->lasers[RIG_SW_LASER_OF(i)] : &rig->lamps[i];
}

const struct rig_switch_conf *rig_switch_conf_of(const struct rig_config *rc, int i)
{
        return i < 0 ? &rc->lasers[RIG_SW_LASER_OF(i)] : &rc->lamps[i];
}

static const char *switch_name(const struct rig *rig, int i)
{
        return rig_switch_conf_of(rig->rc, i)->name;
}

static const char *job_device(const struct job *j)
{
        const struct rig_config *rc = j->rig->rc;

        if (rig_is_camera_job(j->kind))
                return rc->cameras[j->idx].name;
        return is_axis_job(j->kind) ? rc->axes[j->idx].name : switch_name(j->rig, j->idx);
}

static const char *job_operation(const struct job *j)
{
        static const char *const names[] = {
                [J_OPEN_AXIS] = "open",      [J_HOME] = "home",
                [J_MOVE] = "move",           [J_POLL] = "read state",
                [J_STOP] = "stop",           [J_RESET] = "reset",
                [J_RATES] = "set rates",     [J_OPEN_SW] = "open",
                [J_CHECK_SW] = "read state", [J_SWITCH] = "switch",
                [J_OPEN_CAM] = "open",       [J_CAPTURE] = "capture",
                [J_PEEK] = "capture",        [J_STREAM_START] = "stream",
                [J_STREAM_NEXT] = "stream",  [J_STREAM_STOP] = "stop streaming",
        };
        return names[j->kind];
}

static struct bus *job_bus(const struct job *j)
{
        struct rig *rig = j->rig;

        if (rig_is_camera_job(j->kind))
                return rig->cams[j->idx]->bus;
        return is_axis_job(j->kind) ? rig->axes[j->idx].ax->bus
                                    : rig_switch_slot(rig, j->idx)->sw->bus;
}

/* After a successful open or reset, reads the drive's state into the job (worker). */
static int poll_after(struct job *j, struct rig_axis *a, int r)
{
        if (r >= 0)
                r = axis_poll(a->ax);
        if (r >= 0)
                j->st = a->ax->state;
        return r;
}

/* Runs on the bus worker: a move (or homing) at the job's rates, written to the drive when
 * they change. */
static int move_call(struct job *j, struct rig_axis *a)
{
        int r = 0;

        if (j->speed != a->ax->speed || j->accel != a->ax->accel)
                r = axis_set_rates(a->ax, j->speed, j->accel);
        if (r < 0)
                return r;
        return j->kind == J_HOME ? axis_home(a->ax) : axis_move_abs(a->ax, j->arg);
}

/* Runs on the bus worker: a read-back, timed mid-way through the drive's answer. */
static int poll_call(struct job *j, struct rig_axis *a)
{
        uint64_t t0 = gn_realtime_ns();
        int r = axis_poll(a->ax);

        j->rtt_ns = gn_realtime_ns() - t0;
        j->t_ns = t0 + j->rtt_ns / 2;
        j->st = a->ax->state;
        return r;
}

/* Runs on the bus worker: the blocking driver call for one job. */
static int job_call(struct bus *b, struct job *j)
{
        struct rig *rig = j->rig;
        struct rig_axis *a = is_axis_job(j->kind) ? &rig->axes[j->idx] : NULL;
        int r;

        switch (j->kind) {
        case J_OPEN_AXIS: /* open writes ax->speed and ax->accel */
                return poll_after(j, a, axis_open(a->ax));
        case J_HOME:
        case J_MOVE:
                if (j->gen != atomic_load(&a->gen))
                        return -ECANCELED;
                return move_call(j, a);
        case J_POLL:
                return poll_call(j, a);
        case J_STOP:
                return axis_stop(a->ax);
        case J_RESET:
                return poll_after(j, a, axis_reset(a->ax));
        case J_RATES:
                return axis_set_rates(a->ax, j->speed, j->accel);
        case J_OPEN_SW:
                r = sw_open(rig_switch_slot(rig, j->idx)->sw);
                return r < 0 ? r : sw_get(rig_switch_slot(rig, j->idx)->sw, &j->on);
        case J_CHECK_SW:
                return sw_get(rig_switch_slot(rig, j->idx)->sw, &j->on);
        case J_SWITCH:
                if (j->on && j->gen != atomic_load(&rig_switch_slot(rig, j->idx)->gen))
                        return -ECANCELED; /* queued before the safe state */
                return sw_set(rig_switch_slot(rig, j->idx)->sw, j->on);
        case J_OPEN_CAM:
                return cam_open(rig->cams[j->idx]);
        case J_CAPTURE:
                return cam_capture(rig->cams[j->idx], &j->creq, &j->frame);
        case J_PEEK:
        case J_STREAM_START:
        case J_STREAM_NEXT:
        case J_STREAM_STOP:
                return rig_stream_job_call(j);
        }
        return -EINVAL;
}

/* The device's own account of its last failure (device, operation, register, cause). */
static const char *device_error(const struct job *j)
{
        struct rig *rig = j->rig;

        if (is_axis_job(j->kind))
                return rig->axes[j->idx].ax->last_error;
        if (rig_is_camera_job(j->kind))
                return rig->cams[j->idx]->last_error;
        return rig_switch_slot(rig, j->idx)->sw->last_error;
}

/* Runs on the bus worker: the job, and the driver's message if it failed. */
static int job_run(struct bus *b, void *userdata)
{
        struct job *j = userdata;
        int r = job_call(b, j);

        if (r < 0 && r != -ECANCELED)
                snprintf(j->why, sizeof(j->why), "%s", device_error(j));
        return r;
}

static void job_done(struct bus *b, int result, void *userdata);

int rig_submit(struct job *j, bool urgent)
{
        int r;

        j->clear = j->rig->clear_collect;
        r = bus_submit(job_bus(j), job_run, job_done, j, urgent);
        if (r < 0) {
                gn_frame_free_data(&j->frame);
                free(j);
                return r;
        }
        j->rig->pending++;
        j->rig->clear_pending += j->clear;
        return 0;
}

int rig_submit_new(struct rig *rig, enum job_kind kind, int idx, double arg, bool on, bool urgent)
{
        struct job *j = calloc(1, sizeof(*j));

        if (!j)
                return -ENOMEM;
        *j = (struct job){.rig = rig, .kind = kind, .idx = idx, .arg = arg, .on = on};
        if (is_axis_job(kind)) {
                j->gen = atomic_load(&rig->axes[idx].gen);
                j->motions = rig->axes[idx].motions;
        }
        return rig_submit(j, urgent);
}

/* Queues switch job j (freed on failure). 0, or -errno: the job is dropped and its done will
 * never be called, so the caller must report the failure. */
static int switch_submit(struct rig *rig, struct job *j, bool urgent)
{
        struct rig_switch *s = rig_switch_slot(rig, j->idx);
        int r;

        s->changing++;
        j->gen = atomic_load(&s->gen);
        r = rig_submit(j, urgent);
        if (r < 0)
                s->changing--;
        return r;
}

static void axis_finish(struct rig_axis *a, int result, const char *msg);

void rig_safe_state(struct rig *rig)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                struct rig_axis *a = &rig->axes[i];
                bool moving = a->st.moving || a->op == AX_MOVING || a->op == AX_HOMING;

                atomic_fetch_add(&a->gen, 1);
                if (a->op == AX_MOVING || a->op == AX_HOMING)
                        axis_finish(a, -ECANCELED, "canceled: the rig goes to its safe state");
                if (a->open && moving)
                        rig_axis_stop_and_follow(a, "moves when the rig goes to its safe state");
                else if (a->open)
                        (void)rig_submit_new(rig, J_STOP, i, 0, false, true);
        }
        for (int i = -(int)rig->rc->n_lasers; i < (int)rig->rc->n_lamps; i++) {
                struct job *j;
                atomic_fetch_add(&rig_switch_slot(rig, i)->gen, 1);
                if (!rig_switch_slot(rig, i)->open || !(j = calloc(1, sizeof(*j))))
                        continue;
                *j = (struct job){.rig = rig, .kind = J_SWITCH, .idx = i, .on = false};
                (void)switch_submit(rig, j, true);
        }
}

/* Latches the first fault, tells clients, and goes to the safe state. A device that
 * fails while the rig is already faulted (e.g. during the safe state) is only logged,
 * so a dead bus cannot make the safe state loop. The fault is latched before the moves
 * it ends are answered, so clients see the fault, never an idle rig in between. */
void rig_fault(struct rig *rig, const char *device, int err, const char *fmt, ...)
{
        char msg[256];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        if (rig->fault) {
                log_warning("%s: %s (rig already in fault state)", device, msg);
                return;
        }
        log_error("fault on %s: %s; going to safe state", device, msg);
        rig->fault = true;
        snprintf(rig->fault_device, sizeof(rig->fault_device), "%s", device);
        snprintf(rig->fault_msg, sizeof(rig->fault_msg), "%s", msg);
        rig_emit(rig,
                 &(struct rig_event){
                         .type = RIG_EVENT_FAULT, .device = device, .error = err, .message = msg});
        rig_update_state(rig);
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].op != AX_IDLE)
                        axis_finish(&rig->axes[i], -EIO, msg);
        rig_safe_state(rig);
}

/* Records the message of a failed device operation for replies and faults: the
 * driver's own when it gave one, else device, operation and errno. */
static const char *job_error(struct job *j, int result)
{
        struct rig *rig = j->rig;

        if (j->why[0])
                return snprintf(rig->last_error, sizeof(rig->last_error), "%s", j->why),
                       rig->last_error;
        snprintf(rig->last_error, sizeof(rig->last_error), "%s '%s': %s failed: %s",
                 is_axis_job(j->kind)         ? "axis"
                 : rig_is_camera_job(j->kind) ? "camera"
                 : j->idx < 0                 ? "laser"
                                              : "lamp",
                 job_device(j), job_operation(j), strerror(-result));
        return rig->last_error;
}

static void notify_axis(struct rig_axis *a, enum rig_event_type type)
{
        rig_emit(a->rig, &(struct rig_event){.type = type,
                                             .device = a->ax->conf->name,
                                             .position = a->st.position_deg,
                                             .moving = a->st.moving});
}

/* Ends the running move/home/stop of a, calling its completion once. */
static void axis_finish(struct rig_axis *a, int result, const char *msg)
{
        rig_done_fn done = a->done;
        enum axis_op op = a->op;

        a->op = AX_IDLE;
        a->done = NULL;
        a->settling = false;
        sd_event_source_set_enabled(a->timer, SD_EVENT_OFF);
        if (result >= 0 && (op == AX_MOVING || op == AX_HOMING))
                notify_axis(a, RIG_EVENT_MOVE_DONE);
        if (done)
                done(a->rig, result, result < 0 ? msg : NULL, a->ud);
        rig_update_state(a->rig);
}

static void arm(struct rig_axis *a, uint64_t usec)
{
        if (usec == POLL_USEC && a->rig->track_axis == a->idx)
                usec = TRACK_POLL_USEC;
        sd_event_source_set_time_relative(a->timer, usec);
        sd_event_source_set_enabled(a->timer, SD_EVENT_ONESHOT);
}

/* Faults the rig on axis a and ends a's operation. rig_fault ends it when it latches the
 * fault, but not when the rig is in fault already (a stop followed during the safe state):
 * the operation would then wait forever for a poll nobody queues. */
static void axis_fault(struct rig_axis *a, int err, const char *msg)
{
        rig_fault(a->rig, a->ax->conf->name, err, "%s", msg);
        if (a->op != AX_IDLE)
                axis_finish(a, err, msg);
}

static uint64_t now_usec(struct rig *rig)
{
        uint64_t t = 0;

        sd_event_now(rig->event, CLOCK_MONOTONIC, &t);
        return t;
}

void rig_axis_stop_and_follow(struct rig_axis *a, const char *why)
{
        struct rig *rig = a->rig;

        log_warning("axis '%s' %s at %.3f deg: stopping it", a->ax->conf->name, why,
                    a->st.position_deg);
        atomic_fetch_add(&a->gen, 1);
        if (rig_submit_new(rig, J_STOP, a->idx, 0, false, true) < 0)
                return;
        a->op = AX_STOPPING;
        a->started = now_usec(rig);
        a->deadline = a->started + STOP_WAIT_USEC;
        rig_update_state(rig);
}

/* The acceleration of a move of a at speed (0: the settings'): a move at a speed of its own (a
 * continuous scan) keeps the rig file's, which its run-up was computed with. */
static double move_accel(const struct rig_axis *a, double speed)
{
        return speed > 0 ? a->ax->conf->accel : a->accel_setting;
}

/* Queues a homing (J_HOME) or a move of a to leg degrees at speed (0: the speed setting). */
static int submit_motion(struct rig_axis *a, enum job_kind kind, double leg, double speed)
{
        struct job *j = calloc(1, sizeof(*j));

        if (!j)
                return -ENOMEM;
        a->motions++;
        *j = (struct job){.rig = a->rig,
                          .kind = kind,
                          .idx = a->idx,
                          .arg = leg,
                          .speed = speed > 0 ? speed : a->speed_setting,
                          .accel = move_accel(a, speed),
                          .gen = atomic_load(&a->gen),
                          .motions = a->motions};
        return rig_submit(j, false);
}

/* Commands the next leg of the move of a (to leg degrees) and follows it. */
static void submit_leg(struct rig_axis *a, double leg)
{
        int r = submit_motion(a, J_MOVE, leg, a->speed);

        a->leg = leg;
        a->settling = false;
        a->started = now_usec(a->rig);
        if (r < 0)
                return axis_finish(a, r, "the drive's queue is full");
        arm(a, POLL_USEC);
}

/* The move of a ended away from its target: another try while retries are left
 * (approaching again past the backlash), else the move missed, which faults the rig. */
static void retry_or_miss(struct rig_axis *a, const char *why)
{
        const struct rig_axis_conf *c = a->ax->conf;
        char msg[256];

        if (a->retries_left > 0) {
                a->retries_left--;
                log_warning("axis '%s' %s at %.3f deg (target %.3f): retrying, %d left", c->name,
                            why, a->st.position_deg, a->target, a->retries_left);
                return submit_leg(a, axis_takeup_target(c, a->st.position_deg, a->target));
        }
        a->missed = true;
        snprintf(msg, sizeof(msg),
                 "axis '%s' missed its target %.3f deg: %s at %.3f deg after %d retries "
                 "(deadband %g deg)",
                 c->name, a->target, why, a->st.position_deg, c->move_retries, c->deadband_deg);
        axis_fault(a, -EIO, msg);
}

/* A leg of a move is in position and settled: the next leg, a retry, or done. */
static void leg_done(struct rig_axis *a)
{
        const struct rig_axis_conf *c = a->ax->conf;

        if (a->op != AX_MOVING)
                return axis_finish(a, 0, NULL);
        if (a->leg != a->target)
                return submit_leg(a, a->target);
        if (!axis_within_deadband(c, a->st.position_deg, a->target))
                return retry_or_miss(a, "ended outside the deadband");
        axis_finish(a, 0, NULL);
}

/* Decides, from a fresh poll, whether the move of a is done, failed or goes on. */
static void axis_progress(struct rig_axis *a)
{
        struct rig *rig = a->rig;
        bool arrived = !a->st.moving && a->st.in_position && (a->op != AX_HOMING || a->st.homed);
        const char *name = a->ax->conf->name;
        uint64_t now = now_usec(rig);
        char msg[256];

        if (a->st.fault) {
                snprintf(msg, sizeof(msg), "axis '%s': drive reports fault code %d at %.3f deg",
                         name, a->st.fault_code, a->st.position_deg);
                return axis_fault(a, -EIO, msg);
        }
        if (now - a->last_notify >= NOTIFY_USEC) {
                a->last_notify = now;
                notify_axis(a, RIG_EVENT_AXIS_MOVED);
        }
        if (a->op == AX_STOPPING && !a->st.moving)
                return axis_finish(a, 0, NULL);
        if (a->op != AX_STOPPING && arrived) {
                a->settling = true;
                return arm(a, a->ax->conf->settle_ms * 1000ULL);
        }
        if (a->op == AX_MOVING && !a->st.moving && !a->st.in_position &&
            now - a->started > SHORT_GRACE_USEC &&
            gn_angle_distance(a->st.position_deg, a->leg) > SHORT_DEADBAND_DEG)
                return retry_or_miss(a, "stopped short, not in position");
        if (now > a->deadline) {
                snprintf(msg, sizeof(msg),
                         "axis '%s': %s did not complete within %.1f s (at %.3f deg)", name,
                         a->op == AX_STOPPING ? "stop" : "move", (now - a->started) / 1e6,
                         a->st.position_deg);
                return axis_fault(a, -ETIMEDOUT, msg);
        }
        arm(a, POLL_USEC);
}

static int on_axis_timer(sd_event_source *s, uint64_t usec, void *userdata)
{
        struct rig_axis *a = userdata;

        if (a->op == AX_IDLE)
                return 0;
        if (a->settling)
                return leg_done(a), 0;
        if (rig_submit_new(a->rig, J_POLL, a->idx, 0, false, false) < 0)
                arm(a, POLL_USEC); /* queue full: try again */
        return 0;
}

/* A poll of an axis nobody is moving: record it, and stop motion nobody commanded. */
static void idle_poll_done(struct rig_axis *a)
{
        if (a->st.fault && !a->rig->fault)
                return rig_fault(a->rig, a->ax->conf->name, -EIO,
                                 "axis '%s': drive reports fault code %d at %.3f deg",
                                 a->ax->conf->name, a->st.fault_code, a->st.position_deg);
        if (a->st.moving && !a->rig->exposure)
                rig_axis_stop_and_follow(a, "moves although goniod did not command it");
}

/* True when err means the device no longer answers: it counts as closed until fault.clear
 * reopens it, so the safe state and idle polls do not wait for it again and again. */
static bool device_lost(int err)
{
        return err == -EIO || err == -ETIMEDOUT || err == -ENOENT || err == -ENODEV;
}

static void axis_job_failed(struct job *j, struct rig_axis *a, int result)
{
        const char *msg = job_error(j, result);

        if (device_lost(result))
                a->open = false; /* fault.clear reopens it */
        if (j->rig->fault && a->op == AX_IDLE && j->kind == J_POLL) {
                log_debug("%s (rig in fault state)", msg); /* idle polls: no log every second */
                return;
        }
        axis_fault(a, result, msg);
}

/* A move or homing the worker dropped (a stop bumped the generation after it was queued):
 * when it is the motion still running, nothing else would ever end it. */
static void motion_dropped(const struct job *j, struct rig_axis *a)
{
        if ((j->kind == J_MOVE || j->kind == J_HOME) && j->motions == a->motions &&
            (a->op == AX_MOVING || a->op == AX_HOMING))
                axis_finish(a, -ECANCELED, "canceled: a stop came before the drive took it");
}

/* A poll of a's running operation came back stale: makes sure another one follows, unless
 * the timer is armed already (the next poll or the settle time). */
static void keep_following(struct rig_axis *a)
{
        int on = SD_EVENT_OFF;

        if (sd_event_source_get_enabled(a->timer, &on) >= 0 && on == SD_EVENT_OFF)
                arm(a, POLL_USEC);
}

/* The rates of a were written to its drive, or not: the settings follow the drive. */
static void rates_done(struct job *j, struct rig_axis *a, int result)
{
        if (result >= 0) {
                a->speed_setting = j->speed;
                a->accel_setting = j->accel;
        }
        if (j->done)
                j->done(j->rig, result, result < 0 ? job_error(j, result) : NULL, j->ud);
        if (result < 0)
                axis_job_failed(j, a, result);
}

static void axis_job_done(struct job *j, int result)
{
        struct rig_axis *a = &j->rig->axes[j->idx];
        struct rig *rig = j->rig;

        if (j->kind == J_RATES)
                return rates_done(j, a, result);
        if (result >= 0 && (j->kind == J_POLL || j->kind == J_OPEN_AXIS || j->kind == J_RESET))
                a->st = j->st;
        if (result >= 0 && j->kind == J_POLL && rig->track_axis == j->idx && rig->track_fn)
                rig->track_fn(rig->track_ud, j->idx, j->st.position_deg, j->t_ns, j->rtt_ns);
        if (j->kind == J_OPEN_AXIS)
                a->open = result >= 0;
        if (j->kind == J_POLL && !j->exp)
                a->polling = false;
        if (result == -ECANCELED)
                return motion_dropped(j, a);
        if (result < 0)
                return axis_job_failed(j, a, result);
        if (j->kind == J_HOME || j->kind == J_MOVE || j->kind == J_STOP)
                arm(a, POLL_USEC);
        else if (j->kind == J_POLL && a->op != AX_IDLE && j->motions == a->motions)
                axis_progress(a);
        else if (j->kind == J_POLL && a->op != AX_IDLE)
                keep_following(a); /* an older poll saw the drive before its command */
        else if (a->op == AX_IDLE)
                idle_poll_done(a); /* also after open and reset */
}

struct later {
        struct rig *rig;
        struct rig_switch *s;
        rig_done_fn done;
        void *ud;
};

static void later_finish(struct later *l)
{
        l->s->changing--;
        rig_update_state(l->rig);
        if (l->done)
                l->done(l->rig, 0, NULL, l->ud);
        free(l);
}

static int on_later(sd_event_source *s, uint64_t usec, void *userdata)
{
        later_finish(userdata);
        sd_event_source_unref(s);
        return 0;
}

/* Ends the change of switch s after ms milliseconds (a lamp's warm-up), or now. */
static void finish_switch_later(struct rig *rig, struct rig_switch *s, int ms, rig_done_fn done,
                                void *ud)
{
        struct later *l = malloc(sizeof(*l));
        sd_event_source *src = NULL;

        if (!l) {
                s->changing--;
                if (done)
                        done(rig, 0, NULL, ud);
                return;
        }
        *l = (struct later){rig, s, done, ud};
        if (ms > 0 && sd_event_add_time_relative(rig->event, &src, CLOCK_MONOTONIC, ms * 1000ULL,
                                                 TIMER_ACCURACY, on_later, l) >= 0) {
                sd_event_source_set_description(src, "lamp-warmup");
                return;
        }
        later_finish(l);
}

/* A laser nobody here switched on (goniod restarted, a hand on the relay) goes off: only
 * a client or a session that owns it may have it on. */
static void laser_found_on(struct rig *rig, int i)
{
        struct job *j = calloc(1, sizeof(*j));

        log_warning("laser '%s' found on when opened: switching it off", switch_name(rig, i));
        if (!j)
                return;
        *j = (struct job){.rig = rig, .kind = J_SWITCH, .idx = i, .on = false};
        (void)switch_submit(rig, j, true);
}

struct limit {
        struct rig *rig;
        int idx;
};

static int on_limit(sd_event_source *src, uint64_t usec, void *userdata)
{
        struct limit *l = userdata;
        struct rig *rig = l->rig;
        int i = l->idx;
        struct rig_switch *s = rig_switch_slot(rig, i);
        struct job *j = calloc(1, sizeof(*j));

        log_warning("%s '%s' on for its max_on_s (%g s): switching it off",
                    i < 0 ? "laser" : "lamp", switch_name(rig, i), s->sw->conf->max_on_s);
        s->limit = sd_event_source_disable_unref(s->limit); /* frees l */
        if (j) {
                *j = (struct job){.rig = rig, .kind = J_SWITCH, .idx = i, .on = false};
                (void)switch_submit(rig, j, true);
        }
        return 0;
}

/* Arms switch i's limit of time on (its max_on_s, 0: none) when it went on, disarms it
 * when it went off. */
static void limit_on_time(struct rig *rig, int i, bool on)
{
        struct rig_switch *s = rig_switch_slot(rig, i);
        double max_on = s->sw->conf->max_on_s;
        struct limit *l;

        s->limit = sd_event_source_disable_unref(s->limit);
        if (!on || !(max_on > 0) || !(l = malloc(sizeof(*l))))
                return;
        *l = (struct limit){rig, i};
        if (sd_event_add_time_relative(rig->event, &s->limit, CLOCK_MONOTONIC,
                                       (uint64_t)(max_on * 1e6), TIMER_ACCURACY, on_limit, l) < 0) {
                log_warning("%s: cannot limit its time on: %m", switch_name(rig, i));
                free(l);
                return;
        }
        sd_event_source_set_destroy_callback(s->limit, free);
        sd_event_source_set_description(s->limit, "max-on");
}

static void switch_job_done(struct job *j, int result)
{
        struct rig *rig = j->rig;
        struct rig_switch *s = rig_switch_slot(rig, j->idx);
        const char *name = job_device(j);

        if (j->kind == J_OPEN_SW)
                s->open = result >= 0;
        if (j->kind == J_SWITCH && result < 0)
                s->changing--;
        if (result == -ECANCELED) { /* dropped at shutdown, not a device fault */
                if (j->done)
                        j->done(rig, result, "canceled", j->ud);
                return;
        }
        if (result < 0) {
                const char *msg = job_error(j, result);
                s->open = s->open && !device_lost(result);
                rig_fault(rig, name, result, "%s", msg);
                if (j->done)
                        j->done(rig, result, msg, j->ud);
                return;
        }
        if (j->kind == J_OPEN_SW && j->idx < 0 && j->on)
                laser_found_on(rig, j->idx);
        if (j->kind != J_SWITCH)
                return;
        rig_emit(rig, &(struct rig_event){.type = RIG_EVENT_SWITCH, .device = name, .on = j->on});
        limit_on_time(rig, j->idx, j->on);
        finish_switch_later(rig, s, j->on ? s->sw->conf->warmup_ms : 0, j->done, j->ud);
}

static void clear_finished(struct rig *rig)
{
        rig_done_fn done = rig->clear_done;

        rig->clear_done = NULL;
        rig_update_state(rig);
        if (done)
                done(rig, rig->fault ? -EIO : 0, rig->fault ? rig->fault_msg : NULL, rig->clear_ud);
}

static void job_done(struct bus *b, int result, void *userdata)
{
        struct job *j = userdata;
        struct rig *rig = j->rig;

        rig->pending--;
        if (j->exp)
                rig_expose_job_done(j, result);
        else if (j->kind == J_OPEN_CAM) {
                rig->cam_open[j->idx] = result >= 0;
                if (result < 0 && result != -ECANCELED)
                        rig_fault(rig, job_device(j), result, "%s", job_error(j, result));
        } else if (rig_is_camera_job(j->kind))
                rig_stream_job_done(j, result);
        else if (j->kind >= J_OPEN_SW)
                switch_job_done(j, result);
        else
                axis_job_done(j, result);
        if (j->clear && --rig->clear_pending == 0)
                clear_finished(rig);
        gn_frame_free_data(&j->frame);
        free(j);
}

static int start_motion(struct rig *rig, int i, enum axis_op op, double target, double speed,
                        rig_done_fn done, void *ud)
{
        struct rig_axis *a = &rig->axes[i];
        const struct rig_axis_conf *c = a->ax->conf;
        double t = axis_move_time(op == AX_HOMING ? 360 : fabs(target - a->st.position_deg),
                                  speed > 0 ? speed : a->speed_setting, move_accel(a, speed)),
               leg;
        int r;

        if (rig->closing)
                return -ESHUTDOWN;
        if (rig->fault)
                return -ESTALE;
        if (rig->exposure)
                return snprintf(rig->busy, sizeof(rig->busy), "a capture is being exposed"), -EBUSY;
        if (a->op != AX_IDLE)
                return snprintf(rig->busy, sizeof(rig->busy), "axis '%s' is %s", c->name,
                                a->op == AX_STOPPING ? "stopping" : "moving"),
                       -EBUSY;
        if (!a->open)
                return -ENODEV;
        leg = op == AX_HOMING ? 0 : axis_takeup_target(c, a->st.position_deg, target);
        r = submit_motion(a, op == AX_HOMING ? J_HOME : J_MOVE, leg, speed);
        if (r < 0)
                return r;
        a->op = op;
        a->speed = speed;
        a->target = target;
        a->leg = leg;
        a->retries_left = c->move_retries;
        a->missed = false;
        a->done = done;
        a->ud = ud;
        a->started = now_usec(rig);
        a->deadline = a->started + (c->move_timeout_ms ? c->move_timeout_ms * 1000ULL
                                                       : (uint64_t)(3 * t * 1e6) + 10000000) *
                                           (1 + (leg != target) + c->move_retries);
        rig_update_state(rig);
        return 0;
}

int rig_home(struct rig *rig, int i, rig_done_fn done, void *userdata)
{
        return start_motion(rig, i, AX_HOMING, 0, 0, done, userdata);
}

/* A move of axis i to *target (relative: by it) at speed (0: max_speed). */
static int move(struct rig *rig, int i, double *target, bool relative, double speed,
                rig_done_fn done, void *userdata)
{
        struct rig_axis *a = &rig->axes[i];
        double deg = *target;
        int r;

        if (!a->open)
                return -ENODEV;
        if (!a->st.homed && !a->ax->conf->absolute_encoder)
                return -EPERM;
        if (relative)
                deg += a->st.position_deg;
        r = axis_check_target(a->ax, &deg);
        if (r < 0)
                return r;
        *target = deg;
        return start_motion(rig, i, AX_MOVING, deg, speed, done, userdata);
}

int rig_move(struct rig *rig, int i, double *target, bool relative, rig_done_fn done,
             void *userdata)
{
        return move(rig, i, target, relative, 0, done, userdata);
}

bool rig_axis_speed_settable(const struct rig *rig, int i)
{
        return rig->axes[i].ax->ops->set_rates != NULL;
}

int rig_move_at(struct rig *rig, int i, double *target, double speed, rig_done_fn done,
                void *userdata)
{
        if (speed > 0 && !rig_axis_speed_settable(rig, i))
                return -EOPNOTSUPP;
        if (speed > rig->rc->axes[i].max_speed)
                return -ERANGE;
        return move(rig, i, target, false, speed, done, userdata);
}

void rig_track(struct rig *rig, int i, rig_track_fn fn, void *userdata)
{
        rig->track_axis = fn ? i : -1;
        rig->track_fn = fn;
        rig->track_ud = userdata;
}

size_t rig_stop(struct rig *rig, int *stopped)
{
        size_t n = 0;

        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                struct rig_axis *a = &rig->axes[i];
                char msg[128];

                atomic_fetch_add(&a->gen, 1);
                if (!a->open)
                        continue;
                if (a->op == AX_IDLE && !a->st.moving) {
                        (void)rig_submit_new(rig, J_STOP, i, 0, false, true);
                        continue;
                }
                if (stopped)
                        stopped[n] = i;
                n++;
                snprintf(msg, sizeof(msg), "%s of '%s' canceled by stop",
                         a->op == AX_HOMING ? "homing" : "move", a->ax->conf->name);
                if (a->op != AX_IDLE)
                        axis_finish(a, -ECANCELED, msg);
                rig_axis_stop_and_follow(a, "stop requested");
        }
        return n;
}

int rig_switch(struct rig *rig, int i, bool on, rig_done_fn done, void *userdata)
{
        struct job *j;

        if (i < 0 ? RIG_SW_LASER_OF(i) >= (int)rig->rc->n_lasers : i >= (int)rig->rc->n_lamps)
                return -ENOENT;
        if (on && rig->closing)
                return -ESHUTDOWN;
        if (on && rig->fault)
                return -ESTALE;
        if (rig->exposure)
                return snprintf(rig->busy, sizeof(rig->busy), "a capture is being exposed"), -EBUSY;
        if (!rig_switch_slot(rig, i)->open)
                return -ENODEV;
        j = calloc(1, sizeof(*j));
        if (!j)
                return -ENOMEM;
        *j = (struct job){
                .rig = rig, .kind = J_SWITCH, .idx = i, .on = on, .done = done, .ud = userdata};
        return switch_submit(rig, j, false);
}

int rig_check_camera_request(const struct rig *rig, int i, const struct cam_request *req, char *msg,
                             size_t len)
{
        return cam_check_request(rig->cams[i], req, msg, len);
}

const char *rig_busy_reason(const struct rig *rig)
{
        return rig->busy[0] ? rig->busy : "busy";
}

const char *rig_last_error(const struct rig *rig)
{
        return rig->fault ? rig->fault_msg : rig->last_error;
}

struct gn_pose rig_pose(const struct rig *rig)
{
        struct gn_pose p = gn_pose_none();

        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->rc->axes[i].role >= 0 &&
                    (rig->axes[i].st.homed || rig->rc->axes[i].absolute_encoder))
                        p.deg[rig->rc->axes[i].role] = rig->axes[i].st.position_deg;
        for (size_t i = 0; i < rig->rc->n_lamps && i < GN_POSE_MAX_LAMPS; i++)
                if (rig->lamps[i].sw->on)
                        p.lamps |= UINT32_C(1) << i;
        for (size_t i = 0; i < rig->rc->n_lasers; i++)
                if (rig->lasers[i].sw->on)
                        p.lasers |= UINT32_C(1) << i;
        return p;
}

static bool axes_idle(const struct rig *rig)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].op != AX_IDLE)
                        return false;
        return true;
}

/* Runs the loop until no job is in flight and no axis is being followed, or until
 * timeout. */
static void wait_idle(struct rig *rig, uint64_t timeout_usec)
{
        uint64_t end = now_usec(rig) + timeout_usec;

        while ((rig->pending > 0 || !axes_idle(rig)) && now_usec(rig) < end)
                if (sd_event_run(rig->event, 100 * 1000) < 0)
                        break;
}

/* Queues an open job for every device not open yet. */
static void open_devices(struct rig *rig)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (!rig->axes[i].open)
                        (void)rig_submit_new(rig, J_OPEN_AXIS, i, 0, false, false);
        for (size_t i = 0; i < rig->rc->n_lamps; i++)
                if (!rig->lamps[i].open)
                        (void)rig_submit_new(rig, J_OPEN_SW, i, 0, false, false);
        for (size_t i = 0; i < rig->rc->n_lasers; i++)
                if (!rig->lasers[i].open)
                        (void)rig_submit_new(rig, J_OPEN_SW, RIG_SW_LASER(i), 0, false, false);
        for (size_t i = 0; i < rig->rc->n_cameras; i++)
                if (!rig->cam_open[i])
                        (void)rig_submit_new(rig, J_OPEN_CAM, i, 0, false, false);
}

int rig_clear_fault(struct rig *rig, rig_done_fn done, void *userdata)
{
        if (rig->closing)
                return -ESHUTDOWN;
        if (rig->clear_done)
                return -EBUSY;
        rig->fault = false;
        rig->fault_msg[0] = rig->fault_device[0] = rig->last_error[0] = 0;
        rig->clear_done = done;
        rig->clear_ud = userdata;
        rig->clear_collect = true;
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].open)
                        (void)rig_submit_new(rig, J_RESET, i, 0, false, false);
        for (int i = -(int)rig->rc->n_lasers; i < (int)rig->rc->n_lamps; i++)
                if (rig_switch_slot(rig, i)->open)
                        (void)rig_submit_new(rig, J_CHECK_SW, i, 0, false, false);
        open_devices(rig);
        rig->clear_collect = false;
        if (rig->clear_pending == 0)
                clear_finished(rig);
        return 0;
}

int rig_override_fault(struct rig *rig)
{
        if (rig->closing)
                return -ESHUTDOWN;
        if (!rig->fault)
                return 0;
        if (rig->clear_done || rig->pending)
                return -EBUSY;
        log_warning("fault on %s overridden by an admin (%s); devices that failed stay out of "
                    "service",
                    rig->fault_device, rig->fault_msg);
        rig->fault = false;
        rig->fault_msg[0] = rig->fault_device[0] = 0;
        rig_update_state(rig);
        return 0;
}

/* Reads idle drives back, so status is true and uncommanded motion is seen. */
static int on_idle_poll(sd_event_source *s, uint64_t usec, void *userdata)
{
        struct rig *rig = userdata;

        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                struct rig_axis *a = &rig->axes[i];
                if (a->open && a->op == AX_IDLE && !a->polling && !rig->exposure &&
                    rig_submit_new(rig, J_POLL, i, 0, false, false) >= 0)
                        a->polling = true;
        }
        sd_event_source_set_time_relative(s, IDLE_POLL_USEC);
        return 0;
}

static struct bus *bus_of(struct rig *rig, const char *name)
{
        for (size_t i = 0; i < rig->rc->n_buses; i++)
                if (strcmp(rig->rc->buses[i].name, name) == 0)
                        return rig->buses[i];
        return NULL;
}

static int build_axis(struct rig *rig, size_t i)
{
        struct rig_axis *a = &rig->axes[i];
        const struct rig_axis_conf *c = &rig->rc->axes[i];
        int r;

        *a = (struct rig_axis){
                .rig = rig, .idx = i, .speed_setting = c->max_speed, .accel_setting = c->accel};
        if ((r = axis_new(c, bus_of(rig, c->bus), &a->ax)) < 0 ||
            (r = sd_event_add_time_relative(rig->event, &a->timer, CLOCK_MONOTONIC, 0,
                                            TIMER_ACCURACY, on_axis_timer, a)) < 0)
                return log_error_errno(r, "axis '%s': %m", c->name);
        sd_event_source_set_enabled(a->timer, SD_EVENT_OFF);
        sd_event_source_set_description(a->timer, "axis-poll");
        return 0;
}

static int build_devices(struct rig *rig)
{
        struct rig_config *rc = rig->rc;
        int r;

        for (size_t i = 0; i < rc->n_buses; i++)
                if ((r = bus_new(rig->event, &rc->buses[i], &rig->buses[i])) < 0)
                        return log_error_errno(r, "bus '%s': %m", rc->buses[i].name);
        for (size_t i = 0; i < rc->n_axes; i++)
                if ((r = build_axis(rig, i)) < 0)
                        return r;
        for (size_t i = 0; i < rc->n_lamps; i++)
                if ((r = sw_new(&rc->lamps[i], bus_of(rig, rc->lamps[i].bus), &rig->lamps[i].sw)) <
                    0)
                        return log_error_errno(r, "lamp '%s': %m", rc->lamps[i].name);
        for (size_t i = 0; i < rc->n_lasers; i++)
                if ((r = sw_new(&rc->lasers[i], bus_of(rig, rc->lasers[i].bus),
                                &rig->lasers[i].sw)) < 0)
                        return log_error_errno(r, "laser '%s': %m", rc->lasers[i].name);
        for (size_t i = 0; i < rc->n_cameras; i++)
                if ((r = cam_new(&rc->cameras[i], bus_of(rig, rc->cameras[i].bus), &rig->cams[i])) <
                    0)
                        return log_error_errno(r, "camera '%s': %m", rc->cameras[i].name);
        r = sd_event_add_time_relative(rig->event, &rig->idle_poll, CLOCK_MONOTONIC, IDLE_POLL_USEC,
                                       10 * TIMER_ACCURACY, on_idle_poll, rig);
        if (r < 0)
                return r;
        sd_event_source_set_enabled(rig->idle_poll, SD_EVENT_ON);
        return sd_event_source_set_description(rig->idle_poll, "axis-idle-poll");
}

int rig_new(sd_event *event, struct rig_config *rc, rig_event_fn notify, void *userdata,
            struct rig **ret)
{
        struct rig *rig = calloc(1, sizeof(*rig));
        int r;

        if (!rig)
                return -ENOMEM;
        rig->event = event;
        rig->rc = rc;
        rig->track_axis = -1;
        r = build_devices(rig);
        if (r < 0) {
                rig_free(rig);
                return r;
        }
        open_devices(rig);
        wait_idle(rig, OPEN_WAIT_USEC);
        rig->notify = notify;
        rig->notify_ud = userdata;
        rig->last_state = rig_state(rig);
        *ret = rig;
        return 0;
}

struct rig *rig_free(struct rig *rig)
{
        if (!rig)
                return NULL;
        rig->notify = NULL;
        rig->freeing = true;
        rig_expose_abandon(rig);
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].op != AX_IDLE)
                        axis_finish(&rig->axes[i], -ECANCELED, "daemon is shutting down");
        /* After a normal shutdown the manager has reached the safe state and the loop has
         * finished; otherwise (a failed start) reach it here while the loop can still run. */
        if (rig->buses[0] && sd_event_get_state(rig->event) != SD_EVENT_FINISHED) {
                rig_safe_state(rig);
                wait_idle(rig, 5 * 1000 * 1000ULL);
        }
        for (size_t i = 0; i < rig->rc->n_buses; i++)
                rig->buses[i] = bus_free(rig->buses[i]); /* drops what is still queued */
        sd_event_source_disable_unref(rig->idle_poll);
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                sd_event_source_disable_unref(rig->axes[i].timer);
                axis_free(rig->axes[i].ax);
        }
        for (int i = -(int)rig->rc->n_lasers; i < (int)rig->rc->n_lamps; i++) {
                struct rig_switch *s = rig_switch_slot(rig, i);
                s->limit = sd_event_source_disable_unref(s->limit);
                sw_free(s->sw);
        }
        for (size_t i = 0; i < rig->rc->n_cameras; i++)
                cam_free(rig->cams[i]);
        free(rig);
        return NULL;
}

void rig_shutdown(struct rig *rig)
{
        rig->closing = true;
        rig_safe_state(rig);
}

unsigned rig_pending(const struct rig *rig)
{
        return rig->pending;
}

const char *rig_state(const struct rig *rig)
{
        bool homing = false, moving = false, stopping = false;

        if (rig->fault)
                return "fault";
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                homing = homing || rig->axes[i].op == AX_HOMING;
                moving = moving || rig->axes[i].op == AX_MOVING;
                stopping = stopping || rig->axes[i].op == AX_STOPPING;
        }
        return homing          ? "homing"
               : moving        ? "moving"
               : stopping      ? "stopping"
               : rig->exposure ? "capturing"
                               : "idle";
}

int rig_axis_index(const struct rig *rig, const char *name)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (strcmp(rig->rc->axes[i].name, name) == 0)
                        return i;
        return -ENOENT;
}

int rig_lamp_index(const struct rig *rig, const char *name)
{
        char *end;
        long v = strtol(name, &end, 10);

        if (*name && !*end)
                return v >= 0 && (size_t)v < rig->rc->n_lamps ? (int)v : -ENOENT;
        for (size_t i = 0; i < rig->rc->n_lamps; i++)
                if (strcmp(rig->rc->lamps[i].name, name) == 0)
                        return i;
        return -ENOENT;
}

int rig_camera_index(const struct rig *rig, const char *name)
{
        for (size_t i = 0; i < rig->rc->n_cameras; i++)
                if (strcmp(rig->rc->cameras[i].name, name) == 0)
                        return i;
        return -ENOENT;
}

const struct rig_config *rig_config(const struct rig *rig)
{
        return rig->rc;
}
