/* datasets.h - the dataset.* methods of the control protocol (docs/protocol.md):
 * open (or create), close, list and info, on the manager's open dataset and its data
 * directory; and the JSON shape of a stored capture, shared with the capture reply. */
#pragma once

#include <jansson.h>

#include "common/workq.h"
#include "dataset/ds.h"
#include "server.h"

/* The JSON object of a stored capture (docs/protocol.md, `capture`). New reference, or
 * NULL without memory. */
json_t *datasets_row_json(const struct ds_capture *c);

struct manager;

/* Method handlers (srv_method_fn) with the struct manager as userdata. Each answers
 * when the dataset worker is done; -EBUSY while a capture is in flight or another open
 * or close runs, -EAGAIN when the worker's queue is full. Loop thread. */
int datasets_open(struct srv_req *req, json_t *params, void *userdata);
int datasets_close(struct srv_req *req, json_t *params, void *userdata);
int datasets_list(struct srv_req *req, json_t *params, void *userdata);
int datasets_info(struct srv_req *req, json_t *params, void *userdata);
/* dataset.check: rows, files, checksums, orphans and the session plans (ds_check), on a
 * handle of its own; an error listing the problems when there are any. */
int datasets_check(struct srv_req *req, json_t *params, void *userdata);

/* Queues fn on the dataset worker ("ds-ops", started on first use); done runs on the loop.
 * Returns 0, -EAGAIN (queue full) or -errno. */
int datasets_push(struct manager *m, workq_fn fn, workq_done_fn done, void *userdata);

/* Makes d (named name, holding count rows) the capture pipeline's dataset. On failure d is
 * closed on the worker. Returns 0 or capture_attach's -errno. */
int datasets_attach(struct manager *m, struct ds *d, const char *name, int64_t count);

/* The path of dataset name in the data directory: 0, -EINVAL (not one component of
 * [A-Za-z0-9._-] not starting with '.') or -ENAMETOOLONG. */
int datasets_path(const struct manager *m, const char *name, char *path, size_t len);

/* Stops the dataset worker after its running job; queued jobs are answered as
 * cancelled (an open or close in flight leaves the dataset it held open in m, for the
 * caller to close). Call before freeing the server, the pool and m->ds. */
void datasets_free(struct manager *m);
