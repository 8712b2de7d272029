/* rig.h - the assembled rig inside goniod: buses, axes, lamps, laser and cameras
 * built from the rig file, driven asynchronously from the event loop.
 *
 * Every operation is queued on the device's bus worker and completes through a
 * callback on the loop thread. Motion is followed by polling the drive until it
 * is in position and settled. On any device fault the rig records the fault and
 * goes to its safe state: motion stopped, laser off, lamps off. */
#pragma once

#include <jansson.h>
#include <stdbool.h>

#include "common/frame.h"
#include "common/rigconf.h"
#include "drivers/camera/camera.h"

typedef struct sd_event sd_event;

struct rig;

/* Completion of an operation on the loop thread: result >= 0 or -errno; msg explains
 * a failure (NULL on success). */
typedef void (*rig_done_fn)(struct rig *rig, int result, const char *msg, void *userdata);

/* Completion of a capture: frame is owned by the callee on success. */
typedef void (*rig_frame_fn)(struct rig *rig, int result, const char *msg, struct gn_frame *frame,
                             void *userdata);

/* Receives the rig's notifications (params stolen): axis.moved, move.done,
 * switch.changed, fault, state.changed. */
typedef void (*rig_notify_fn)(void *userdata, const char *method, json_t *params);

/* The rig's state of one moment, recorded with each capture. */
struct rig_snapshot {
        double turntable_deg, light_arm_deg, camera_arm_deg;
        char lamps[256]; /* names of lit lamps, comma-separated */
        bool laser;
};

/* Builds the devices of rc (which must outlive the rig) and opens them, running the
 * loop until every device answered (a device that does not puts the rig in fault state
 * rather than failing). Returns 0 or -errno (bad backend names, no memory). */
int rig_new(sd_event *event, struct rig_config *rc, rig_notify_fn notify, void *userdata,
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

/* Stops every axis at once (urgent); pending moves complete with -ECANCELED.
 * Fills names (array of names stopped). */
void rig_stop(struct rig *rig, json_t *names);

/* Switches lamp i (or the laser when i < 0) and waits for its warm-up. */
int rig_switch(struct rig *rig, int i, bool on, rig_done_fn done, void *userdata);

/* Captures one frame with camera i. -EBUSY while an axis moves. */
int rig_capture(struct rig *rig, int i, const struct cam_request *req, rig_frame_fn done,
                void *userdata);

/* Latches a fault of device (the first one is kept), notifies clients and goes to the safe
 * state. Used by the rig itself and for faults outside it (a full disk). */
void rig_fault(struct rig *rig, const char *device, int err, const char *fmt, ...)
        __attribute__((format(printf, 4, 5)));

/* Stops every axis and switches lamps and laser off, urgently (asynchronous). */
void rig_safe_state(struct rig *rig);

/* Device jobs in flight; 0 once the safe state has been reached. */
unsigned rig_pending(const struct rig *rig);

/* Records the current pose, lamps and laser. */
void rig_snapshot(const struct rig *rig, struct rig_snapshot *snap);

/* Clears a latched fault: resets drives, reads back every switch and reopens devices that
 * failed; done gets -EIO (with the new fault's message) if a device still fails. -EBUSY while
 * a clear is running. */
int rig_clear_fault(struct rig *rig, rig_done_fn done, void *userdata);

/* "idle", "homing", "moving", "capturing" or "fault". */
const char *rig_state(const struct rig *rig);

/* Builds the status object (axes, lamps, laser, cameras, fault, homed). New reference. */
json_t *rig_status(const struct rig *rig);

/* Builds the describe object: devices, backends and their options. New reference. */
json_t *rig_describe(const struct rig *rig);

/* The rig configuration. */
const struct rig_config *rig_config(const struct rig *rig);
