/* ds_pool.c - the storage worker pool: PNG encoding on worker threads, one writer
 * thread that owns the dataset, completions on the sd-event loop (see ds_pool.h).
 *
 * DESIGN
 * Two stages, each made of common/workq workers. n encoder queues run ds_png_encode
 * (CPU bound, in parallel); one writer queue runs ds_store_png (write, fsync, rename,
 * commit), so the struct ds is used by a single thread and no lock is held across
 * I/O. A job's encode completion arrives on the loop, which hands the job to the
 * writer; the writer's completion arrives on the loop, which calls the caller's done.
 *
 * Capacity: the pool counts a job from ds_pool_store until just before its done is
 * called (a done sees its own job finished, like every in-flight count of common/workq
 * and daemon/); past capacity it returns -EAGAIN. Every workq is sized for all jobs
 * in flight, so the hand-over to the writer never fails for lack of room.
 *
 * Order: with one encoder, rows are committed in submission order; with more, in the
 * order the encodes finish (row ids follow commit order; t_request_ns keeps the order
 * of the requests).
 *
 * Outcome: a job's done reports exactly what the writer did: 0 only after its row was
 * committed, else the -errno and message of the stage that failed (the store leaves
 * nothing behind on failure, see ds.c); the result is never changed after the commit.
 *
 * Shutdown: ds_pool_free frees the encoders first (finished encodes are handed to the
 * writer, queued ones are cancelled), then the writer (its running store completes,
 * queued ones are cancelled). Every accepted job gets exactly one done. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/workq.h"
#include "ds_png.h"
#include "ds_pool.h"

#define DS_POOL_MAX_ENCODERS 16

struct ds_pool {
        struct ds *ds; /* borrowed; used by the writer thread only */
        struct workq *encoders[DS_POOL_MAX_ENCODERS];
        unsigned n_encoders;
        struct workq *writer;
        size_t capacity, in_flight;
};

struct store_job {
        struct ds_pool *pool;
        struct gn_frame frame; /* pixels owned until encoded; the shape is kept */
        struct ds_capture capture;
        int level;
        void *png;
        size_t len;
        ds_pool_done_fn done;
        void *userdata;
        char error[256]; /* why the job failed, set by the thread that failed it */
};

/* Answers j and frees it. The job stops counting as in flight before its done runs, so
 * that done sees the pool as it is after the job (idle after the last one). */
static void job_finish(struct store_job *j, int result)
{
        if (result == -ECANCELED && !j->error[0])
                snprintf(j->error, sizeof(j->error), "cancelled before it was stored");
        if (result < 0)
                j->capture.id = 0;
        j->pool->in_flight--;
        if (j->done)
                j->done(result, &j->capture, result < 0 ? j->error : "", j->userdata);
        free(j->png);
        gn_frame_free_data(&j->frame);
        free(j);
}

/* Encoder thread. */
static int encode_job(void *userdata)
{
        struct store_job *j = userdata;
        int r = ds_png_encode(&j->frame, j->level, &j->png, &j->len);

        if (r < 0)
                snprintf(j->error, sizeof(j->error), "Failed to encode %dx%d %s frame: %s",
                         j->frame.width, j->frame.height, gn_frame_format(&j->frame), strerror(-r));
        free(j->frame.data);
        j->frame.data = NULL;
        return r;
}

/* Writer thread. */
static int write_job(void *userdata)
{
        struct store_job *j = userdata;
        int r = ds_store_png(j->pool->ds, j->png, j->len, &j->frame, &j->capture);

        if (r < 0)
                snprintf(j->error, sizeof(j->error), "%s", ds_last_error(j->pool->ds));
        return r;
}

static void write_done(int result, void *userdata)
{
        job_finish(userdata, result);
}

static void encode_done(int result, void *userdata)
{
        struct store_job *j = userdata;

        if (result >= 0)
                result = workq_push(j->pool->writer, write_job, write_done, j, false);
        if (result < 0)
                job_finish(j, result);
}

int ds_pool_new(sd_event *event, struct ds *d, unsigned n_encoders, size_t capacity,
                struct ds_pool **ret)
{
        struct ds_pool *p;
        int r = 0;

        if (!event || !d || n_encoders < 1 || n_encoders > DS_POOL_MAX_ENCODERS || capacity < 1 ||
            !ret)
                return -EINVAL;
        p = calloc(1, sizeof(*p));
        if (!p)
                return -ENOMEM;
        p->ds = d;
        p->capacity = capacity;
        for (unsigned i = 0; i < n_encoders && r == 0; i++) {
                char name[16];

                snprintf(name, sizeof(name), "ds-enc%u", i);
                r = workq_new(event, name, capacity, &p->encoders[i]);
                p->n_encoders += r == 0;
        }
        if (r == 0)
                r = workq_new(event, "ds-write", capacity, &p->writer);
        if (r < 0) {
                ds_pool_free(p);
                return r;
        }
        *ret = p;
        return 0;
}

struct ds_pool *ds_pool_free(struct ds_pool *p)
{
        if (!p)
                return NULL;
        for (unsigned i = 0; i < p->n_encoders; i++)
                p->encoders[i] = workq_free(p->encoders[i]);
        p->writer = workq_free(p->writer);
        free(p);
        return NULL;
}

static struct workq *least_busy_encoder(struct ds_pool *p)
{
        struct workq *best = p->encoders[0];

        for (unsigned i = 1; i < p->n_encoders; i++)
                if (workq_in_flight(p->encoders[i]) < workq_in_flight(best))
                        best = p->encoders[i];
        return best;
}

int ds_pool_store(struct ds_pool *p, struct gn_frame *frame, const struct ds_capture *c,
                  ds_pool_done_fn done, void *userdata)
{
        struct store_job *j;
        int r;

        if (!p || !frame || !frame->data || !c)
                return -EINVAL;
        if (p->in_flight >= p->capacity)
                return -EAGAIN;
        j = calloc(1, sizeof(*j));
        if (!j)
                return -ENOMEM;
        *j = (struct store_job){.pool = p,
                                .frame = *frame,
                                .capture = *c,
                                .level = ds_get_compression(p->ds),
                                .done = done,
                                .userdata = userdata};
        j->capture.id = 0; /* set once committed */
        r = workq_push(least_busy_encoder(p), encode_job, encode_done, j, false);
        if (r < 0) {
                free(j);
                return r;
        }
        *frame = (struct gn_frame){};
        p->in_flight++;
        return 0;
}

size_t ds_pool_in_flight(const struct ds_pool *p)
{
        return p ? p->in_flight : 0;
}
