/* api.h - the "libcamera" camera backend: a camera libcamera knows (vimc, a Raspberry Pi or
 * UVC sensor...), reached through the C shim lc_shim.h, on a bus of type local. */
#pragma once

#include "drivers/camera/camera.h"

/* The backend's ops, registered as "libcamera" in drivers/registry.c.
 * open() finds the camera (by id, or model and index: struct lccam_conf), acquires it and
 * configures one stream at the rig file's width x height in a format gonio converts to rgb8
 * (mono8 for a grey sensor). Returns 0 (also when open already); -ENODEV (the cause lists the
 * cameras there are), -EBUSY, -EINVAL (size or format not offered), -EOPNOTSUPP (built
 * without libcamera). It then narrows the camera's option table to the controls the camera
 * offers (c->ops becomes a per-camera copy until close), so cam_check_request() refuses
 * exposure or gain with -EOPNOTSUPP on a camera without ExposureTime or AnalogueGain (vimc
 * has neither); a request for 16-bit samples fails with -EOPNOTSUPP.
 * capture() starts the camera, waits for a frame (at most LCCAM_TIMEOUT_MS plus the exposure;
 * -ETIMEDOUT), takes up to LCCAM_SETTLE_FRAMES frames until the metadata shows the requested
 * exposure applied, and stops it. Frames carry the exposure and gain the metadata reports (0
 * when the camera reports none) and the sensor timestamp on CLOCK_REALTIME.
 * Streaming: stream_fd() is an eventfd, readable while a completed frame waits;
 * stream_dequeue() never blocks (-EAGAIN). */
extern const struct cam_ops cam_lc_ops;

/* The backend as the rig file knows it: "libcamera: { bus: cams, id: ID }" or
 * "libcamera: { bus: cams, model: MODEL, index: N }" on a bus of type local. */
extern const struct rig_backend cam_lc_backend;

/* Bound on the wait for one frame, beyond its exposure. */
#define LCCAM_TIMEOUT_MS 5000
/* Most frames capture() takes waiting for the requested exposure to show in the metadata. */
#define LCCAM_SETTLE_FRAMES 8
