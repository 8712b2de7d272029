/* rig_internal.h - the parts of the rig shared by rig.c (devices, jobs, motion,
 * switches, faults), rig_expose.c (exposures) and rig_json.c (status, describe).
 * Everything here runs on the loop thread except job_run's driver calls. */
#pragma once

#include <stdatomic.h>
#include <systemd/sd-event.h>

#include "drivers/axis/axis.h"
#include "drivers/bus/bus.h"
#include "drivers/switch/switch.h"
#include "rig.h"

enum axis_op { AX_IDLE, AX_MOVING, AX_HOMING, AX_STOPPING };

struct rig_axis {
        struct rig *rig;
        int idx;
        struct axis *ax;
        struct axis_state st; /* last state the drive reported */
        bool open;
        enum axis_op op;
        atomic_uint gen; /* bumped by stop; queued moves of older generations are dropped */
        rig_done_fn done;
        void *ud;
        sd_event_source *timer;
        double target;    /* of the running move, degrees */
        double leg;       /* commanded now: target, or the backlash take-up point before it */
        int retries_left; /* extra moves allowed to reach the deadband */
        bool missed;      /* the last move ended outside its deadband */
        uint64_t started, deadline, last_notify;
        bool settling;
        bool polling;     /* an idle poll is queued */
        unsigned motions; /* moves and homings queued so far: a poll queued before the latest
                           * one reads the drive before it and says nothing of its progress */
        double speed;     /* of the running move, deg/s; 0: the speed setting */
        /* the settings of the following moves (rig_settings.c): the rig file's max_speed
         * and accel until device.set changes them */
        double speed_setting, accel_setting;
};

struct rig_switch {
        struct sw *sw;
        bool open;
        unsigned changing;      /* switch jobs in flight and warm-ups running */
        atomic_uint gen;        /* bumped by the safe state; queued switch-ons of older ones drop */
        sd_event_source *limit; /* armed while on: switches it off at its max_on_s */
};

struct exposure;

/* A camera's single frame for a look (rig_peek, rig_stream.c): one in flight at a time. */
struct rig_peek {
        bool busy;       /* its capture job is queued or running */
        rig_frame_fn fn; /* NULL: forgotten (rig_peek_cancel), the frame is dropped */
        void *ud;
};

/* A camera's frame stream (rig_stream.c). */
struct rig_stream {
        bool on;   /* started and not stopped: dequeue jobs follow each other */
        bool next; /* a dequeue job is queued */
        rig_frame_fn fn;
        void *ud;
};

struct rig {
        sd_event *event;
        struct rig_config *rc;
        struct bus *buses[RIG_MAX_BUSES];
        struct rig_axis axes[RIG_MAX_AXES];
        struct rig_switch lamps[RIG_MAX_LAMPS], lasers[RIG_MAX_LASERS];
        struct cam *cams[RIG_MAX_CAMERAS];
        bool cam_open[RIG_MAX_CAMERAS];
        /* each camera's default controls set by device.set (rig_settings.c): what a request's
         * 0 becomes; 0 here: the rig file's, which the driver applies itself */
        struct cam_request cam_defaults[RIG_MAX_CAMERAS];
        unsigned pending;           /* jobs in flight */
        struct exposure *exposure;  /* the exposure running, or NULL */
        sd_event_source *idle_poll; /* reads idle drives back periodically */
        struct rig_stream streams[RIG_MAX_CAMERAS];
        struct rig_peek peeks[RIG_MAX_CAMERAS];
        int track_axis; /* the axis whose every read-back goes to track_fn, or -1 */
        rig_track_fn track_fn;
        void *track_ud;
        rig_event_fn notify;
        void *notify_ud;
        bool fault, freeing;
        bool closing; /* rig_shutdown: nothing new is started */
        char fault_device[RIG_NAME_MAX];
        char fault_msg[256];
        char last_error[256];
        char busy[160];
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
        J_RATES,
        J_OPEN_SW,
        J_CHECK_SW,
        J_SWITCH,
        J_OPEN_CAM,
        J_CAPTURE,
        J_PEEK, /* a capture outside any exposure (rig_peek) */
        J_STREAM_START,
        J_STREAM_NEXT,
        J_STREAM_STOP
};

struct job {
        struct rig *rig;
        enum job_kind kind;
        int idx; /* device index; < 0: laser RIG_SW_LASER_OF(idx) for switch jobs */
        unsigned gen;
        double arg;
        double speed;     /* J_MOVE, J_HOME, J_RATES: deg/s */
        double accel;     /* J_MOVE, J_HOME, J_RATES: deg/s^2 */
        uint64_t t_ns;    /* J_POLL: CLOCK_REALTIME mid-way through the drive's answer */
        uint64_t rtt_ns;  /* J_POLL: the answer's round trip */
        unsigned motions; /* J_POLL: the axis's motions when queued */
        bool on;
        struct axis_state st;
        struct cam_request creq;
        struct gn_frame frame;
        rig_done_fn done;
        void *ud;
        struct exposure *exp;    /* the exposure this poll or capture belongs to */
        int shot;                /* index into the exposure's shots */
        bool clear;              /* part of a fault.clear */
        char why[DEV_ERROR_MAX]; /* the driver's message when the job failed (worker) */
};

/* Queues j on its device's bus (urgent jobs first); frees j on failure. 0 or -errno. */
int rig_submit(struct job *j, bool urgent);

/* Allocates and queues a job. 0 or -errno. */
int rig_submit_new(struct rig *rig, enum job_kind kind, int idx, double arg, bool on, bool urgent);

/* Sends ev to the rig's listener. */
void rig_emit(struct rig *rig, const struct rig_event *ev);

/* Emits RIG_EVENT_STATE if rig_state() changed. */
void rig_update_state(struct rig *rig);

/* Starts stopping axis a and following it until it stands still (uncommanded motion). */
void rig_axis_stop_and_follow(struct rig_axis *a, const char *why);

/* Completion of an exposure's poll or capture job (rig_expose.c). */
void rig_expose_job_done(struct job *j, int result);

/* The slot of switch index i (a lamp, or a laser when i < 0: RIG_SW_LASER). */
struct rig_switch *rig_switch_slot(struct rig *rig, int i);

/* True for the camera jobs (open, capture, streaming). */
bool rig_is_camera_job(enum job_kind kind);

/* Runs a streaming job or a peek's capture on the bus worker (rig_stream.c). */
int rig_stream_job_call(struct job *j);

/* Completion of a streaming job or a peek's capture (rig_stream.c). */
void rig_stream_job_done(struct job *j, int result);

/* req with its 0s (the camera's defaults) replaced by camera i's settings where device.set
 * gave some (rig_settings.c). */
struct cam_request rig_camera_request(const struct rig *rig, int i, const struct cam_request *req);

/* Fails the exposure in flight at rig_free: its completion is dropped (rig_expose.c). */
void rig_expose_abandon(struct rig *rig);
