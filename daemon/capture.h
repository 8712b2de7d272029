/* capture.h - goniod's capture pipeline: one request becomes an exposure of one or
 * more cameras in one confirmed pose (rig_expose), each frame is stored in the open
 * dataset off the loop (ds_pool), and each stored row is announced. No JSON here:
 * the protocol methods and, later, the session runner drive it alike. */
#pragma once

#include <systemd/sd-event.h>

#include "dataset/ds.h"
#include "dataset/ds_pool.h"
#include "rig.h"

struct capture;

/* One camera's outcome: stored (row filled, result 0) or not (result -errno, msg). */
struct capture_shot {
        int result;
        char msg[300];
        struct ds_capture row; /* camera always set; the rest when stored */
};

/* The outcome of one request: every camera asked for, stored or not. */
struct capture_result {
        size_t n_shots;
        struct capture_shot shots[RIG_MAX_CAMERAS];
};

/* Completion of capture_take on the loop thread; res is valid during the call only. */
typedef void (*capture_done_fn)(struct capture *cp, const struct capture_result *res,
                                void *userdata);

/* Called on the loop thread when the frames of a take are back from the cameras and handed to
 * the storage pool (before they are stored): the rig may move on. */
typedef void (*capture_exposed_fn)(struct capture *cp, void *userdata);

/* What the rows of a take record beyond pose and controls: the session runner's labels. */
struct capture_tag {
        const char *session;               /* NULL: none */
        const char *kind;                  /* "image" (NULL), "dark", "flat", "laser" */
        int bracket;                       /* index in the HDR bracket */
        int64_t plan_seq[RIG_MAX_CAMERAS]; /* per camera of the take; 0: none */
        int64_t dark_id[RIG_MAX_CAMERAS];  /* the dark frame's row per camera; 0: none */
        int64_t flat_id[RIG_MAX_CAMERAS];  /* the flat field's row per camera; 0: none */
        capture_exposed_fn exposed;        /* may be NULL */
        /* The pose the frames must have been exposed in (angles where not NAN, within
         * DS_PLAN_POSE_TOL_DEG; lamps and laser exactly), or NULL: a frame exposed elsewhere
         * is not stored (its shot fails with -EIO). */
        const struct gn_pose *planned;
};

/* Called on the loop thread for every row committed (capture.stored). */
typedef void (*capture_stored_fn)(void *userdata, const struct ds_capture *row);

/* Called on the loop thread with every frame of camera cam exposed or streamed for storing,
 * before it is stored: frame is valid during the call only and must not be changed (the
 * live view's source, daemon/preview.h). */
typedef void (*capture_tap_fn)(void *userdata, int cam, const struct gn_frame *frame);

/* Has fn(userdata, ...) see every frame (NULL: none). */
void capture_set_tap(struct capture *cp, capture_tap_fn fn, void *userdata);

/* Creates the pipeline over rig (borrowed; must outlive it). stored (may be NULL) is told
 * of every committed row. Returns 0 or -ENOMEM. */
int capture_new(sd_event *event, struct rig *rig, capture_stored_fn stored, void *userdata,
                struct capture **ret);

/* Finishes pending stores (their requests complete), forgets exposures still running
 * (their requests get no completion), closes the dataset. NULL is a no-op; returns NULL. */
struct capture *capture_free(struct capture *cp);

/* Makes d (taken over: closed by capture_free, or handed back by capture_detach) the
 * dataset captures go to, named name, holding count rows, with a storage pool of its own.
 * No I/O on d. Returns 0, -EBUSY while captures are in flight or a dataset is attached,
 * or -errno (d is then not taken). */
int capture_attach(struct capture *cp, struct ds *d, const char *name, int64_t count);

/* Takes the dataset away from the pipeline (its idle pool freed) and returns it for the
 * caller to close off the loop; NULL when none. Only while capture_in_flight() is 0. */
struct ds *capture_detach(struct capture *cp);

/* The open dataset and its name, or NULL. Valid until it is closed. */
struct ds *capture_dataset(const struct capture *cp);
const char *capture_dataset_name(const struct capture *cp);

/* Rows in the open dataset (counted at open, plus those stored since). */
int64_t capture_dataset_count(const struct capture *cp);

/* Exposes cams[0..n) (camera indices) with req and stores the frames in the open dataset,
 * labelled by tag (may be NULL; copied); done gets each camera's outcome once every frame is
 * stored or failed. Returns 0, -ESTALE (no dataset open, or the rig is faulted), -EAGAIN (the
 * storage queue has no room for n frames: wait for stores), or rig_expose's refusal (-EBUSY:
 * rig_busy_reason() says why). */
int capture_take(struct capture *cp, const int *cams, size_t n, const struct cam_request *req,
                 const struct capture_tag *tag, capture_done_fn done, void *userdata);

/* Stores frame (its data taken over), a frame of camera cam streamed outside rig_expose (a
 * continuous scan), with pose as its row's pose, labelled by tag (may be NULL; copied); done
 * gets the outcome once stored or failed. Returns 0, -ESTALE (no dataset open), -EAGAIN (the
 * storage queue is full: frame left to the caller) or -ENOMEM. */
int capture_store_frame(struct capture *cp, int cam, struct gn_frame *frame,
                        const struct gn_pose *pose, const struct capture_tag *tag,
                        capture_done_fn done, void *userdata);

/* Frames the storage queue can take now. */
size_t capture_store_room(const struct capture *cp);

/* Exposures and stores in flight (0: the dataset may change). */
unsigned capture_in_flight(const struct capture *cp);
