/* session.c - goniod's session runner (see session.h, docs/sessions.md).
 *
 * DESIGN
 * The plan lives in the dataset's index. Starting a session records the whole plan there
 * (ds_session_begin) and then, like every resume, runs what the index says is missing
 * (ds_plan_pending): one code path, so a run after a crash is the run every test makes.
 * Rows carry their plan item's seq and the index refuses a second row of one seq, so a
 * capture is present at most once whatever happens; resuming makes it present at least once.
 *
 * Index work (open, begin, pending, state records, .lp files) runs on the dataset worker,
 * and only while no capture is in flight, so the storage pool's writer and the worker never
 * use the dataset at once. Everything else runs on the loop, as a state machine woken by
 * each completion (step()):
 *   LOADING    the dataset job runs
 *   PREPARING  a rig fault is cleared and the axes that lost their home are homed
 *   RUNNING    for each shot: move and switch into its pose, expose, hand the frames to the
 *              pool; the next pose's motion starts as soon as the frames are back, while the
 *              pool encodes and stores them (the pool's bounded queue holds the runner back)
 *   PAUSING    after a pause request or a failure: wait for the stores, lamps and laser off,
 *              record "paused" with the cause
 *   ENDING     after the last shot or an abort: wait for the stores, record the end, write
 *              the .lp files, close the dataset (dataset.json is rewritten) */
#include <dirent.h>
#include <errno.h>
#include <inttypes.h>
#include <stdarg.h>
#include <math.h>
#include <string.h>
#include <sys/statvfs.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "common/riggeom.h"
#include "common/sessconf.h"
#include "dataset/ds_session.h"
#include "datasets.h"
#include "manager.h"
#include "plan.h"
#include "protocol/proto.h"
#include "session.h"
#include "session_internal.h"

#define PROGRESS_USEC  100000           /* session.progress at most 10 times a second */
#define POSE_TOLERANCE 1e-4             /* deg: an axis this close to its target is not moved */
#define RETRY_USEC     (5 * 1000000ULL) /* a session paused by a fault tries again this often */
#define STILL_POLL_MS  20 /* preparing: how often to look whether stopping axes stand still */
#define SPACE_MARGIN   4  /* a full disk must have room for this many uncompressed shots */
#define AGAIN_MS       20 /* a capture refused with nothing in flight to call back: retry */

static const char *const state_names[] = {"none",    "starting", "preparing", "running",
                                          "pausing", "paused",   "ending"};

static void step(struct session_runner *s);

/* ---- small helpers ---- */

void session_set_error(struct session_runner *s, int err, const char *fmt, ...)
{
        va_list ap;

        if (s->error < 0)
                return;
        s->error = err;
        va_start(ap, fmt);
        vsnprintf(s->reason, sizeof(s->reason), fmt, ap);
        va_end(ap);
}

static bool drained(const struct session_runner *s)
{
        return s->ops == 0 && !s->exposing && s->takes == 0;
}

void session_notify_state(struct session_runner *s)
{
        manager_notify_json(s->m, "session.state", session_status(s));
}

void session_set_state(struct session_runner *s, enum sstate st)
{
        s->state = st;
        snprintf(s->busy, sizeof(s->busy), "session '%s' is %s (gonioctl session %s)", s->name,
                 state_names[st], st == S_PAUSED ? "abort" : "pause or abort");
        session_notify_state(s);
}

/* Answers the start or resume request, once. */
void session_answer(struct session_runner *s, int result, const char *msg)
{
        session_done_fn done = s->done;

        s->done = NULL;
        if (done)
                done(s->m, result, msg, session_status(s), s->done_ud);
}

static int64_t dark_of(const struct session_runner *s, int cam, int exposure_us, double gain)
{
        for (size_t i = 0; i < s->n_darks; i++)
                if (s->darks[i].cam == cam && s->darks[i].exposure_us == exposure_us &&
                    s->darks[i].gain == gain)
                        return s->darks[i].id;
        return 0;
}

static void remember_dark(struct session_runner *s, int cam, int exposure_us, double gain,
                          int64_t id)
{
        size_t i;

        for (i = 0; i < s->n_darks; i++)
                if (s->darks[i].cam == cam && s->darks[i].exposure_us == exposure_us &&
                    s->darks[i].gain == gain)
                        break;
        if (i == MAX_DARKS)
                return;
        s->darks[i] = (struct dark){cam, exposure_us, gain, id};
        s->n_darks += i == s->n_darks;
}

/* ---- status ---- */

json_t *session_status(const struct session_runner *s)
{
        uint64_t until = s->state == S_NONE && s->t_end_ns ? s->t_end_ns : gn_monotonic_ns();
        double elapsed = s->t_run_ns ? (until - s->t_run_ns) / 1e9 : 0;
        double rate = elapsed > 0 ? s->captured_run / elapsed : 0;
        int64_t remaining = s->planned - s->captured;
        double eta = rate > 0 ? remaining / rate : s->estimate_s;

        json_t *st;

        if (s->state == S_NONE && !s->ended[0])
                return json_pack("{ss}", "state", "none");
        st = json_pack("{sssssssssIsIsIsfsfsfsIsI}", "state", state_names[s->state], "name",
                       s->name, "dataset", s->dataset, "reason", s->reason, "planned",
                       (json_int_t)s->planned, "captured", (json_int_t)s->captured, "remaining",
                       (json_int_t)remaining, "rate_per_s", rate, "eta_s", eta, "elapsed_s",
                       elapsed, "shot", (json_int_t)s->next, "shots", (json_int_t)s->n_shots);
        if (st && s->state == S_NONE)
                json_object_set_new(st, "ended", json_string(s->ended));
        if (st && s->error < 0)
                json_object_set_new(st, "code", json_integer(proto_errno_to_code(s->error)));
        return st;
}

static void progress(struct session_runner *s)
{
        uint64_t now = gn_monotonic_ns();

        if (now - s->t_progress_ns < PROGRESS_USEC * 1000ULL && s->captured < s->planned)
                return;
        s->t_progress_ns = now;
        manager_notify_json(s->m, "session.progress", session_status(s));
}

bool session_active(const struct session_runner *s)
{
        return s && s->state != S_NONE;
}

const char *session_busy_reason(const struct session_runner *s)
{
        return session_active(s) ? s->busy : NULL;
}

/* ---- preparing: fault cleared, axes homed ---- */

/* Completion of any rig operation of the runner: one less in flight; the first failure is
 * kept. */
static void on_op_done(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct session_runner *s = userdata;

        s->ops--;
        if (result < 0)
                session_set_error(s, result, "%s", msg ? msg : strerror(-result));
        step(s);
}

/* Homes the axes that have no home (a drive restarted, goniod restarted), swept or not, so
 * that every row records the whole pose. */
static void home_lost_axes(struct session_runner *s)
{
        struct gn_pose now = rig_pose(s->m->rig);

        for (int role = 0; role < GN_ROLE_COUNT; role++) {
                int ax = rigconf_axis_of_role(rc_of(s), role);
                int r;

                if (ax < 0 || !isnan(now.deg[role]))
                        continue;
                r = rig_home(s->m->rig, ax, on_op_done, s);
                if (r < 0)
                        session_set_error(s, r, "cannot home '%s': %s", rc_of(s)->axes[ax].name,
                                          r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
                else
                        s->ops++;
        }
}

static void on_fault_cleared(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct session_runner *s = userdata;

        s->ops--;
        if (result < 0)
                session_set_error(s, result, "the rig is still in fault: %s", msg ? msg : "");
        else
                home_lost_axes(s);
        step(s);
}

/* The timing model's duration of the shots still to take, from the rig's pose now. */
static double estimate_rest(const struct session_runner *s)
{
        struct plan_shot *ps = calloc(s->n_shots ? s->n_shots : 1, sizeof(*ps));
        struct gn_pose now = rig_pose(s->m->rig);
        double t;

        if (!ps)
                return 0;
        for (size_t i = 0; i < s->n_shots; i++) {
                const struct run_shot *sh = &s->shots[i];
                ps[i] = (struct plan_shot){.pose = sh->pose,
                                           .exposure_us = sh->exposure_us,
                                           .gain = sh->gain,
                                           .bracket = sh->bracket};
                for (size_t k = 0; k < sh->n; k++)
                        ps[i].cameras |= 1u << sh->cams[k];
        }
        t = plan_estimate(rc_of(s), ps, s->n_shots, &now);
        free(ps);
        return t;
}

/* Brings the rig to where the shots can run: fault cleared, lost homes found. */
void session_prepare(struct session_runner *s)
{
        int r;

        if (s->exiting)
                return;
        s->positioned = false;
        s->pos_phase = 0;
        s->settle_pending_ms = 0;
        s->captured_run = 0;
        s->t_run_ns = gn_monotonic_ns();
        s->estimate_s = estimate_rest(s);
        session_set_state(s, S_PREPARING);
        if (strcmp(rig_state(s->m->rig), "fault") == 0) {
                r = rig_clear_fault(s->m->rig, on_fault_cleared, s);
                if (r < 0)
                        session_set_error(s, r, "cannot clear the rig's fault: %s", strerror(-r));
                else
                        s->ops++;
        } else {
                home_lost_axes(s);
        }
        step(s);
}

/* ---- running: position, expose ---- */

static int on_settled(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct session_runner *s = userdata;

        s->settle_timer = sd_event_source_disable_unref(s->settle_timer);
        s->ops--;
        step(s);
        return 0;
}

/* Waits ms as one more operation: the session's extra settle time of the axes just moved, the
 * rest of stopping axes, or a pause before trying a refused capture again. */
static void settle(struct session_runner *s, int ms)
{
        int r = sd_event_add_time_relative(s->m->event, &s->settle_timer, CLOCK_MONOTONIC,
                                           ms * 1000ULL, 1000, on_settled, s);

        if (r < 0)
                session_set_error(s, r, "cannot arm the settle timer: %s", strerror(-r));
        else
                s->ops++;
}

/* Starts the moves of the axes the shot puts elsewhere; returns the longest extra settle. */
static int move_axes(struct session_runner *s, const struct run_shot *sh, const struct gn_pose *now)
{
        int settle_ms = 0;

        for (int role = 0; role < GN_ROLE_COUNT; role++) {
                int ax = rigconf_axis_of_role(rc_of(s), role);
                double target = sh->pose.deg[role];
                int r;

                if (ax < 0 || isnan(target) ||
                    (!isnan(now->deg[role]) &&
                     gn_angle_distance(now->deg[role], target) <=
                             MAX(POSE_TOLERANCE, rc_of(s)->axes[ax].deadband_deg)))
                        continue;
                r = rig_move(s->m->rig, ax, &target, false, on_op_done, s);
                if (r < 0) {
                        session_set_error(s, r, "move %s to %g: %s", rc_of(s)->axes[ax].name,
                                          target,
                                          r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
                        return settle_ms;
                }
                s->ops++;
                settle_ms = MAX(settle_ms, s->settle_ms[role]);
        }
        return settle_ms;
}

/* Switches lamp i (a laser: RIG_SW_LASER) to on unless it is so already. */
static void switch_to(struct session_runner *s, int i, bool on, bool is_on)
{
        int r;

        if (on == is_on)
                return;
        r = rig_switch(s->m->rig, i, on, on_op_done, s);
        if (r < 0)
                session_set_error(s, r, "switch %s %s: %s", rig_switch_conf_of(rc_of(s), i)->name,
                                  on ? "on" : "off",
                                  r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
        else
                s->ops++;
}

/* Switches lamps and lasers to the lighting of pose (all off for NULL). */
static void light(struct session_runner *s, const struct gn_pose *pose, const struct gn_pose *now)
{
        for (size_t i = 0; i < rc_of(s)->n_lamps; i++)
                switch_to(s, i, pose && (pose->lamps >> i & 1), now->lamps >> i & 1);
        for (size_t i = 0; i < rc_of(s)->n_lasers; i++)
                switch_to(s, RIG_SW_LASER(i), pose && (pose->lasers >> i & 1),
                          now->lasers >> i & 1);
}

/* Moves and switches the rig into the next shot's pose, then waits the session's settle time:
 * each phase ends when its operations are done (step() calls back). */
static void position(struct session_runner *s)
{
        const struct run_shot *sh = &s->shots[s->next];
        struct gn_pose now = rig_pose(s->m->rig);

        switch (s->pos_phase) {
        case 0:
                s->pos_phase = 1;
                s->settle_pending_ms = move_axes(s, sh, &now);
                light(s, &sh->pose, &now);
                if (s->ops > 0 || s->error < 0)
                        return;
                /* fallthrough */
        case 1:
                s->pos_phase = 2;
                if (s->settle_pending_ms > 0) {
                        settle(s, s->settle_pending_ms);
                        s->settle_pending_ms = 0;
                        if (s->ops > 0 || s->error < 0)
                                return;
                }
                /* fallthrough */
        default:
                s->positioned = true;
                step(s);
        }
}

/* The frames are back: the next shot may move the rig while these are stored. */
static void on_exposed(struct capture *cp, void *userdata)
{
        struct session_runner *s = userdata;

        s->exposing = false;
        s->next++;
        s->positioned = false;
        s->pos_phase = 0;
        step(s);
}

/* Every frame of a take is stored or failed. */
static void on_taken(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct session_runner *s = userdata;

        s->takes--;
        for (size_t i = 0; i < res->n_shots; i++) {
                const struct capture_shot *sh = &res->shots[i];
                if (sh->result < 0) {
                        /* the fault this failure latched may have failed a move first (-EIO,
                         * same message): the cause's errno is the store's (ENOSPC...) */
                        if (s->error < 0 && strcmp(s->reason, sh->msg) == 0)
                                s->error = sh->result;
                        session_set_error(s, sh->result, "%s", sh->msg);
                        continue;
                }
                s->captured++;
                s->captured_run++;
                int cam = session_camera_index(rc_of(s), sh->row.camera);
                if (strcmp(sh->row.kind, "dark") == 0)
                        remember_dark(s, cam, sh->row.exposure_us, sh->row.gain, sh->row.id);
                if (strcmp(sh->row.kind, "flat") == 0 && cam >= 0)
                        s->flats[cam] = sh->row.id;
        }
        progress(s);
        step(s);
}

/* A take of dark frames or flat fields is stored: the shots after it may name its rows. */
static void on_ref_taken(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct session_runner *s = userdata;

        s->ref_takes--;
        on_taken(cp, res, userdata);
}

/* Exposes the cameras of the next shot, labelled with their plan items. */
static void expose(struct session_runner *s)
{
        const struct run_shot *sh = &s->shots[s->next];
        struct capture_tag tag = {.session = s->name,
                                  .kind = sh->kind,
                                  .bracket = sh->bracket,
                                  .exposed = on_exposed,
                                  .planned = &sh->pose};
        struct cam_request req = {.exposure_us = sh->exposure_us, .gain = sh->gain};
        bool dark = strcmp(sh->kind, "dark") == 0, flat = strcmp(sh->kind, "flat") == 0;
        int r;

        for (size_t k = 0; k < sh->n; k++) {
                tag.plan_seq[k] = sh->seq[k];
                tag.dark_id[k] = dark ? 0 : dark_of(s, sh->cams[k], sh->exposure_us, sh->gain);
                tag.flat_id[k] = dark || flat ? 0 : s->flats[sh->cams[k]];
        }
        if (s->ref_takes > 0 && !dark)
                return; /* the dark or flat rows it names are not stored yet: on_ref_taken */
        s->exposing = true;
        s->takes++;
        s->ref_takes += dark || flat;
        r = capture_take(s->m->capture, sh->cams, sh->n, &req, &tag,
                         dark || flat ? on_ref_taken : on_taken, s);
        if (r >= 0)
                return;
        s->exposing = false;
        s->takes--;
        s->ref_takes -= dark || flat;
        if (r == -EAGAIN && s->takes == 0) /* a device queue is full and no store calls back */
                settle(s, AGAIN_MS);
        else if (r != -EAGAIN) /* -EAGAIN: the storage queue is full; a store's answer calls back */
                session_set_error(s, r, "capture refused: %s",
                                  r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
}

static void begin_stop(struct session_runner *s, enum sstate st);

static void step_running(struct session_runner *s)
{
        if (s->ops > 0 || s->exposing)
                return;
        if (s->error < 0 || s->pause_req || s->abort_req)
                return begin_stop(s, s->abort_req ? S_ENDING : S_PAUSING);
        if (s->next == s->n_shots)
                return begin_stop(s, S_ENDING);
        if (!s->positioned)
                return position(s);
        expose(s);
        if (s->error < 0)
                step(s);
}

static void step_preparing(struct session_runner *s)
{
        if (s->ops > 0)
                return;
        if (s->error < 0 || s->pause_req || s->abort_req) {
                session_answer(s, s->error < 0 ? s->error : -ECANCELED,
                               s->error < 0 ? s->reason : "paused or aborted before it ran");
                return begin_stop(s, s->abort_req ? S_ENDING : S_PAUSING);
        }
        if (strcmp(rig_state(s->m->rig), "stopping") == 0 ||
            strcmp(rig_state(s->m->rig), "moving") == 0)
                return settle(s, STILL_POLL_MS); /* a stop just before the resume: wait for rest */
        session_set_state(s, S_RUNNING);
        session_answer(s, 0, NULL);
        step(s);
}

/* ---- pausing and ending ---- */

/* True when the session paused for a cause that can go away by itself: a device fault (the
 * device comes back), a full disk (space is freed), a drive that lost its home. Not after a
 * client's pause or stop. */
static bool retry_worth(const struct session_runner *s)
{
        if (s->pause_req || s->abort_req || s->error >= 0)
                return false;
        return strcmp(rig_state(s->m->rig), "fault") == 0 || s->error != -ECANCELED;
}

/* Bytes the next shot's frames take uncompressed, times the margin. */
static uint64_t space_needed(const struct session_runner *s)
{
        const struct run_shot *sh = s->next < s->n_shots ? &s->shots[s->next] : NULL;
        uint64_t bytes = 0;

        for (size_t k = 0; sh && k < sh->n; k++) {
                const struct rig_camera_conf *c = &rc_of(s)->cameras[sh->cams[k]];
                bytes += (uint64_t)c->width * c->height * 3 * (c->bits > 8 ? 2 : 1);
        }
        return SPACE_MARGIN * bytes;
}

/* True when the dataset's file system has room for the next shot. */
static bool space_for_next(const struct session_runner *s)
{
        char path[PATH_MAX];
        struct statvfs st;

        if (datasets_path(s->m, s->dataset, path, sizeof(path)) < 0 || statvfs(path, &st) < 0)
                return true; /* let the resume find out */
        return (uint64_t)st.f_bavail * st.f_frsize >= space_needed(s);
}

static int on_retry(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct session_runner *s = userdata;
        char msg[256];
        bool storage = s->error == -ENOSPC || s->error == -EDQUOT || s->error == -EFBIG;

        if (s->state != S_PAUSED)
                return 0;
        if ((storage && !space_for_next(s)) ||
            session_resume(s, NULL, NULL, NULL, msg, sizeof(msg)) < 0)
                return sd_event_source_set_time_relative(es, RETRY_USEC) < 0
                               ? 0
                               : sd_event_source_set_enabled(es, SD_EVENT_ONESHOT);
        log_info("session '%s': resuming after '%s'", s->name, s->reason);
        return 0;
}

/* After a pause with a cause that can go away, tries to resume every RETRY_USEC. */
void session_arm_retry(struct session_runner *s)
{
        int r;

        if (s->exiting || !retry_worth(s))
                return;
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        r = sd_event_add_time_relative(s->m->event, &s->retry_timer, CLOCK_MONOTONIC, RETRY_USEC,
                                       100000, on_retry, s);
        if (r < 0)
                log_warning("session '%s': cannot arm the resume timer: %s", s->name, strerror(-r));
}

static void begin_stop(struct session_runner *s, enum sstate st)
{
        if (st == S_PAUSING && s->error >= 0 && !s->reason[0])
                snprintf(s->reason, sizeof(s->reason), "paused by a client");
        if (st == S_ENDING && s->abort_req)
                snprintf(s->reason, sizeof(s->reason), "aborted by a client");
        s->lights_off = false;
        session_set_state(s, st);
        step(s);
}

/* Pausing or ending: once nothing is in flight, lamps and laser off, then the record. */
static void step_stopping(struct session_runner *s)
{
        if (!drained(s))
                return;
        if (s->state == S_ENDING && !s->abort_req && s->error >= 0 && s->captured < s->planned)
                session_set_error(s, -EIO, "%" PRId64 " planned captures are missing",
                                  s->planned - s->captured);
        if (s->state == S_ENDING && !s->abort_req && s->error < 0)
                return begin_stop(s, S_PAUSING); /* a store failed at the end: resume it */
        if (!s->lights_off) {
                struct gn_pose now = rig_pose(s->m->rig);

                s->lights_off = true;
                light(s, NULL, &now);
                if (s->ops > 0)
                        return;
        }
        session_record(s, s->state == S_PAUSING ? "paused" : s->abort_req ? "aborted" : "done");
}

static void step(struct session_runner *s)
{
        if (s->exiting)
                return; /* goniod is exiting: the capture, the rig or the index may be gone */
        switch (s->state) {
        case S_PREPARING:
                return step_preparing(s);
        case S_RUNNING:
                return step_running(s);
        case S_PAUSING:
        case S_ENDING:
                return step_stopping(s);
        default:
                return;
        }
}

/* ---- requests ---- */

int session_pause(struct session_runner *s, char *msg, size_t len)
{
        if (s->state == S_NONE)
                return snprintf(msg, len, "no session is running"), -ENOENT;
        if (s->state == S_PAUSED || s->state == S_PAUSING || s->pause_req)
                return snprintf(msg, len, "session '%s' is %s already", s->name,
                                state_names[s->state]),
                       -EALREADY;
        if (s->state == S_ENDING || s->state == S_LOADING)
                return snprintf(msg, len, "session '%s' is %s", s->name, state_names[s->state]),
                       -EBUSY;
        s->pause_req = true;
        step(s);
        return 0;
}

int session_abort(struct session_runner *s, char *msg, size_t len)
{
        if (s->state == S_NONE)
                return snprintf(msg, len, "no session is running"), -ENOENT;
        if (s->state == S_ENDING || s->state == S_LOADING)
                return snprintf(msg, len, "session '%s' is %s", s->name, state_names[s->state]),
                       -EBUSY;
        s->abort_req = true;
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        if (s->state == S_PAUSED) {
                snprintf(s->reason, sizeof(s->reason), "aborted by a client");
                s->lights_off = true;
                session_set_state(s, S_ENDING);
        } else {
                (void)rig_stop(s->m->rig, NULL); /* the moves in flight end with -ECANCELED */
        }
        step(s);
        return 0;
}

int session_runner_new(struct manager *m, struct session_runner **ret)
{
        struct session_runner *s = calloc(1, sizeof(*s));

        if (!s)
                return -ENOMEM;
        s->m = m;
        *ret = s;
        return 0;
}

void session_runner_stop(struct session_runner *s)
{
        s->exiting = true;
        s->settle_timer = sd_event_source_disable_unref(s->settle_timer);
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        session_answer(s, -ECANCELED, "goniod is shutting down");
}

struct session_runner *session_runner_free(struct session_runner *s)
{
        if (!s)
                return NULL;
        s->settle_timer = sd_event_source_disable_unref(s->settle_timer);
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        free(s->shots);
        free(s);
        return NULL;
}
