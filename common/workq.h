/* workq.h - a worker thread with a fixed-size job queue whose completions are
 * delivered on an sd-event loop (or on the worker when there is no loop).
 *
 * Used by the bus workers (drivers/bus) and the dataset store's storage pool.
 * Every job pushed successfully gets exactly one done call: with its result,
 * or with -ECANCELED when workq_free() drops it before it ran. */
#pragma once

#include <stdbool.h>
#include <stddef.h>

typedef struct sd_event sd_event;

/* Extra slots only urgent jobs may use, so that a stop gets through a full queue. */
#define WORKQ_URGENT_RESERVE 4

struct workq;

/* Runs on the worker thread; returns >= 0 or -errno. */
typedef int (*workq_fn)(void *userdata);
/* Runs on the loop thread (or the worker without a loop) with the job's result. */
typedef void (*workq_done_fn)(int result, void *userdata);

/* Starts a worker named name (thread and event source "workq-NAME") taking up to capacity
 * jobs not yet completed; event may be NULL (done then runs on the worker). Call on the
 * loop's thread. Returns 0, -EINVAL or -errno; *ret is freed with workq_free(). */
int workq_new(sd_event *event, const char *name, size_t capacity, struct workq **ret);

/* Stops the worker after its running job, delivers completed results, then calls done
 * with -ECANCELED for every job that never ran, on the calling (loop) thread. Must not be
 * called from a job; may be called from a done callback of q (q's memory is then released
 * when that callback returns). NULL is a no-op; returns NULL. */
struct workq *workq_free(struct workq *q);

/* Queues fn; urgent jobs run before every normal job (FIFO among themselves) and may use
 * WORKQ_URGENT_RESERVE extra slots. done may be NULL. Any thread. Returns 0, -EAGAIN when
 * the queue is full, -ESHUTDOWN once workq_free() began. */
int workq_push(struct workq *q, workq_fn fn, workq_done_fn done, void *userdata, bool urgent);

/* Jobs pushed and not yet completed (queued, running or awaiting delivery); a job no longer
 * counts during its own done. Any thread. */
size_t workq_in_flight(struct workq *q);
