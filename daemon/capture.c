/* capture.c - goniod's capture pipeline (see capture.h).
 *
 * DESIGN: a request owns one struct take. Its exposure comes back from the rig
 * with every frame and the pose the devices confirmed around it; each good frame
 * becomes a row and goes to the storage pool, and the request completes when the
 * last store has answered. A store that fails (a full disk) faults the rig, so it
 * goes to its safe state before anything else is tried; the rows committed before
 * stay and are reported as stored, so a retry never duplicates them. */
#include <assert.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "common/log.h"
#include "capture.h"
#include "dataset/ds_session.h"

#define POOL_ENCODERS 2
#define POOL_CAPACITY 16

struct take {
        struct capture *cp;
        struct capture_result res;
        unsigned pending; /* stores not answered yet */
        char session[DS_NAME_MAX];
        char kind[8];
        struct gn_pose planned;
        struct capture_tag tag; /* session, kind and planned point into the take */
        capture_done_fn done;
        void *ud;
        struct take *next;
};

struct capture {
        sd_event *event;
        struct rig *rig;
        struct ds *ds;
        struct ds_pool *pool;
        char ds_name[DS_NAME_MAX];
        int64_t ds_count;
        struct take *exposing; /* takes whose exposure has not come back */
        capture_stored_fn stored;
        void *stored_ud;
        capture_tap_fn tap;
        void *tap_ud;
};

int capture_new(sd_event *event, struct rig *rig, capture_stored_fn stored, void *userdata,
                struct capture **ret)
{
        struct capture *cp = calloc(1, sizeof(*cp));

        if (!cp)
                return -ENOMEM;
        *cp = (struct capture){.event = event, .rig = rig, .stored = stored, .stored_ud = userdata};
        *ret = cp;
        return 0;
}

static void unlink_exposing(struct capture *cp, struct take *t)
{
        for (struct take **p = &cp->exposing; *p; p = &(*p)->next)
                if (*p == t) {
                        *p = t->next;
                        return;
                }
}

struct capture *capture_free(struct capture *cp)
{
        if (!cp)
                return NULL;
        while (cp->exposing) {
                struct take *t = cp->exposing;
                cp->exposing = t->next;
                free(t); /* the rig drops the completion at rig_free */
        }
        cp->pool = ds_pool_free(cp->pool); /* answers the stores */
        cp->ds = ds_close(cp->ds);
        free(cp);
        return NULL;
}

void capture_set_tap(struct capture *cp, capture_tap_fn fn, void *userdata)
{
        cp->tap = fn;
        cp->tap_ud = userdata;
}

unsigned capture_in_flight(const struct capture *cp)
{
        return (cp->exposing != NULL) + ds_pool_in_flight(cp->pool); /* stores: the pool's */
}

struct ds *capture_detach(struct capture *cp)
{
        struct ds *d = cp->ds;

        assert(capture_in_flight(cp) == 0);
        cp->pool = ds_pool_free(cp->pool);
        cp->ds = NULL;
        cp->ds_name[0] = 0;
        cp->ds_count = 0;
        return d;
}

int capture_attach(struct capture *cp, struct ds *d, const char *name, int64_t count)
{
        int r;

        if (capture_in_flight(cp) > 0 || cp->ds)
                return -EBUSY;
        r = ds_pool_new(cp->event, d, POOL_ENCODERS, POOL_CAPACITY, &cp->pool);
        if (r < 0)
                return r;
        cp->ds = d;
        cp->ds_count = count;
        snprintf(cp->ds_name, sizeof(cp->ds_name), "%s", name);
        return 0;
}

struct ds *capture_dataset(const struct capture *cp)
{
        return cp->ds;
}

const char *capture_dataset_name(const struct capture *cp)
{
        return cp->ds ? cp->ds_name : NULL;
}

int64_t capture_dataset_count(const struct capture *cp)
{
        return cp->ds_count;
}

static void take_part_done(struct take *t)
{
        struct capture *cp = t->cp;

        if (--t->pending > 0)
                return;
        t->done(cp, &t->res, t->ud);
        free(t);
}

/* One shot's store job: which take and which shot. */
struct store_ref {
        struct take *t;
        size_t shot;
};

static void on_stored(int result, const struct ds_capture *c, const char *error, void *userdata)
{
        struct store_ref *ref = userdata;
        struct take *t = ref->t;
        struct capture_shot *s = &t->res.shots[ref->shot];
        struct capture *cp = t->cp;

        free(ref);
        s->result = result;
        if (result >= 0) {
                s->row = *c;
                cp->ds_count++;
                if (cp->stored)
                        cp->stored(cp->stored_ud, c);
        } else {
                snprintf(s->msg, sizeof(s->msg),
                         "camera '%s': storing the frame in dataset '%s' failed: %s", c->camera,
                         cp->ds_name, result == -ECANCELED ? "canceled at shutdown" : error);
                if (result != -ECANCELED)
                        rig_fault(cp->rig, "dataset", result, "%s", s->msg);
        }
        take_part_done(t);
}

/* The row describing shot s of exposure e. */
static void fill_row(struct capture *cp, const struct take *t, const struct rig_exposure *e,
                     const struct rig_shot *s, struct ds_capture *row)
{
        const struct rig_config *rc = rig_config(cp->rig);
        const char *names[RIG_MAX_LAMPS];

        for (size_t i = 0; i < rc->n_lamps; i++)
                names[i] = rc->lamps[i].name;
        row->pose = e->pose;
        (void)gn_pose_lamp_list(&e->pose, names, rc->n_lamps, row->lamps, sizeof(row->lamps));
        snprintf(row->session, sizeof(row->session), "%s", t->session);
        snprintf(row->kind, sizeof(row->kind), "%s", t->kind);
        row->bracket = t->tag.bracket;
        row->plan_seq = t->tag.plan_seq[s - e->shots];
        row->dark_id = t->tag.dark_id[s - e->shots];
        row->flat_id = t->tag.flat_id[s - e->shots];
        row->exposure_us = s->frame.exposure_us;
        row->gain = s->frame.gain;
        row->t_request_ns = e->t_request_ns;
        row->t_exposure_ns = s->frame.timestamp_ns;
}

/* True when the exposure's pose is the planned one (see struct capture_tag). */
static bool as_planned(const struct gn_pose *got, const struct gn_pose *want)
{
        for (int r = 0; r < GN_ROLE_COUNT; r++)
                if (!isnan(want->deg[r]) &&
                    (isnan(got->deg[r]) ||
                     gn_angle_distance(got->deg[r], want->deg[r]) > DS_PLAN_POSE_TOL_DEG))
                        return false;
        return got->lamps == want->lamps && got->lasers == want->lasers;
}

/* Hands shot i's frame to the storage pool, or records why it cannot be stored. */
static void store_shot(struct take *t, struct rig_exposure *e, size_t i)
{
        struct capture *cp = t->cp;
        struct rig_shot *s = &e->shots[i];
        struct capture_shot *out = &t->res.shots[i];
        struct store_ref *ref;
        int r;

        out->result = s->result;
        if (s->result < 0)
                return (void)snprintf(out->msg, sizeof(out->msg), "%s", s->msg);
        if (cp->tap)
                cp->tap(cp->tap_ud, s->cam, &s->frame);
        if (t->tag.planned && !as_planned(&e->pose, t->tag.planned)) {
                out->result = -EIO;
                return (void)snprintf(out->msg, sizeof(out->msg),
                                      "camera '%s': not stored: the rig was not in the planned "
                                      "pose (an axis or a switch changed behind goniod's back)",
                                      rig_config(cp->rig)->cameras[s->cam].name);
        }
        if (!cp->pool)
                r = -ESTALE;
        else if (!(ref = malloc(sizeof(*ref))))
                r = -ENOMEM;
        else {
                *ref = (struct store_ref){t, i};
                fill_row(cp, t, e, s, &out->row);
                r = ds_pool_store(cp->pool, &s->frame, &out->row, on_stored, ref);
                if (r >= 0)
                        return (void)t->pending++;
                free(ref);
        }
        out->result = r;
        snprintf(out->msg, sizeof(out->msg), "camera '%s': %s",
                 rig_config(cp->rig)->cameras[s->cam].name,
                 r == -EAGAIN   ? "the storage queue is full"
                 : r == -ESTALE ? "the dataset was closed during the capture"
                                : strerror(-r));
}

/* Hands every frame of e to the storage pool; t completes when the last is stored. */
static void hand_over(struct take *t, struct rig_exposure *e)
{
        struct capture *cp = t->cp;

        t->pending = 1; /* held until every shot is handed over */
        for (size_t i = 0; i < e->n_shots; i++)
                store_shot(t, e, i);
        if (t->tag.exposed)
                t->tag.exposed(cp, t->ud);
        take_part_done(t);
}

static void on_exposed(struct rig *rig, struct rig_exposure *e, void *userdata)
{
        struct take *t = userdata;

        unlink_exposing(t->cp, t);
        hand_over(t, e);
}

size_t capture_store_room(const struct capture *cp)
{
        size_t used = ds_pool_in_flight(cp->pool);

        for (const struct take *t = cp->exposing; t; t = t->next)
                used += t->res.n_shots; /* frames on their way to the pool */
        return cp->pool && used < POOL_CAPACITY ? POOL_CAPACITY - used : 0;
}

/* A take of cams[0..n) labelled by tag (copied; may be NULL), not linked anywhere yet. */
static struct take *take_new(struct capture *cp, const int *cams, size_t n,
                             const struct capture_tag *tag, capture_done_fn done, void *userdata)
{
        const struct rig_config *rc = rig_config(cp->rig);
        struct take *t = calloc(1, sizeof(*t));

        if (!t)
                return NULL;
        *t = (struct take){.cp = cp, .done = done, .ud = userdata};
        if (tag)
                t->tag = *tag;
        if (tag && tag->planned) {
                t->planned = *tag->planned;
                t->tag.planned = &t->planned;
        }
        snprintf(t->session, sizeof(t->session), "%s", tag && tag->session ? tag->session : "");
        snprintf(t->kind, sizeof(t->kind), "%s", tag && tag->kind ? tag->kind : "image");
        t->res.n_shots = n;
        for (size_t i = 0; i < n; i++)
                snprintf(t->res.shots[i].row.camera, sizeof(t->res.shots[i].row.camera), "%s",
                         rc->cameras[cams[i]].name);
        return t;
}

int capture_take(struct capture *cp, const int *cams, size_t n, const struct cam_request *req,
                 const struct capture_tag *tag, capture_done_fn done, void *userdata)
{
        struct take *t;
        int r;

        if (!cp->pool)
                return -ESTALE;
        if (n == 0 || n > RIG_MAX_CAMERAS)
                return -EINVAL;
        if (capture_store_room(cp) < n)
                return -EAGAIN;
        if (!(t = take_new(cp, cams, n, tag, done, userdata)))
                return -ENOMEM;
        t->next = cp->exposing;
        cp->exposing = t;
        r = rig_expose(cp->rig, cams, n, req, on_exposed, t);
        if (r < 0) {
                unlink_exposing(cp, t);
                free(t);
        }
        return r;
}

int capture_store_frame(struct capture *cp, int cam, struct gn_frame *frame,
                        const struct gn_pose *pose, const struct capture_tag *tag,
                        capture_done_fn done, void *userdata)
{
        struct rig_exposure e = {.pose = *pose, .t_request_ns = frame->timestamp_ns, .n_shots = 1};
        struct take *t;

        if (!cp->pool)
                return -ESTALE;
        if (capture_store_room(cp) < 1)
                return -EAGAIN;
        if (!(t = take_new(cp, &cam, 1, tag, done, userdata)))
                return -ENOMEM;
        e.shots[0] = (struct rig_shot){.cam = cam, .frame = *frame};
        *frame = (struct gn_frame){0};
        hand_over(t, &e);
        gn_frame_free_data(&e.shots[0].frame);
        return 0;
}
