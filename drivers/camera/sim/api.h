/* api.h - the "sim" camera backend: frames rendered by gonio-sim, fetched over its
 * frame socket (docs/sim.md, "Frame socket"); the socket path is the port of the
 * camera's bus (of type sim). */
#pragma once

#include "drivers/camera/camera.h"

/* The backend's ops, registered as "sim" in drivers/registry.c. capture() blocks at most
 * CAM_SIM_TIMEOUT_MS, reconnects once after a broken connection and returns 0,
 * -ETIMEDOUT (also for a frame gonio-sim dropped), -ECONNREFUSED/-ENOENT (no gonio-sim),
 * -ECONNRESET/-EPIPE, -EBADMSG (malformed reply) or the error gonio-sim names; -EBUSY
 * while streaming. Streaming keeps one render request in flight: stream_fd() is the
 * socket (readable when the frame's header arrives), stream_dequeue() reads that frame
 * (blocking at most CAM_SIM_TIMEOUT_MS) and asks for the next with the same request. */
extern const struct cam_ops cam_sim_ops;

/* The backend as the rig file knows it: a map "sim: { bus: frames }" on a bus of type sim,
 * with no other key. */
extern const struct rig_backend cam_sim_backend;

/* Bound on one capture: request, render and transfer. */
#define CAM_SIM_TIMEOUT_MS 10000
