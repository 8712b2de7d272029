/* rig_stream.c - camera streams: frames taken back to back while the rig moves (a
 * continuous scan), and peeks: single frames for a look (the live view); both outside the
 * confirmed-pose exposures of rig_expose.c.
 *
 * DESIGN: a stream is a chain of jobs on the camera's bus worker: START, then one NEXT
 * (a blocking dequeue, cam_stream_next: bounded) after another, each queued when the
 * previous one's frame is back on the loop, until rig_stream_stop queues STOP. A frame
 * that comes back after the stop is dropped. The caller owns the rig meanwhile. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "common/log.h"
#include "rig_internal.h"

/* Longest wait for a stream's next frame, beyond its exposure. */
#define RIG_STREAM_WAIT_MS 5000

int rig_stream_job_call(struct job *j)
{
        struct cam *c = j->rig->cams[j->idx];

        switch (j->kind) {
        case J_PEEK:
                return cam_capture(c, &j->creq, &j->frame);
        case J_STREAM_START:
                return cam_stream_start(c, &j->creq);
        case J_STREAM_NEXT:
                return cam_stream_next(c, RIG_STREAM_WAIT_MS + j->creq.exposure_us / 1000,
                                       &j->frame);
        default:
                cam_stream_stop(c);
                return 0;
        }
}

/* Queues a job of kind for camera i's stream. */
static int submit(struct rig *rig, enum job_kind kind, int i, const struct cam_request *req)
{
        struct job *j = calloc(1, sizeof(*j));

        if (!j)
                return -ENOMEM;
        *j = (struct job){.rig = rig, .kind = kind, .idx = i};
        if (req)
                j->creq = rig_camera_request(rig, i, req);
        return rig_submit(j, false);
}

/* Ends camera i's stream with an error: fn gets it once. */
static void stream_failed(struct rig *rig, int i, int result, const char *msg)
{
        struct rig_stream *st = &rig->streams[i];
        rig_frame_fn fn = st->fn;

        st->on = false;
        st->fn = NULL;
        (void)submit(rig, J_STREAM_STOP, i, NULL);
        if (fn)
                fn(rig, result, NULL, msg, st->ud);
}

/* The driver's message for a failed job, else camera, operation and errno. */
static const char *job_message(struct job *j, int result, char *buf, size_t len)
{
        if (j->why[0])
                return j->why;
        snprintf(buf, len, "camera '%s': streaming failed: %s", j->rig->rc->cameras[j->idx].name,
                 strerror(-result));
        return buf;
}

/* A peek's frame is back: to its fn unless forgotten. */
static void peek_done(struct job *j, int result)
{
        struct rig_peek *pk = &j->rig->peeks[j->idx];
        rig_frame_fn fn = pk->fn;
        void *ud = pk->ud;
        char msg[256];

        *pk = (struct rig_peek){0};
        if (fn && !j->rig->freeing)
                fn(j->rig, result, result < 0 ? NULL : &j->frame,
                   result < 0 ? job_message(j, result, msg, sizeof(msg)) : NULL, ud);
}

void rig_stream_job_done(struct job *j, int result)
{
        struct rig *rig = j->rig;
        struct rig_stream *st = &rig->streams[j->idx];
        char msg[256];
        int r;

        if (j->kind == J_PEEK)
                return peek_done(j, result);
        if (j->kind == J_STREAM_STOP)
                return;
        if (j->kind == J_STREAM_NEXT)
                st->next = false;
        if (!st->on)
                return; /* stopped meanwhile: the frame is dropped */
        if (result < 0)
                return stream_failed(rig, j->idx, result, job_message(j, result, msg, sizeof(msg)));
        if ((r = submit(rig, J_STREAM_NEXT, j->idx, &j->creq)) < 0)
                return stream_failed(rig, j->idx, r, "the camera's queue is full");
        st->next = true;
        if (j->kind == J_STREAM_NEXT)
                st->fn(rig, 0, &j->frame, NULL, st->ud);
}

/* Queues the first job (kind) of a stream or a peek of camera i (busy: it has one already),
 * unless the rig refuses it. Returns 0 or -errno. */
static int begin(struct rig *rig, int i, bool busy, enum job_kind kind,
                 const struct cam_request *req)
{
        if (rig->closing)
                return -ESHUTDOWN;
        if (rig->fault)
                return -ESTALE;
        if (busy)
                return -EBUSY;
        return rig->cam_open[i] ? submit(rig, kind, i, req) : -ENODEV;
}

int rig_stream_start(struct rig *rig, int i, const struct cam_request *req, rig_frame_fn fn,
                     void *userdata)
{
        struct rig_stream *st = &rig->streams[i];
        int r = begin(rig, i, st->on || st->next, J_STREAM_START, req);

        if (r < 0)
                return r;
        *st = (struct rig_stream){.on = true, .fn = fn, .ud = userdata};
        return 0;
}

int rig_peek(struct rig *rig, int i, const struct cam_request *req, rig_frame_fn fn, void *userdata)
{
        struct rig_peek *pk = &rig->peeks[i];
        int r = begin(rig, i, pk->busy || rig->streams[i].on || rig->streams[i].next, J_PEEK, req);

        if (r < 0)
                return r;
        *pk = (struct rig_peek){.busy = true, .fn = fn, .ud = userdata};
        return 0;
}

void rig_peek_cancel(struct rig *rig, int i)
{
        rig->peeks[i].fn = NULL;
}

void rig_stream_stop(struct rig *rig, int i)
{
        struct rig_stream *st = &rig->streams[i];

        if (!st->on)
                return;
        st->on = false;
        st->fn = NULL;
        if (submit(rig, J_STREAM_STOP, i, NULL) < 0)
                log_warning("camera '%s': cannot queue the end of its stream",
                            rig->rc->cameras[i].name);
}
