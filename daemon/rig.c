/* rig.c - the assembled rig inside goniod, driven asynchronously.
 *
 * DESIGN: the loop thread owns all rig state. An operation becomes a job on the
 * device's bus worker (drivers/bus); the job calls the blocking driver op and
 * the result returns to the loop. Moves and homing are then followed by poll
 * jobs on a per-axis one-shot timer until the drive reports in position, then a
 * settle timer. A stop bumps the axis's generation counter first, so a move job
 * still queued behind it is dropped on the worker instead of moving the axis
 * after the stop. Any device error latches a fault and sends the rig to its safe
 * state (every axis stopped, lamps and laser off). */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <systemd/sd-event.h>

#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/registry.h"
#include "protocol/proto.h"
#include "rig.h"

#define POLL_USEC      (20 * 1000)
#define NOTIFY_USEC    (200 * 1000)
#define OPEN_WAIT_USEC (15 * 1000 * 1000ULL)

enum axis_op { AX_IDLE, AX_MOVING, AX_HOMING };

struct rig_axis {
        struct rig *rig;
        int idx;
        struct axis *ax;
        struct axis_state st; /* last state seen by the loop */
        bool open;
        enum axis_op op;
        atomic_uint gen; /* bumped by stop; queued moves of older generations are dropped */
        rig_done_fn done;
        void *ud;
        sd_event_source *timer;
        uint64_t deadline, last_notify;
        bool settling;
};

struct rig_switch {
        struct sw *sw;
        bool open;
};

struct rig {
        sd_event *event;
        struct rig_config *rc;
        struct bus *buses[RIG_MAX_BUSES];
        struct rig_axis axes[RIG_MAX_AXES];
        struct rig_switch lamps[RIG_MAX_LAMPS], laser;
        struct cam *cams[RIG_MAX_CAMERAS];
        bool cam_open[RIG_MAX_CAMERAS];
        unsigned pending;  /* jobs in flight */
        unsigned captures; /* captures in flight */
        rig_notify_fn notify;
        void *notify_ud;
        bool fault;
        char fault_device[RIG_NAME_MAX];
        char fault_msg[256];
        const char *last_state;
        /* fault.clear in progress: its jobs are counted, done runs when the last ends */
        bool clear_collect;
        unsigned clear_pending;
        rig_done_fn clear_done;
        void *clear_ud;
};

/* Axis jobs come first: is_axis_job() relies on the order. */
enum job_kind {
        J_OPEN_AXIS,
        J_HOME,
        J_MOVE,
        J_POLL,
        J_STOP,
        J_RESET,
        J_OPEN_SW,
        J_CHECK_SW,
        J_SWITCH,
        J_OPEN_CAM,
        J_CAPTURE
};

struct job {
        struct rig *rig;
        enum job_kind kind;
        int idx; /* device index; -1 = the laser for switch jobs */
        unsigned gen;
        double arg;
        bool on;
        struct axis_state st;
        struct cam_request creq;
        struct gn_frame frame;
        rig_done_fn done;
        rig_frame_fn frame_done;
        void *ud;
        bool clear; /* part of a fault.clear */
};

static bool is_axis_job(enum job_kind kind)
{
        return kind <= J_RESET;
}

static void emit(struct rig *rig, const char *method, json_t *params)
{
        if (rig->notify)
                rig->notify(rig->notify_ud, method, params);
        else
                json_decref(params);
}

static void update_state(struct rig *rig)
{
        const char *s = rig_state(rig);

        if (s != rig->last_state) {
                rig->last_state = s;
                emit(rig, "state.changed", json_pack("{ss}", "state", s));
        }
}

static struct rig_switch *switch_slot(struct rig *rig, int i)
{
        return i < 0 ? &rig->laser : &rig->lamps[i];
}

static const char *job_device(const struct job *j)
{
        const struct rig_config *rc = j->rig->rc;

        switch (j->kind) {
        case J_OPEN_SW:
        case J_CHECK_SW:
        case J_SWITCH:
                return j->idx < 0 ? rc->laser.name : rc->lamps[j->idx].name;
        case J_OPEN_CAM:
        case J_CAPTURE:
                return rc->cameras[j->idx].name;
        default:
                return rc->axes[j->idx].name;
        }
}

static struct bus *job_bus(const struct job *j)
{
        struct rig *rig = j->rig;

        switch (j->kind) {
        case J_OPEN_SW:
        case J_CHECK_SW:
        case J_SWITCH:
                return switch_slot(rig, j->idx)->sw->bus;
        case J_OPEN_CAM:
        case J_CAPTURE:
                return rig->cams[j->idx]->bus;
        default:
                return rig->axes[j->idx].ax->bus;
        }
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

/* Runs on the bus worker: the blocking driver call for one job. */
static int job_run(struct bus *b, void *userdata)
{
        struct job *j = userdata;
        struct rig *rig = j->rig;
        struct rig_axis *a = is_axis_job(j->kind) ? &rig->axes[j->idx] : NULL;
        int r;

        switch (j->kind) {
        case J_OPEN_AXIS:
                return poll_after(j, a, axis_open(a->ax));
        case J_HOME:
        case J_MOVE:
                if (j->gen != atomic_load(&a->gen))
                        return -ECANCELED;
                return j->kind == J_HOME ? axis_home(a->ax) : axis_move_abs(a->ax, j->arg);
        case J_POLL:
                r = axis_poll(a->ax);
                j->st = a->ax->state;
                return r;
        case J_STOP:
                return axis_stop(a->ax);
        case J_RESET:
                return poll_after(j, a, axis_reset(a->ax));
        case J_OPEN_SW:
                r = sw_open(switch_slot(rig, j->idx)->sw);
                return r < 0 ? r : sw_get(switch_slot(rig, j->idx)->sw, &j->on);
        case J_CHECK_SW:
                return sw_get(switch_slot(rig, j->idx)->sw, &j->on);
        case J_SWITCH:
                return sw_set(switch_slot(rig, j->idx)->sw, j->on);
        case J_OPEN_CAM:
                return cam_open(rig->cams[j->idx]);
        case J_CAPTURE:
                return cam_capture(rig->cams[j->idx], &j->creq, &j->frame);
        }
        return -EINVAL;
}

static void job_done(struct bus *b, int result, void *userdata);

static int submit(struct job *j, bool urgent)
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

static int submit_new(struct rig *rig, enum job_kind kind, int idx, double arg, bool on,
                      bool urgent)
{
        struct job *j = calloc(1, sizeof(*j));

        if (!j)
                return -ENOMEM;
        *j = (struct job){.rig = rig, .kind = kind, .idx = idx, .arg = arg, .on = on};
        if (is_axis_job(kind))
                j->gen = atomic_load(&rig->axes[idx].gen);
        return submit(j, urgent);
}

void rig_safe_state(struct rig *rig)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                atomic_fetch_add(&rig->axes[i].gen, 1);
                if (rig->axes[i].open)
                        (void)submit_new(rig, J_STOP, i, 0, false, true);
        }
        if (rig->rc->has_laser && rig->laser.open)
                (void)submit_new(rig, J_SWITCH, -1, 0, false, true);
        for (size_t i = 0; i < rig->rc->n_lamps; i++)
                if (rig->lamps[i].open)
                        (void)submit_new(rig, J_SWITCH, i, 0, false, true);
}

static void axis_finish(struct rig_axis *a, int result, const char *msg);

/* Latches the first fault, tells clients, and goes to the safe state. A device that
 * fails while the rig is already faulted (e.g. during the safe state) is only logged,
 * so a dead bus cannot make the safe state loop. */
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
        emit(rig, "fault",
             json_pack("{sssiss}", "device", device, "code", proto_errno_to_code(err), "message",
                       msg));
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].op != AX_IDLE)
                        axis_finish(&rig->axes[i], -EIO, msg);
        rig_safe_state(rig);
        update_state(rig);
}

static void notify_axis(struct rig_axis *a, const char *method)
{
        emit(a->rig, method,
             json_pack("{sssfsb}", "axis", a->ax->conf->name, "position", a->st.position_deg,
                       "moving", a->st.moving));
}

/* Ends the running move/home of a, calling its completion once. */
static void axis_finish(struct rig_axis *a, int result, const char *msg)
{
        rig_done_fn done = a->done;
        enum axis_op op = a->op;

        a->op = AX_IDLE;
        a->done = NULL;
        a->settling = false;
        sd_event_source_set_enabled(a->timer, SD_EVENT_OFF);
        if (result >= 0 && op != AX_IDLE)
                notify_axis(a, "move.done");
        if (done)
                done(a->rig, result, result < 0 ? msg : NULL, a->ud);
        update_state(a->rig);
}

static void arm(struct rig_axis *a, uint64_t usec)
{
        sd_event_source_set_time_relative(a->timer, usec);
        sd_event_source_set_enabled(a->timer, SD_EVENT_ONESHOT);
}

static uint64_t now_usec(struct rig *rig)
{
        uint64_t t = 0;

        sd_event_now(rig->event, CLOCK_MONOTONIC, &t);
        return t;
}

/* Decides, from a fresh poll, whether the move of a is done, failed or goes on. */
static void axis_progress(struct rig_axis *a)
{
        struct rig *rig = a->rig;
        bool arrived = !a->st.moving && a->st.in_position && (a->op != AX_HOMING || a->st.homed);
        uint64_t now = now_usec(rig);

        if (a->st.fault)
                return rig_fault(rig, a->ax->conf->name, -EIO, "drive reports fault code %d",
                                 a->st.fault_code);
        if (now - a->last_notify >= NOTIFY_USEC) {
                a->last_notify = now;
                notify_axis(a, "axis.moved");
        }
        if (arrived) {
                a->settling = true;
                return arm(a, a->ax->conf->settle_ms * 1000ULL);
        }
        if (now > a->deadline) {
                axis_finish(a, -ETIMEDOUT, "the axis did not reach its target in time");
                return rig_fault(rig, a->ax->conf->name, -ETIMEDOUT,
                                 "move did not complete in time");
        }
        arm(a, POLL_USEC);
}

static int on_axis_timer(sd_event_source *s, uint64_t usec, void *userdata)
{
        struct rig_axis *a = userdata;
        int r;

        if (a->op == AX_IDLE)
                return 0;
        if (a->settling)
                return axis_finish(a, 0, NULL), 0;
        r = submit_new(a->rig, J_POLL, a->idx, 0, false, false);
        if (r < 0)
                arm(a, POLL_USEC); /* queue full: try again */
        return 0;
}

static void axis_job_done(struct job *j, int result)
{
        struct rig_axis *a = &j->rig->axes[j->idx];
        const char *name = a->ax->conf->name;

        if (result >= 0 && (j->kind == J_POLL || j->kind == J_OPEN_AXIS || j->kind == J_RESET))
                a->st = j->st;
        if (j->kind == J_OPEN_AXIS)
                a->open = result >= 0;
        if (result == -ECANCELED || (j->kind == J_POLL && a->op == AX_IDLE && result >= 0))
                return;
        if (result < 0) {
                if (a->op != AX_IDLE && j->kind != J_STOP)
                        axis_finish(a, result, strerror(-result));
                return rig_fault(j->rig, name, result, "%s failed: %s",
                                 j->kind == J_OPEN_AXIS ? "open" : "drive command",
                                 strerror(-result));
        }
        if (j->kind == J_HOME || j->kind == J_MOVE)
                arm(a, POLL_USEC);
        else if (j->kind == J_STOP)
                (void)submit_new(j->rig, J_POLL, j->idx, 0, false, false);
        else if (j->kind == J_POLL)
                axis_progress(a);
}

struct later {
        struct rig *rig;
        rig_done_fn done;
        void *ud;
};

static int on_later(sd_event_source *s, uint64_t usec, void *userdata)
{
        struct later *l = userdata;

        l->done(l->rig, 0, NULL, l->ud);
        free(l);
        sd_event_source_unref(s);
        return 0;
}

/* Calls done after ms milliseconds (a lamp's warm-up), or now. */
static void done_later(struct rig *rig, int ms, rig_done_fn done, void *ud)
{
        struct later *l = ms > 0 ? malloc(sizeof(*l)) : NULL;
        sd_event_source *s = NULL;

        if (l) {
                *l = (struct later){rig, done, ud};
                if (sd_event_add_time_relative(rig->event, &s, CLOCK_MONOTONIC, ms * 1000ULL, 1000,
                                               on_later, l) >= 0) {
                        sd_event_source_set_description(s, "lamp-warmup");
                        return;
                }
                free(l);
        }
        done(rig, 0, NULL, ud);
}

static void switch_job_done(struct job *j, int result)
{
        struct rig *rig = j->rig;
        struct rig_switch *s = switch_slot(rig, j->idx);
        const char *name = job_device(j);

        if (j->kind == J_OPEN_SW)
                s->open = result >= 0;
        if (result == -ECANCELED) { /* dropped at shutdown, not a device fault */
                if (j->done)
                        j->done(rig, result, "canceled", j->ud);
                return;
        }
        if (result < 0) {
                char msg[256];
                snprintf(msg, sizeof(msg), "%s: %s failed: %s", name,
                         j->kind == J_SWITCH ? "switching" : "reading the state",
                         strerror(-result));
                rig_fault(rig, name, result, "%s", msg);
                if (j->done)
                        j->done(rig, result, msg, j->ud);
                return;
        }
        if (j->kind == J_CHECK_SW)
                return;
        emit(rig, "switch.changed", json_pack("{sssb}", "name", name, "on", s->sw->on));
        if (j->done)
                done_later(rig, j->on ? s->sw->conf->warmup_ms : 0, j->done, j->ud);
}

static void camera_job_done(struct job *j, int result)
{
        struct rig *rig = j->rig;
        char msg[256];

        if (j->kind == J_OPEN_CAM) {
                rig->cam_open[j->idx] = result >= 0;
                if (result < 0)
                        rig_fault(rig, job_device(j), result, "open failed: %s", strerror(-result));
                return;
        }
        rig->captures--;
        snprintf(msg, sizeof(msg), "camera '%s': %s", job_device(j), strerror(-result));
        j->frame_done(rig, result, result < 0 ? msg : NULL, &j->frame, j->ud);
        update_state(rig);
}

static void clear_finished(struct rig *rig)
{
        rig_done_fn done = rig->clear_done;

        rig->clear_done = NULL;
        update_state(rig);
        if (done)
                done(rig, rig->fault ? -EIO : 0, rig->fault ? rig->fault_msg : NULL, rig->clear_ud);
}

static void job_done(struct bus *b, int result, void *userdata)
{
        struct job *j = userdata;

        j->rig->pending--;
        switch (j->kind) {
        case J_OPEN_SW:
        case J_CHECK_SW:
        case J_SWITCH:
                switch_job_done(j, result);
                break;
        case J_OPEN_CAM:
        case J_CAPTURE:
                camera_job_done(j, result);
                break;
        default:
                axis_job_done(j, result);
        }
        if (j->clear && --j->rig->clear_pending == 0)
                clear_finished(j->rig);
        gn_frame_free_data(&j->frame);
        free(j);
}

static int start_motion(struct rig *rig, int i, enum axis_op op, double target, rig_done_fn done,
                        void *ud)
{
        struct rig_axis *a = &rig->axes[i];
        const struct rig_axis_conf *c = a->ax->conf;
        double t = axis_move_time(op == AX_HOMING ? 360 : fabs(target - a->st.position_deg),
                                  c->max_speed, c->accel);
        int r;

        if (rig->fault)
                return -ESTALE;
        if (a->op != AX_IDLE)
                return -EBUSY;
        if (!a->open)
                return -ENODEV;
        r = submit_new(rig, op == AX_HOMING ? J_HOME : J_MOVE, i, target, false, false);
        if (r < 0)
                return r;
        a->op = op;
        a->done = done;
        a->ud = ud;
        a->deadline = now_usec(rig) + (c->move_timeout_ms ? c->move_timeout_ms * 1000ULL
                                                          : (uint64_t)(3 * t * 1e6) + 10000000);
        update_state(rig);
        return 0;
}

int rig_home(struct rig *rig, int i, rig_done_fn done, void *userdata)
{
        return start_motion(rig, i, AX_HOMING, 0, done, userdata);
}

int rig_move(struct rig *rig, int i, double *target, bool relative, rig_done_fn done,
             void *userdata)
{
        struct rig_axis *a = &rig->axes[i];
        double deg = *target;
        int r;

        if (!a->open)
                return -ENODEV;
        if (!a->st.homed)
                return -EPERM;
        if (relative)
                deg += a->st.position_deg;
        r = axis_check_target(a->ax, &deg);
        if (r < 0)
                return r;
        *target = deg;
        return start_motion(rig, i, AX_MOVING, deg, done, userdata);
}

void rig_stop(struct rig *rig, json_t *names)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                struct rig_axis *a = &rig->axes[i];
                char msg[128];

                atomic_fetch_add(&a->gen, 1);
                if (!a->open)
                        continue;
                (void)submit_new(rig, J_STOP, i, 0, false, true);
                if (a->op == AX_IDLE && !a->st.moving)
                        continue;
                if (names)
                        json_array_append_new(names, json_string(a->ax->conf->name));
                snprintf(msg, sizeof(msg), "%s of '%s' canceled by stop",
                         a->op == AX_HOMING ? "homing" : "move", a->ax->conf->name);
                if (a->op != AX_IDLE)
                        axis_finish(a, -ECANCELED, msg);
        }
}

int rig_switch(struct rig *rig, int i, bool on, rig_done_fn done, void *userdata)
{
        struct rig_switch *s = switch_slot(rig, i);
        struct job *j;

        if (i < 0 && !rig->rc->has_laser)
                return -ENOENT;
        if (on && rig->fault)
                return -ESTALE;
        if (!s->open)
                return -ENODEV;
        j = calloc(1, sizeof(*j));
        if (!j)
                return -ENOMEM;
        *j = (struct job){
                .rig = rig, .kind = J_SWITCH, .idx = i, .on = on, .done = done, .ud = userdata};
        return submit(j, false);
}

int rig_capture(struct rig *rig, int i, const struct cam_request *req, rig_frame_fn done,
                void *userdata)
{
        struct job *j;
        int r;

        if (rig->fault)
                return -ESTALE;
        if (!rig->cam_open[i])
                return -ENODEV;
        for (size_t k = 0; k < rig->rc->n_axes; k++)
                if (rig->axes[k].op != AX_IDLE)
                        return -EBUSY;
        j = calloc(1, sizeof(*j));
        if (!j)
                return -ENOMEM;
        *j = (struct job){.rig = rig,
                          .kind = J_CAPTURE,
                          .idx = i,
                          .creq = *req,
                          .frame_done = done,
                          .ud = userdata};
        r = submit(j, false);
        if (r >= 0) {
                rig->captures++;
                update_state(rig);
        }
        return r;
}

void rig_snapshot(const struct rig *rig, struct rig_snapshot *snap)
{
        double *pose[] = {&snap->turntable_deg, &snap->light_arm_deg, &snap->camera_arm_deg};
        static const char *const names[] = {"turntable", "light_arm", "camera_arm"};

        memset(snap, 0, sizeof(*snap));
        for (size_t k = 0; k < ELEMENTSOF(names); k++) {
                int i = rig_axis_index(rig, names[k]);
                *pose[k] = i >= 0 ? rig->axes[i].st.position_deg : NAN;
        }
        for (size_t i = 0; i < rig->rc->n_lamps; i++) {
                size_t len = strlen(snap->lamps);
                if (rig->lamps[i].sw->on)
                        snprintf(snap->lamps + len, sizeof(snap->lamps) - len, "%s%s",
                                 len ? "," : "", rig->rc->lamps[i].name);
        }
        snap->laser = rig->rc->has_laser && rig->laser.sw->on;
}

/* Runs the loop until no job is in flight, or until timeout. */
static void wait_idle(struct rig *rig, uint64_t timeout_usec)
{
        uint64_t end = now_usec(rig) + timeout_usec;

        while (rig->pending > 0 && now_usec(rig) < end)
                if (sd_event_run(rig->event, 100 * 1000) < 0)
                        break;
}

/* Queues an open job for every device not open yet. */
static void open_devices(struct rig *rig)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (!rig->axes[i].open)
                        (void)submit_new(rig, J_OPEN_AXIS, i, 0, false, false);
        for (size_t i = 0; i < rig->rc->n_lamps; i++)
                if (!rig->lamps[i].open)
                        (void)submit_new(rig, J_OPEN_SW, i, 0, false, false);
        if (rig->rc->has_laser && !rig->laser.open)
                (void)submit_new(rig, J_OPEN_SW, -1, 0, false, false);
        for (size_t i = 0; i < rig->rc->n_cameras; i++)
                if (!rig->cam_open[i])
                        (void)submit_new(rig, J_OPEN_CAM, i, 0, false, false);
}

int rig_clear_fault(struct rig *rig, rig_done_fn done, void *userdata)
{
        if (rig->clear_done)
                return -EBUSY;
        rig->fault = false;
        rig->fault_msg[0] = rig->fault_device[0] = 0;
        rig->clear_done = done;
        rig->clear_ud = userdata;
        rig->clear_collect = true;
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].open)
                        (void)submit_new(rig, J_RESET, i, 0, false, false);
        for (size_t i = 0; i < rig->rc->n_lamps + rig->rc->has_laser; i++) {
                int k = i < rig->rc->n_lamps ? (int)i : -1;
                if (switch_slot(rig, k)->open)
                        (void)submit_new(rig, J_CHECK_SW, k, 0, false, false);
        }
        open_devices(rig);
        rig->clear_collect = false;
        if (rig->clear_pending == 0)
                clear_finished(rig);
        return 0;
}

static struct bus *bus_of(struct rig *rig, const char *name)
{
        for (size_t i = 0; i < rig->rc->n_buses; i++)
                if (strcmp(rig->rc->buses[i].name, name) == 0)
                        return rig->buses[i];
        return NULL;
}

static int build_devices(struct rig *rig)
{
        struct rig_config *rc = rig->rc;
        int r;

        for (size_t i = 0; i < rc->n_buses; i++)
                if ((r = bus_new(rig->event, &rc->buses[i], &rig->buses[i])) < 0)
                        return log_error_errno(r, "bus '%s': %m", rc->buses[i].name);
        for (size_t i = 0; i < rc->n_axes; i++) {
                struct rig_axis *a = &rig->axes[i];
                *a = (struct rig_axis){.rig = rig, .idx = i};
                if ((r = axis_new(&rc->axes[i], bus_of(rig, rc->axes[i].bus), &a->ax)) < 0 ||
                    (r = sd_event_add_time_relative(rig->event, &a->timer, CLOCK_MONOTONIC, 0, 0,
                                                    on_axis_timer, a)) < 0)
                        return log_error_errno(r, "axis '%s': %m", rc->axes[i].name);
                a->ax->rig = rc; /* register profiles defined in the rig file */
                sd_event_source_set_enabled(a->timer, SD_EVENT_OFF);
                sd_event_source_set_description(a->timer, "axis-poll");
        }
        for (size_t i = 0; i < rc->n_lamps; i++)
                if ((r = sw_new(&rc->lamps[i], bus_of(rig, rc->lamps[i].bus), &rig->lamps[i].sw)) <
                    0)
                        return log_error_errno(r, "lamp '%s': %m", rc->lamps[i].name);
        if (rc->has_laser &&
            (r = sw_new(&rc->laser, bus_of(rig, rc->laser.bus), &rig->laser.sw)) < 0)
                return log_error_errno(r, "laser '%s': %m", rc->laser.name);
        for (size_t i = 0; i < rc->n_cameras; i++)
                if ((r = cam_new(&rc->cameras[i], bus_of(rig, rc->cameras[i].bus), &rig->cams[i])) <
                    0)
                        return log_error_errno(r, "camera '%s': %m", rc->cameras[i].name);
        return 0;
}

int rig_new(sd_event *event, struct rig_config *rc, rig_notify_fn notify, void *userdata,
            struct rig **ret)
{
        struct rig *rig = calloc(1, sizeof(*rig));
        int r;

        if (!rig)
                return -ENOMEM;
        rig->event = event;
        rig->rc = rc;
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
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                sd_event_source_disable_unref(rig->axes[i].timer);
                axis_free(rig->axes[i].ax);
        }
        for (size_t i = 0; i < rig->rc->n_lamps; i++)
                sw_free(rig->lamps[i].sw);
        sw_free(rig->laser.sw);
        for (size_t i = 0; i < rig->rc->n_cameras; i++)
                cam_free(rig->cams[i]);
        free(rig);
        return NULL;
}

unsigned rig_pending(const struct rig *rig)
{
        return rig->pending;
}

const char *rig_state(const struct rig *rig)
{
        bool homing = false, moving = false;

        if (rig->fault)
                return "fault";
        for (size_t i = 0; i < rig->rc->n_axes; i++) {
                homing = homing || rig->axes[i].op == AX_HOMING;
                moving = moving || rig->axes[i].op == AX_MOVING;
        }
        return homing ? "homing" : moving ? "moving" : rig->captures ? "capturing" : "idle";
}

static json_t *axis_status(const struct rig_axis *a)
{
        const struct rig_axis_conf *c = a->ax->conf;

        return json_pack("{sssfsbsbsbsbsisfsfsb}", "name", c->name, "position", a->st.position_deg,
                         "moving", a->op != AX_IDLE || a->st.moving, "homed", a->st.homed, "fault",
                         a->st.fault, "open", a->open, "fault_code", a->st.fault_code, "min",
                         c->min_deg, "max", c->max_deg, "continuous", c->continuous);
}

json_t *rig_status(const struct rig *rig)
{
        const struct rig_config *rc = rig->rc;
        json_t *axes = json_array(), *lamps = json_array(), *cams = json_array();
        bool homed = rc->n_axes > 0;

        for (size_t i = 0; i < rc->n_axes; i++) {
                json_array_append_new(axes, axis_status(&rig->axes[i]));
                homed = homed && rig->axes[i].st.homed;
        }
        for (size_t i = 0; i < rc->n_lamps; i++)
                json_array_append_new(lamps, json_pack("{sssb}", "name", rc->lamps[i].name, "on",
                                                       rig->lamps[i].sw->on));
        for (size_t i = 0; i < rc->n_cameras; i++)
                json_array_append_new(cams, json_pack("{sssisisi}", "name", rc->cameras[i].name,
                                                      "width", rc->cameras[i].width, "height",
                                                      rc->cameras[i].height, "bits",
                                                      rc->cameras[i].bits));
        return json_pack(
                "{sssbsososososo}", "state", rig_state(rig), "homed", homed, "axes", axes, "lamps",
                lamps, "laser",
                rc->has_laser ? json_pack("{sssb}", "name", rc->laser.name, "on", rig->laser.sw->on)
                              : json_null(),
                "cameras", cams, "fault",
                rig->fault ? json_pack("{ssss}", "device", rig->fault_device, "message",
                                       rig->fault_msg)
                           : json_null());
}

static json_t *opts_json(const struct opt_desc *opts, int n)
{
        json_t *a = json_array();

        for (int i = 0; i < n; i++)
                json_array_append_new(
                        a, json_pack("{sssbsbss?sfsf}", "name", opt_key_name(opts[i].key), "get",
                                     (opts[i].flags & OPT_GET) != 0, "set",
                                     (opts[i].flags & OPT_SET) != 0, "unit", opts[i].unit, "min",
                                     opts[i].min, "max", opts[i].max));
        return a;
}

static json_t *device_json(const char *cls, const char *name, const char *backend, const char *bus,
                           const struct opt_desc *opts, int n)
{
        return json_pack("{ssssssssso}", "class", cls, "name", name, "backend", backend, "bus", bus,
                         "options", opts_json(opts, n));
}

json_t *rig_describe(const struct rig *rig)
{
        const struct rig_config *rc = rig->rc;
        json_t *devs = json_array();

        for (size_t i = 0; i < rc->n_axes; i++) {
                const struct axis *ax = rig->axes[i].ax;
                json_array_append_new(devs,
                                      device_json("axis", rc->axes[i].name, ax->ops->name,
                                                  rc->axes[i].bus, ax->ops->opts, ax->ops->n_opts));
        }
        for (size_t i = 0; i < rc->n_lamps + rc->has_laser; i++) {
                const struct sw *s = i < rc->n_lamps ? rig->lamps[i].sw : rig->laser.sw;
                json_array_append_new(devs, device_json(i < rc->n_lamps ? "lamp" : "laser",
                                                        s->conf->name, s->ops->name, s->conf->bus,
                                                        s->ops->opts, s->ops->n_opts));
        }
        for (size_t i = 0; i < rc->n_cameras; i++) {
                const struct cam *c = rig->cams[i];
                json_array_append_new(devs,
                                      device_json("camera", c->conf->name, c->ops->name,
                                                  c->conf->bus, c->ops->opts, c->ops->n_opts));
        }
        return json_pack("{ssso}", "rig", rc->name, "devices", devs);
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
