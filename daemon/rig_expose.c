/* rig_expose.c - exposures: the frames of several cameras taken in one pose that the
 * devices confirm before and after.
 *
 * DESIGN: an exposure runs in three stages, each a set of jobs on the bus workers:
 * read every open axis back (BEFORE), capture each camera (FRAMES), read the axes
 * again (AFTER). From the first job until the completion, moves and switching are
 * refused, so the pose read in BEFORE holds during every exposure; AFTER proves it.
 * Lamps and laser are as their relays confirmed and no switch may be warming up.
 * One exposure runs at a time. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "common/clock.h"
#include "common/log.h"
#include "rig_internal.h"

#define POSE_TOLERANCE_DEG 0.01 /* encoder noise of a standing drive */

enum stage { EXP_BEFORE, EXP_FRAMES, EXP_AFTER };

struct exposure {
        struct rig *rig;
        struct rig_exposure e;
        struct cam_request req;
        enum stage stage;
        unsigned pending;
        int error; /* fails every shot when set */
        char msg[256];
        rig_expose_fn done;
        void *ud;
};

static void fail_all(struct exposure *x, int err, const char *msg)
{
        if (x->error)
                return;
        x->error = err;
        snprintf(x->msg, sizeof(x->msg), "%s", msg);
}

/* Queues one poll of every open axis (or one capture per shot); counts them. */
static void submit_stage(struct exposure *x)
{
        struct rig *rig = x->rig;
        size_t n = x->stage == EXP_FRAMES ? x->e.n_shots : rig->rc->n_axes;

        for (size_t i = 0; i < n; i++) {
                struct job *j;
                int idx = x->stage == EXP_FRAMES ? x->e.shots[i].cam : (int)i;

                if (x->stage != EXP_FRAMES && !rig->axes[i].open)
                        continue;
                if (!(j = calloc(1, sizeof(*j)))) {
                        fail_all(x, -ENOMEM, "out of memory");
                        continue;
                }
                *j = (struct job){.rig = rig,
                                  .kind = x->stage == EXP_FRAMES ? J_CAPTURE : J_POLL,
                                  .idx = idx,
                                  .creq = x->stage == EXP_FRAMES
                                                  ? rig_camera_request(rig, idx, &x->req)
                                                  : x->req,
                                  .exp = x,
                                  .shot = i};
                if (rig_submit(j, false) < 0)
                        fail_all(x, -EAGAIN, "the device queue is full");
                else
                        x->pending++;
        }
}

static void finish(struct exposure *x)
{
        struct rig *rig = x->rig;

        for (size_t i = 0; i < x->e.n_shots; i++)
                if (x->error && x->e.shots[i].result >= 0) {
                        x->e.shots[i].result = x->error;
                        snprintf(x->e.shots[i].msg, sizeof(x->e.shots[i].msg), "%s", x->msg);
                }
        rig->exposure = NULL;
        rig_update_state(rig);
        if (x->done)
                x->done(rig, &x->e, x->ud);
        for (size_t i = 0; i < x->e.n_shots; i++)
                gn_frame_free_data(&x->e.shots[i].frame);
        free(x);
}

/* The first axis whose drive reports motion, or NULL. */
static const struct rig_axis *moving_axis(const struct rig *rig)
{
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].open && rig->axes[i].st.moving)
                        return &rig->axes[i];
        return NULL;
}

/* After BEFORE: the pose to record, unless an axis moves. */
static void check_before(struct exposure *x)
{
        const struct rig_axis *a = moving_axis(x->rig);
        char msg[256];

        x->e.pose = rig_pose(x->rig);
        if (!a)
                return;
        snprintf(msg, sizeof(msg),
                 "axis '%s' is moving (at %.3f deg) although no move was commanded",
                 a->ax->conf->name, a->st.position_deg);
        fail_all(x, -EBUSY, msg);
}

/* After AFTER: the pose must be the one recorded before the frames. */
static void check_after(struct exposure *x)
{
        struct rig *rig = x->rig;
        struct gn_pose now = rig_pose(rig);

        if (gn_pose_equal(&x->e.pose, &now, POSE_TOLERANCE_DEG))
                return;
        for (int r = 0; r < GN_ROLE_COUNT; r++) {
                int i = rigconf_axis_of_role(rig->rc, r);
                if (i >= 0 &&
                    gn_angle_distance(x->e.pose.deg[r], now.deg[r]) > POSE_TOLERANCE_DEG) {
                        rig_fault(rig, rig->rc->axes[i].name, -EIO,
                                  "axis '%s' moved during the exposure, from %.3f to %.3f deg",
                                  rig->rc->axes[i].name, x->e.pose.deg[r], now.deg[r]);
                        break;
                }
        }
        if (!rig->fault)
                rig_fault(rig, "rig", -EIO, "lamps or laser changed during the exposure");
        fail_all(x, -EIO, rig_last_error(rig));
}

/* Moves to the next stage once the current one's jobs are all back. */
static void advance(struct exposure *x)
{
        if (x->pending > 0)
                return;
        if (x->stage == EXP_BEFORE && !x->error)
                check_before(x);
        else if (x->stage == EXP_AFTER && !x->error)
                check_after(x);
        if (x->error || x->stage == EXP_AFTER || x->rig->freeing)
                return finish(x);
        x->stage++;
        submit_stage(x);
        advance(x);
}

void rig_expose_job_done(struct job *j, int result)
{
        struct exposure *x = j->exp;
        struct rig *rig = j->rig;

        x->pending--;
        if (j->kind == J_POLL && result >= 0)
                rig->axes[j->idx].st = j->st;
        if (j->kind == J_CAPTURE) {
                struct rig_shot *s = &x->e.shots[j->shot];
                s->result = result;
                if (result >= 0)
                        s->frame = j->frame, j->frame = (struct gn_frame){0};
                else if (j->why[0])
                        snprintf(s->msg, sizeof(s->msg), "%s", j->why);
                else
                        snprintf(s->msg, sizeof(s->msg), "camera '%s': capture failed: %s",
                                 rig->rc->cameras[j->idx].name, strerror(-result));
        } else if (result < 0 && result != -ECANCELED) {
                char msg[256];
                snprintf(msg, sizeof(msg), "%s", j->why);
                if (!j->why[0])
                        snprintf(msg, sizeof(msg), "axis '%s': reading the position failed: %s",
                                 rig->rc->axes[j->idx].name, strerror(-result));
                rig_fault(rig, rig->rc->axes[j->idx].name, result, "%s", msg);
                fail_all(x, result, msg);
        }
        if (result == -ECANCELED)
                fail_all(x, result, "the capture was canceled");
        advance(x);
}

void rig_expose_abandon(struct rig *rig)
{
        if (rig->exposure)
                rig->exposure->done = NULL;
}

/* Why an exposure cannot start now (writing rig->busy for -EBUSY), or 0. */
static int refusal(struct rig *rig, const int *cams, size_t n)
{
        if (rig->closing)
                return -ESHUTDOWN;
        if (rig->fault)
                return -ESTALE;
        if (rig->exposure)
                return snprintf(rig->busy, sizeof(rig->busy), "another capture is being exposed"),
                       -EBUSY;
        for (size_t i = 0; i < rig->rc->n_axes; i++)
                if (rig->axes[i].op != AX_IDLE)
                        return snprintf(rig->busy, sizeof(rig->busy), "axis '%s' is moving",
                                        rig->rc->axes[i].name),
                               -EBUSY;
        for (int i = -(int)rig->rc->n_lasers; i < (int)rig->rc->n_lamps; i++)
                if (rig_switch_slot(rig, i)->changing)
                        return snprintf(rig->busy, sizeof(rig->busy), "%s '%s' is switching",
                                        i < 0 ? "laser" : "lamp",
                                        rig_switch_conf_of(rig->rc, i)->name),
                               -EBUSY;
        for (size_t i = 0; i < n; i++)
                if (!rig->cam_open[cams[i]])
                        return -ENODEV;
        return 0;
}

int rig_expose(struct rig *rig, const int *cams, size_t n, const struct cam_request *req,
               rig_expose_fn done, void *userdata)
{
        struct exposure *x;
        int r;

        if (n == 0 || n > RIG_MAX_CAMERAS)
                return -EINVAL;
        if ((r = refusal(rig, cams, n)) < 0)
                return r;
        if (!(x = calloc(1, sizeof(*x))))
                return -ENOMEM;
        *x = (struct exposure){.rig = rig, .req = *req, .done = done, .ud = userdata};
        x->e.t_request_ns = gn_realtime_ns();
        x->e.n_shots = n;
        for (size_t i = 0; i < n; i++)
                x->e.shots[i].cam = cams[i];
        rig->exposure = x;
        rig_update_state(rig);
        submit_stage(x);
        if (x->pending == 0 && x->error) {
                rig->exposure = NULL;
                rig_update_state(rig);
                free(x);
                return -EAGAIN;
        }
        advance(x);
        return 0;
}
