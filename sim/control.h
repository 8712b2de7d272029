/* control.h - gonio-sim's control channel: the requests that inspect or disturb the
 * simulated rig rather than expose a frame: "state", "geometry" and "inject" (Modbus
 * device faults and camera faults), specified in docs/sim.md. The frame server reads
 * them from its socket and dispatches every request but "render" here; camera faults
 * are kept here and consumed by the frame server's render requests.
 *
 * Not thread-safe: every call runs on the frame server's thread. */
#pragma once

#include <jansson.h>

#include "common/pose.h"
#include "common/rigconf.h"
#include "sim/modbus_emu.h"
#include "sim/render/render.h"
#include "sim/request.h"

struct sim_control;

/* A control channel for the rig rc, its scene and its emulated devices (borrowed; they
 * must outlive it). Returns 0, -EINVAL or -ENOMEM. */
int sim_control_new(const struct rig_config *rc, struct sim_scene *scene, struct sim_emu *emu,
                    struct sim_control **ret);

/* Frees c; NULL is a no-op. Returns NULL. */
struct sim_control *sim_control_free(struct sim_control *c);

/* Executes the request rq whose "cmd" is cmd. Returns 0 with the reply object in *reply
 * (a new reference), or -errno with the message recorded in rq: -EINVAL for an unknown
 * cmd or a bad field, -ENOENT for an unknown camera or device, -ENOMEM. */
int sim_control_handle(struct sim_control *c, struct sim_req *rq, const char *cmd, json_t **reply);

/* Consumes the next pending fault of camera cam for one render request: 0 for none,
 * -ETIMEDOUT for a dropped frame, -ECONNABORTED for a disconnect. */
int sim_control_camera_fault(struct sim_control *c, int cam);

/* The JSON of pose st of the rig rc ({"turntable": deg or null, "light_arm": ...,
 * "camera_arm": ..., "lamps": [bool, ...], "laser": bool}), a new reference; NULL when out
 * of memory. */
json_t *sim_pose_json(const struct rig_config *rc, const struct gn_pose *st);
