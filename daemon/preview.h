/* preview.h - the live view's pictures: each camera's frames, downscaled and encoded as JPEG
 * at a few frames per second, for the dashboard's viewers (daemon/web.c).
 *
 * Frames come from what the daemon captures anyway (capture_set_tap: a session's, a scan's,
 * a client's captures) and, while no session or scan owns the rig, from peeks of the camera
 * at a lower rate (rig_peek), which never refuse or hold a move, a switch or an exposure.
 * Only cameras somebody watches are encoded, each frame once for all its viewers, on a
 * worker thread of its own: the loop only downscales (a few samples per output pixel). */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/frame.h"

struct manager;
struct preview;

#define PREVIEW_MAX_WIDTH   320 /* pixels: frames are downscaled by a whole factor to fit */
#define PREVIEW_DEFAULT_FPS 4
#define PREVIEW_MAX_FPS     10
#define PREVIEW_IDLE_FPS    2 /* at most (and at most fps), from peeks while the rig is idle */
#define PREVIEW_QUALITY     75
#define PREVIEW_NICE        10 /* of the encoder thread: the session's threads come first */

/* Receives camera cam's newest picture on the loop thread: jpeg (len bytes, width x height)
 * is valid during the call only. */
typedef void (*preview_fn)(void *ud, int cam, const uint8_t *jpeg, size_t len, int width,
                           int height);

/* Creates the previews of m's cameras at fps frames per second at most (clamped to 1 ..
 * PREVIEW_MAX_FPS), delivered to fn; sees m's captures (capture_set_tap). Returns 0 or
 * -errno. */
int preview_new(struct manager *m, unsigned fps, preview_fn fn, void *ud, struct preview **ret);

/* Stops the worker (an encode running is waited for, its picture dropped), forgets the peeks
 * in flight, frees. NULL is a no-op; returns NULL. */
struct preview *preview_free(struct preview *p);

/* One more (on) or one fewer viewer of camera cam: pictures of cam are made while it has
 * any. */
void preview_watch(struct preview *p, int cam, bool on);

/* A frame of camera cam (borrowed during the call; any format of common/frame.h): encoded
 * when cam is watched, its last picture is older than 1/fps and none is being encoded;
 * dropped otherwise. Loop thread. */
void preview_frame(struct preview *p, int cam, const struct gn_frame *frame);
