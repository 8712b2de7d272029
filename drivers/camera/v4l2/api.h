/* api.h - the "v4l2" camera backend: a V4L2 video capture node (single-planar, mmap
 * streaming) on a bus of type local, found by path, card or bus_info (docs/drivers.md,
 * "V4L2 cameras"). */
#pragma once

#include "drivers/camera/camera.h"

/* The backend's ops, registered as "v4l2" in drivers/registry.c. open() finds the node,
 * negotiates the rig file's width x height in the map's format (refusing another size or
 * format than asked), reads the device's exposure and gain ranges into the camera's option
 * table, applies the rig file's controls and maps the buffers. capture() applies the
 * request with the device stopped, streams until the first frame that started after the
 * controls were set, stops, and returns it with the controls read back; it blocks at most
 * CAM_V4L2_TIMEOUT_MS plus the exposure. Streaming: stream_fd() is the node's fd (POLLIN:
 * a buffer is done). A node that vanished (-ENODEV) is closed and reopened by the next op.
 * Errors name the node, the ioctl and the cause. */
extern const struct cam_ops cam_v4l2_ops;

/* The backend as the rig file knows it: "v4l2: { bus, device | card | bus_info, format,
 * buffers, controls }" on a bus of type local. */
extern const struct rig_backend cam_v4l2_backend;

/* Bound on waiting for one frame, beyond its exposure. */
#define CAM_V4L2_TIMEOUT_MS 3000
