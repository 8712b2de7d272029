/* workq.c - a worker thread with a bounded job queue and loop-delivered completions.
 *
 * DESIGN
 * Threads: one worker thread per queue runs the jobs, one at a time; the owner's
 * thread (the sd-event loop thread, when there is a loop) pushes jobs, receives the
 * completions and frees the queue. workq_push() itself may be called from any thread.
 *
 * Queue: all storage is allocated at creation. A job is "in flight" from a successful
 * push until just before its done callback is called (a done sees its own job gone,
 * whichever thread delivers it); at most capacity jobs are in flight, plus
 * WORKQ_URGENT_RESERVE slots that only urgent jobs may take. A push beyond that fails
 * with -EAGAIN: callers see back-pressure instead of unbounded memory.
 *
 * Ordering: urgent jobs run before all normal jobs, each kind in push order (two FIFO
 * rings). Completions are delivered in the order the jobs finished. The worker writes
 * an eventfd after each job; the loop's io handler drains the completion ring and calls
 * each done outside the lock, so a done callback may push the next job.
 *
 * Shutdown: workq_free() sets stopping, wakes and joins the worker (which finishes the
 * running job only), then on the caller's thread delivers finished results and cancels
 * queued jobs with -ECANCELED, so every job's userdata can be released by its done. */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <systemd/sd-event.h>

#include "cleanup.h"
#include "log.h"
#include "workq.h"

struct job {
        workq_fn fn;
        workq_done_fn done;
        void *userdata;
        int result;
};

struct ring {
        struct job *v;
        size_t head, len, cap;
};

struct workq {
        char name[32];
        size_t capacity;  /* normal jobs in flight */
        size_t in_flight; /* pushed, done not yet called */
        bool stopping;
        bool started;
        bool delivering; /* on_eventfd is calling done callbacks (loop thread) */
        bool dying;      /* workq_free ran inside one of them: on_eventfd frees q */
        pthread_mutex_t lock;
        pthread_cond_t wake;
        pthread_t thread;
        struct ring urgent, normal, finished;
        sd_event_source *source;
        int efd;
};

static int ring_init(struct ring *r, size_t cap)
{
        r->v = calloc(cap, sizeof(*r->v));
        r->cap = cap;
        return r->v ? 0 : -ENOMEM;
}

static void ring_push(struct ring *r, const struct job *j)
{
        r->v[(r->head + r->len++) % r->cap] = *j;
}

static bool ring_pop(struct ring *r, struct job *j)
{
        if (r->len == 0)
                return false;
        *j = r->v[r->head];
        r->head = (r->head + 1) % r->cap;
        r->len--;
        return true;
}

/* Takes the next finished job under the lock and releases its slot. */
static bool take_finished(struct workq *q, struct job *j)
{
        bool got;

        pthread_mutex_lock(&q->lock);
        got = ring_pop(&q->finished, j);
        if (got)
                q->in_flight--;
        pthread_mutex_unlock(&q->lock);
        return got;
}

static void deliver(const struct job *j)
{
        if (j->done)
                j->done(j->result, j->userdata);
}

static void destroy(struct workq *q);

/* Delivers the finished jobs on the loop. A done callback may free q (workq_free): then q
 * is freed here, once that callback has returned. */
static int on_eventfd(sd_event_source *s, int fd, uint32_t revents, void *userdata)
{
        struct workq *q = userdata;
        eventfd_t n;
        struct job j;

        (void)eventfd_read(fd, &n); /* EAGAIN when a previous round drained it: fine */
        q->delivering = true;
        while (!q->dying && take_finished(q, &j))
                deliver(&j);
        q->delivering = false;
        if (q->dying)
                destroy(q);
        return 0;
}

/* Worker side of one job: hand the result to the loop, or deliver it here without one. */
static void finish(struct workq *q, struct job *j)
{
        if (q->efd < 0) {
                pthread_mutex_lock(&q->lock);
                q->in_flight--; /* before done, as on the loop (take_finished) */
                pthread_mutex_unlock(&q->lock);
                deliver(j);
                pthread_mutex_lock(&q->lock);
                return;
        }
        pthread_mutex_lock(&q->lock);
        ring_push(&q->finished, j);
        pthread_mutex_unlock(&q->lock);
        if (eventfd_write(q->efd, 1) < 0)
                log_error_errno(errno, "workq '%s': Failed to signal completion: %m", q->name);
        pthread_mutex_lock(&q->lock);
}

static void *worker(void *userdata)
{
        struct workq *q = userdata;
        struct job j;

        pthread_mutex_lock(&q->lock);
        for (;;) {
                while (!q->stopping && q->urgent.len == 0 && q->normal.len == 0)
                        pthread_cond_wait(&q->wake, &q->lock);
                if (q->stopping)
                        break;
                if (!ring_pop(&q->urgent, &j))
                        ring_pop(&q->normal, &j);
                pthread_mutex_unlock(&q->lock);
                j.result = j.fn(j.userdata);
                finish(q, &j); /* returns with the lock held */
        }
        pthread_mutex_unlock(&q->lock);
        return NULL;
}

static int attach_loop(struct workq *q, sd_event *event)
{
        char desc[48];
        int r;

        q->efd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
        if (q->efd < 0)
                return log_error_errno(errno, "workq '%s': Failed to create eventfd: %m", q->name);
        r = sd_event_add_io(event, &q->source, q->efd, EPOLLIN, on_eventfd, q);
        if (r < 0)
                return log_error_errno(r, "workq '%s': Failed to add event source: %m", q->name);
        snprintf(desc, sizeof(desc), "workq-%s", q->name);
        (void)sd_event_source_set_description(q->source, desc);
        return 0;
}

static int start_worker(struct workq *q)
{
        char tname[16]; /* the kernel's limit, with the NUL */
        int r;

        r = pthread_create(&q->thread, NULL, worker, q);
        if (r != 0)
                return log_error_errno(r, "workq '%s': Failed to start worker: %m", q->name);
        q->started = true;
        snprintf(tname, sizeof(tname), "wq-%.12s", q->name);
        (void)pthread_setname_np(q->thread, tname);
        return 0;
}

int workq_new(sd_event *event, const char *name, size_t capacity, struct workq **ret)
{
        struct workq *q;
        size_t slots = capacity + WORKQ_URGENT_RESERVE;
        int r;

        if (!name || !ret || capacity == 0)
                return -EINVAL;
        q = calloc(1, sizeof(*q));
        if (!q)
                return -ENOMEM;
        snprintf(q->name, sizeof(q->name), "%s", name);
        q->capacity = capacity;
        q->efd = -EBADF;
        pthread_mutex_init(&q->lock, NULL);
        pthread_cond_init(&q->wake, NULL);
        r = ring_init(&q->urgent, slots);
        if (r >= 0)
                r = ring_init(&q->normal, slots);
        if (r >= 0)
                r = ring_init(&q->finished, slots);
        if (r >= 0 && event)
                r = attach_loop(q, event);
        if (r >= 0)
                r = start_worker(q);
        if (r < 0) {
                workq_free(q);
                return r;
        }
        *ret = q;
        return 0;
}

/* Calls done(-ECANCELED) for each job left in r, its slot released first; caller's
 * thread, worker already joined. */
static void cancel_ring(struct workq *q, struct ring *r)
{
        struct job j;

        while (ring_pop(r, &j)) {
                q->in_flight--;
                j.result = -ECANCELED;
                deliver(&j);
        }
}

struct workq *workq_free(struct workq *q)
{
        struct job j;

        if (!q)
                return NULL;
        pthread_mutex_lock(&q->lock);
        q->stopping = true;
        pthread_cond_signal(&q->wake);
        pthread_mutex_unlock(&q->lock);
        if (q->started)
                pthread_join(q->thread, NULL);

        q->source = sd_event_source_disable_unref(q->source);
        while (take_finished(q, &j))
                deliver(&j);
        cancel_ring(q, &q->urgent);
        cancel_ring(q, &q->normal);

        if (q->delivering)
                q->dying = true; /* freed by on_eventfd when the callback we are in returns */
        else
                destroy(q);
        return NULL;
}

static void destroy(struct workq *q)
{
        closep(&q->efd);
        free(q->urgent.v);
        free(q->normal.v);
        free(q->finished.v);
        pthread_cond_destroy(&q->wake);
        pthread_mutex_destroy(&q->lock);
        free(q);
}

int workq_push(struct workq *q, workq_fn fn, workq_done_fn done, void *userdata, bool urgent)
{
        struct job j = {.fn = fn, .done = done, .userdata = userdata};
        size_t limit;
        int r = 0;

        if (!q || !fn)
                return -EINVAL;
        pthread_mutex_lock(&q->lock);
        limit = q->capacity + (urgent ? WORKQ_URGENT_RESERVE : 0);
        if (q->stopping)
                r = -ESHUTDOWN;
        else if (q->in_flight >= limit)
                r = -EAGAIN;
        else {
                ring_push(urgent ? &q->urgent : &q->normal, &j);
                q->in_flight++;
                pthread_cond_signal(&q->wake);
        }
        pthread_mutex_unlock(&q->lock);
        return r;
}

size_t workq_in_flight(struct workq *q)
{
        size_t n;

        pthread_mutex_lock(&q->lock);
        n = q->in_flight;
        pthread_mutex_unlock(&q->lock);
        return n;
}
