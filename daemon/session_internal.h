/* session_internal.h - what the two halves of goniod's session runner share: the runner's
 * state (session.c, the state machine on the loop) and the calls between it and the index
 * work on the dataset worker (session_load.c: planning, loading, recording). */
#pragma once

#include <stdbool.h>
#include <stdint.h>
#include <systemd/sd-event.h>

#include "common/pose.h"
#include "common/rigconf.h"
#include "dataset/ds.h"
#include "manager.h"
#include "session.h"

#define MAX_DARKS    64
#define KIND_NAME(k) ((const char *const[]){"image", "dark", "flat", "laser"}[k])

enum sstate { S_NONE, S_LOADING, S_PREPARING, S_RUNNING, S_PAUSING, S_PAUSED, S_ENDING };

/* One exposure still to take: the pending plan items of one shot. */
struct run_shot {
        struct gn_pose pose;
        char kind[8];
        int bracket, exposure_us;
        double gain;
        size_t n;
        int cams[RIG_MAX_CAMERAS];
        int64_t seq[RIG_MAX_CAMERAS];
};

/* The dark frame to subtract from captures of one camera, exposure and gain. */
struct dark {
        int cam, exposure_us;
        double gain;
        int64_t id;
};

struct session_runner {
        struct manager *m;
        enum sstate state;
        char name[DS_NAME_MAX], dataset[DS_NAME_MAX];
        char reason[256];
        int settle_ms[GN_ROLE_COUNT];
        struct run_shot *shots;
        size_t n_shots, next;
        bool positioned;       /* the rig is in shots[next]'s pose and lighting */
        unsigned ops;          /* rig operations in flight (moves, switches, homing, settle) */
        bool exposing;         /* a take's frames are not back yet */
        unsigned takes;        /* takes whose stores have not all answered */
        unsigned ref_takes;    /* of which darks and flats, whose row ids later shots record */
        int pos_phase;         /* of position(): 0 to start, 1 moving and switching, 2 settling */
        int settle_pending_ms; /* extra settle after the moves in flight */
        int error;             /* first failure of this run: pauses it */
        bool pause_req, abort_req;
        bool exiting;    /* session_runner_stop: goniod is exiting, nothing more is started */
        bool lights_off; /* pausing or ending: lamps and laser were switched off */
        int64_t planned, captured, captured_run;
        uint64_t t_run_ns, t_progress_ns;
        uint64_t t_end_ns; /* when the last session ended (monotonic), for its status */
        double estimate_s; /* timing model of what remained when the run began */
        struct dark darks[MAX_DARKS];
        size_t n_darks;
        int64_t flats[RIG_MAX_CAMERAS]; /* the newest flat field's row per camera, 0: none */
        sd_event_source *settle_timer;
        sd_event_source *retry_timer; /* paused by a fault or a full disk: resume when it is gone */
        char busy[160];               /* session_busy_reason() */
        char ended[16]; /* how the last session ended: "done", "aborted" ("" while one runs) */
        session_done_fn done; /* the start or resume request, answered once running */
        void *done_ud;
};

static inline const struct rig_config *rc_of(const struct session_runner *s)
{
        return s->m->rc;
}

/* Records the run's first failure (err, reason) unless one is recorded; it pauses the run. */
void session_set_error(struct session_runner *s, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* Sets the state and notifies session.state. */
void session_set_state(struct session_runner *s, enum sstate st);

/* Notifies session.state with the status. */
void session_notify_state(struct session_runner *s);

/* Answers the start or resume request (once; no-op when none waits). */
void session_answer(struct session_runner *s, int result, const char *msg);

/* Runs the loaded shots: clears a fault, homes lost axes, then runs (session.c). */
void session_prepare(struct session_runner *s);

/* After a pause whose cause can go away, tries to resume every few seconds. */
void session_arm_retry(struct session_runner *s);

/* Index of camera name in rc, or -ENOENT. */
int session_camera_index(const struct rig_config *rc, const char *name);

/* Records the pause ("paused") or the end ("done", "aborted") of the session on the dataset
 * worker; the state follows when it is recorded (session_load.c). */
void session_record(struct session_runner *s, const char *state);
