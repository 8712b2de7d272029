/* ds_pool.h - the storage worker pool of goniod: stores captured frames in a
 * dataset off the event loop, with a bounded number of jobs in flight and the
 * completions delivered on the sd-event loop. */
#pragma once

#include <stddef.h>

#include "common/frame.h"
#include "ds.h"

typedef struct sd_event sd_event;

struct ds_pool;

/* Called on the loop thread exactly once per accepted job, saying what became of its
 * frame. result 0: the row is committed, and c is that row (c->id > 0, file, sha256...).
 * result < 0: nothing of the frame is recorded (no row, no file, not even after a full
 * disk) and c->id is 0: -ECANCELED (dropped by ds_pool_free before it ran), or the
 * -errno of the encoder or of ds_store_png (-ENOSPC, -EFBIG...), with error saying why
 * (ds_last_error(), or the encoder's failure); error is "" on success. A frame is never
 * reported failed once its row is committed. c and error are valid during the call
 * only. */
typedef void (*ds_pool_done_fn)(int result, const struct ds_capture *c, const char *error,
                                void *userdata);

/* Starts n_encoders PNG encoder threads and one writer thread storing into d, taking
 * at most capacity jobs in flight. While the pool lives, d belongs to its writer: the
 * caller uses d (or frees it) only when ds_pool_in_flight() is 0, or opens a second
 * handle for reading. event must be the loop of the calling thread. Returns 0,
 * -EINVAL or -errno; *ret is freed with ds_pool_free(). */
int ds_pool_new(sd_event *event, struct ds *d, unsigned n_encoders, size_t capacity,
                struct ds_pool **ret);

/* Cancels jobs that have not run (their done gets -ECANCELED), waits for the running
 * ones, delivers every completion, and frees the pool (not d). Loop thread. NULL is a
 * no-op; returns NULL. */
struct ds_pool *ds_pool_free(struct ds_pool *p);

/* Queues frame for storing with the metadata c. On success the pool takes the
 * frame's pixels (*frame is zeroed) and calls done exactly once. Returns 0, -EAGAIN
 * when capacity jobs are in flight (frame untouched), -EINVAL or -ENOMEM. Loop thread. */
int ds_pool_store(struct ds_pool *p, struct gn_frame *frame, const struct ds_capture *c,
                  ds_pool_done_fn done, void *userdata);

/* Jobs accepted whose done has not been called yet; a job no longer counts during its own
 * done (0 in the last job's done). Loop thread. */
size_t ds_pool_in_flight(const struct ds_pool *p);
