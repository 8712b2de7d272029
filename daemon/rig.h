/* rig.h - the assembled rig inside goniod: buses, axes, lamps, laser and cameras
 * built from the rig file, driven asynchronously from the event loop.
 *
 * Every operation is queued on the device's bus worker and completes through a
 * callback on the loop thread. Motion is followed by polling the drive until it
 * is in position and settled. On any device fault the rig records the fault and
 * goes to its safe state: motion stopped, lasers off, lamps off. */
#pragma once

#include <jansson.h>
#include <stdbool.h>

#include "common/frame.h"
#include "common/pose.h"
#include "common/rigconf.h"
#include "drivers/camera/camera.h"

typedef struct sd_event sd_event;

struct rig;

/* Completion of an operation on the loop thread: result >= 0 or -errno; msg explains
 * a failure (NULL on success). */
typedef void (*rig_done_fn)(struct rig *rig, int result, const char *msg, void *userdata);

/* What happened on the rig; turned into protocol notifications by the caller. */
enum rig_event_type {
        RIG_EVENT_STATE,      /* state changed: state */
        RIG_EVENT_AXIS_MOVED, /* progress of a moving axis: device, position, moving */
        RIG_EVENT_MOVE_DONE,  /* a move or homing ended in position: device, position */
        RIG_EVENT_SWITCH,     /* a lamp or a laser was switched: device, on */
        RIG_EVENT_FAULT,      /* a fault was latched: device, error, message */
};

struct rig_event {
        enum rig_event_type type;
        const char *device;  /* axis, lamp, laser or camera name; "dataset" for a store fault */
        const char *state;   /* RIG_EVENT_STATE: the new rig_state() */
        double position;     /* axis events, degrees */
        bool moving;         /* RIG_EVENT_AXIS_MOVED */
        bool on;             /* RIG_EVENT_SWITCH */
        int error;           /* RIG_EVENT_FAULT: -errno */
        const char *message; /* RIG_EVENT_FAULT: device, operation, cause and values */
};

/* Receives the rig's events on the loop thread; ev and its strings are valid during the
 * call only. */
typedef void (*rig_event_fn)(void *userdata, const struct rig_event *ev);

/* One camera's frame of an exposure (rig_expose). */
struct rig_shot {
        int cam;               /* camera index */
        int result;            /* 0, or -errno: no frame */
        char msg[256];         /* why it failed: device, operation, cause */
        struct gn_frame frame; /* owned by the rig; the callee may take frame.data (set it NULL) */
};

/* Result of an exposure: the pose held during every frame's exposure, confirmed by the
 * devices before and after, and one shot per camera asked for. */
struct rig_exposure {
        struct gn_pose pose;
        uint64_t t_request_ns; /* CLOCK_REALTIME when the exposure was asked for */
        size_t n_shots;
        struct rig_shot shots[RIG_MAX_CAMERAS];
};

/* Completion of rig_expose on the loop thread. e is valid during the call only. */
typedef void (*rig_expose_fn)(struct rig *rig, struct rig_exposure *e, void *userdata);

/* A frame of a camera stream on the loop thread: result 0 and frame (the callee may take
 * frame->data, setting it NULL), or -errno and msg (device, operation, cause): the stream has
 * ended. */
typedef void (*rig_frame_fn)(struct rig *rig, int result, struct gn_frame *frame, const char *msg,
                             void *userdata);

/* A position read back from a drive, on the loop thread, with the CLOCK_REALTIME mid-way
 * through the drive's answer and that answer's round trip (the time's uncertainty), ns
 * (rig_track). */
typedef void (*rig_track_fn)(void *userdata, int axis, double position_deg, uint64_t t_ns,
                             uint64_t rtt_ns);

/* Builds the devices of rc (which must outlive the rig) and opens them, running the
 * loop until every device answered (a device that does not puts the rig in fault state
 * rather than failing). A drive found moving (goniod restarted during a move) is stopped
 * and followed until it stands still, so the rig starts with true positions. Returns 0 or -errno
 * (bad backend names, no memory). */
int rig_new(sd_event *event, struct rig_config *rc, rig_event_fn notify, void *userdata,
            struct rig **ret);

/* Puts the rig in its safe state (waiting for it), stops workers, frees. NULL is a no-op. */
struct rig *rig_free(struct rig *rig);

/* Index of the named axis / lamp / camera, or -ENOENT. A lamp may be given by index. */
int rig_axis_index(const struct rig *rig, const char *name);
int rig_lamp_index(const struct rig *rig, const char *name);
int rig_camera_index(const struct rig *rig, const char *name);

/* Starts homing axis i; done when homed and settled. -EBUSY, -ESTALE (faulted). */
int rig_home(struct rig *rig, int i, rig_done_fn done, void *userdata);

/* Starts a move of axis i to *target (relative: by *target), which becomes the absolute
 * target (normalised for continuous axes); done when in position and settled. -ERANGE
 * outside soft limits, -ESTALE when not homed or faulted, -EBUSY when moving. */
int rig_move(struct rig *rig, int i, double *target, bool relative, rig_done_fn done,
             void *userdata);

/* Like rig_move (absolute) at speed deg/s (0: the axis's max_speed), for this move only.
 * -EOPNOTSUPP when the drive cannot set a speed (rig_axis_speed_settable). */
int rig_move_at(struct rig *rig, int i, double *target, double speed, rig_done_fn done,
                void *userdata);

/* True when axis i's drive can move at a speed other than its max_speed. */
bool rig_axis_speed_settable(const struct rig *rig, int i);

/* Hands every state read back from axis i to fn (NULL: none), and while it moves reads it
 * back as often as its bus allows. One axis at a time. */
void rig_track(struct rig *rig, int i, rig_track_fn fn, void *userdata);

/* Starts streaming camera i with req: fn gets every frame until rig_stream_stop, or one error
 * (the stream has then ended). Returns 0, -EBUSY (streaming already), -ESTALE (fault), -ENODEV
 * (the camera failed to open), -ENOMEM. Exposures of the camera are not refused meanwhile:
 * the caller owns the rig. */
int rig_stream_start(struct rig *rig, int i, const struct cam_request *req, rig_frame_fn fn,
                     void *userdata);

/* Stops camera i's stream: fn is not called again; the frame in flight is dropped. */
void rig_stream_stop(struct rig *rig, int i);

/* Takes one frame of camera i with req for a look (the live view), outside any exposure:
 * moves, switching and exposures are not refused meanwhile (an exposure of camera i waits on
 * its bus for this frame at most), and the frame records no pose. fn gets the frame or the
 * error once, on the loop, unless rig_peek_cancel or rig_free came first. Returns 0,
 * -ESHUTDOWN, -ESTALE (fault), -EBUSY (a peek of camera i is in flight, or it streams),
 * -ENODEV, -EAGAIN (its bus queue is full), -ENOMEM. */
int rig_peek(struct rig *rig, int i, const struct cam_request *req, rig_frame_fn fn,
             void *userdata);

/* Forgets the fn of camera i's peek in flight: its frame is dropped. */
void rig_peek_cancel(struct rig *rig, int i);

/* Stops every axis at once (urgent); pending moves complete with -ECANCELED, and axes in
 * motion are followed until they stand still. Writes the indices of the axes that were
 * moving into stopped (may be NULL; room for RIG_MAX_AXES) and returns their number. */
size_t rig_stop(struct rig *rig, int *stopped);

/* Switch indices (rig_switch(), the switch jobs): lamp i is i >= 0, laser k (rig-file
 * order) is RIG_SW_LASER(k) < 0. */
#define RIG_SW_LASER(k)    (-1 - (int)(k))
#define RIG_SW_LASER_OF(i) (-1 - (i))

/* The rig-file entry of switch index i. */
const struct rig_switch_conf *rig_switch_conf_of(const struct rig_config *rc, int i);

/* Switches lamp i (or a laser, RIG_SW_LASER(k)) and waits for its warm-up. Returns 0 (done
 * follows), -ENOENT, -ESHUTDOWN, -ESTALE (switching on while faulted), -EBUSY (an exposure
 * runs), -ENODEV, -ENOMEM, or -EAGAIN when the bus queue is full (done is not called). */
int rig_switch(struct rig *rig, int i, bool on, rig_done_fn done, void *userdata);

/* Exposes cams[0..n) (camera indices) with req: reads every axis back from its drive,
 * takes the frames, reads the axes again, and calls done with the pose confirmed before
 * and after (an axis that moved meanwhile faults the rig and fails every shot). Until
 * done, moves and switching are refused (-EBUSY), so the pose is that of the exposure.
 * Returns 0, -EBUSY (an axis moves, a lamp warms up, another exposure runs), -ESTALE
 * (fault), -ENODEV (a camera failed to open), -ENOMEM. */
int rig_expose(struct rig *rig, const int *cams, size_t n, const struct cam_request *req,
               rig_expose_fn done, void *userdata);

/* Checks req against camera i's own control ranges (the driver's option table, see
 * cam_check_request): 0, or -ERANGE/-EOPNOTSUPP/-EINVAL with "gain 100 outside [0.1, 64]"
 * in msg. */
int rig_check_camera_request(const struct rig *rig, int i, const struct cam_request *req, char *msg,
                             size_t len);

/* Why the rig refuses a move, a switch or an exposure now with -EBUSY: "axis 'x' is
 * moving", "a capture is being exposed", "lamp 'x' is warming up". Valid until the next
 * call into the rig. */
const char *rig_busy_reason(const struct rig *rig);

/* Latches a fault of device (the first one is kept), notifies clients and goes to the safe
 * state. Used by the rig itself and for faults outside it (a full disk). */
void rig_fault(struct rig *rig, const char *device, int err, const char *fmt, ...)
        __attribute__((format(printf, 4, 5)));

/* Stops every axis and switches lamps and lasers off, urgently (asynchronous). Running
 * moves complete with -ECANCELED, as do moves and switch-ons queued before (they would run
 * after the urgent stops); axes in motion are followed until they stand still. */
void rig_safe_state(struct rig *rig);

/* goniod is exiting: from now on moves, homing, switching on, exposures, streams and fault
 * clears are refused with -ESHUTDOWN (stops and switching off still run), then the safe state.
 * Loop thread. */
void rig_shutdown(struct rig *rig);

/* Device jobs in flight; 0 once the safe state has been reached. */
unsigned rig_pending(const struct rig *rig);

/* The last confirmed pose: angles by role (NAN where the rig has no such axis, or where
 * it is not homed, so its angle means nothing in the world frame), lit lamps, lasers. */
struct gn_pose rig_pose(const struct rig *rig);

/* The last error message a device of the rig reported (device, operation, cause), or ""
 * when none: for replies that explain a refusal or failure. */
const char *rig_last_error(const struct rig *rig);

/* Clears a latched fault: resets drives, reads back every switch and reopens devices that
 * failed; done gets -EIO (with the new fault's message) if a device still fails. -EBUSY while
 * a clear is running. */
int rig_clear_fault(struct rig *rig, rig_done_fn done, void *userdata);

/* Lifts a latched fault without resetting or reopening anything (an admin's override): the
 * devices that stopped answering stay out of service (-ENODEV), the rest of the rig may be
 * used; a drive that still reports a fault latches it again at its next read-back. Returns 0
 * (also when no fault is latched), -EBUSY while a clear runs or device jobs are in flight (the
 * safe state is being reached), -ESHUTDOWN at shutdown. */
int rig_override_fault(struct rig *rig);

/* "idle", "homing", "moving", "stopping", "capturing" or "fault". */
const char *rig_state(const struct rig *rig);

/* Builds the status object (axes, lamps, laser, cameras, fault, homed). New reference. */
json_t *rig_status(const struct rig *rig);

/* Builds the describe object: devices, backends and their options. New reference. */
json_t *rig_describe(const struct rig *rig);

/* A device setting (rig_settings.c, docs/goniod.md "Settings"): an axis's speed (deg/s) and
 * accel (deg/s^2) of the moves that name none, a camera's exposure_us and gain of the
 * captures that name none. They start at the rig file's values and last until goniod exits. */
struct rig_setting {
        const char *name, *unit; /* "speed", "deg/s" */
        double value, min, max;
        const char *limit; /* what sets max: "max_speed" (a rig-file key), "the driver's range" */
};

/* The settings of device (an axis or a camera) as {NAME: {value, min, max, unit, limit}}, or
 * NULL when the rig has no such device (or it has no settings). New reference. */
json_t *rig_settings_json(const struct rig *rig, const char *device);

/* Setting name of device into *ret. Returns 0, or -ENOENT (no such device, or no such
 * setting), -EOPNOTSUPP (the camera's driver has no such control), with the reason in msg. */
int rig_setting_get(const struct rig *rig, const char *device, const char *name,
                    struct rig_setting *ret, char *msg, size_t len);

/* Sets setting name of device to value: an axis's rates are written to its drive first (done
 * follows on the loop thread; the setting changes only once the drive took it), a camera's
 * take effect at its next capture (done runs before this returns). Returns 0, or -errno:
 * rig_setting_get's and -ERANGE outside [min, max] (naming the limit) with the reason in msg;
 * else msg is "" and the refusal is -EBUSY (the axis is moving: rig_busy_reason), -ESTALE
 * (fault), -ENODEV (not open), -ESHUTDOWN or -ENOMEM. */
int rig_setting_set(struct rig *rig, const char *device, const char *name, double value,
                    rig_done_fn done, void *userdata, char *msg, size_t len);

/* The rig configuration. */
const struct rig_config *rig_config(const struct rig *rig);
