/* datasets.h - the dataset.* methods of the control protocol (docs/protocol.md):
 * open (or create), close, list and info, on the manager's open dataset and its data
 * directory; and the JSON shape of a stored capture, shared with the capture reply. */
#pragma once

#include <jansson.h>

#include "dataset/ds.h"
#include "server.h"

/* The JSON object of a stored capture (docs/protocol.md, `capture`). New reference, or
 * NULL without memory. */
json_t *datasets_row_json(const struct ds_capture *c);

/* Method handlers (srv_method_fn) with the struct manager as userdata. */
int datasets_open(struct srv_req *req, json_t *params, void *userdata);
int datasets_close(struct srv_req *req, json_t *params, void *userdata);
int datasets_list(struct srv_req *req, json_t *params, void *userdata);
int datasets_info(struct srv_req *req, json_t *params, void *userdata);
