/* camera.h - the camera device class.
 *
 * capture() is blocking and runs on the camera's bus worker; it returns a frame
 * with the controls actually applied.
 *
 * The backend's option table (ops->opts: OPT_EXPOSURE, OPT_GAIN, OPT_BITS with min and
 * max; or the camera's own, c->opts, when the backend learns the ranges from the device at
 * open, as V4L2 does) is the one source of a camera's control ranges: cam_check_request()
 * checks a request against it, for the daemon before it queues a capture as for
 * cam_capture().
 *
 * Streaming (optional ops, for V4L2 mmap streaming and libcamera requests): start with a
 * request, poll the fd stream_fd() returns on the event loop (POLLIN: a frame is ready),
 * dequeue frames, stop. A backend without a pollable fd returns -EOPNOTSUPP from
 * stream_fd() and its stream_dequeue() blocks (bounded) on the bus worker instead. */
#pragma once

#include <stdbool.h>
#include <stdint.h>
#include <stddef.h>

#include "common/frame.h"
#include "common/rigconf.h"
#include "drivers/bus/bus.h"
#include "drivers/opt.h"

struct cam;

struct cam_request {
        int exposure_us; /* 0 = camera default */
        double gain;     /* 0 = camera default */
        int bits;        /* 0 = camera default; 8 or 16 */
};

struct cam_ops {
        const char *name;
        const struct opt_desc *opts;
        int n_opts;
        int (*open)(struct cam *c);
        void (*close)(struct cam *c);
        int (*capture)(struct cam *c, const struct cam_request *req, struct gn_frame *out);
        /* Streaming, all four or none. stream_start: apply req, queue buffers, start;
         * -EBUSY when streaming. stream_fd: the fd to poll (owned by the backend, valid
         * until stream_stop), or -EOPNOTSUPP. stream_dequeue: the next frame into out
         * (owned by the caller), -EAGAIN when none is ready yet (a pollable backend),
         * -ENOTCONN when not streaming. stream_stop: stop and drop frames in flight. */
        int (*stream_start)(struct cam *c, const struct cam_request *req);
        int (*stream_fd)(struct cam *c);
        int (*stream_dequeue)(struct cam *c, struct gn_frame *out);
        void (*stream_stop)(struct cam *c);
};

struct cam {
        const struct cam_ops *ops;
        const struct rig_camera_conf *conf; /* borrowed */
        struct bus *bus;                    /* borrowed */
        void *priv;
        /* The last message the class logged at warning level or worse, whole ("camera
         * 'cam1' [sim@frames]: Failed to capture: gonio-sim: frame dropped"), for
         * operators; "" when none. Written by the ops' thread (see axis.h). */
        char last_error[DEV_ERROR_MAX];
        char cause[DEV_ERROR_MAX]; /* detail of the op in progress, see cam_set_cause() */
        /* This camera's option table, set by open when the device gives the ranges (owned
         * by the backend; read by other threads once the open job completed); NULL:
         * ops->opts. See cam_opts(). */
        const struct opt_desc *opts;
        int n_opts;
};

/* Creates the camera for conf (drivers/registry.c). Returns 0, -ENOENT or -errno. No I/O. */
int cam_new(const struct rig_camera_conf *conf, struct bus *bus, struct cam **ret);

/* Closes (stopping a stream) and frees; NULL is a no-op. Returns NULL. */
struct cam *cam_free(struct cam *c);

/* The camera's option table: c->opts when its backend set one at open, else ops->opts. */
const struct opt_desc *cam_opts(const struct cam *c, int *n);

/* Checks req (NULL: all defaults) against the backend's option table, without I/O and
 * without logging. Returns 0; -ERANGE with "gain 100 outside [0.1, 64]" in msg; -EOPNOTSUPP
 * ("cannot set gain") for a control the backend does not offer; -EINVAL for a sample size
 * other than 8 or 16 bits. msg (len bytes, may be NULL) is "" on success. Any thread. */
int cam_check_request(const struct cam *c, const struct cam_request *req, char *msg, size_t len);

/* Open/capture wrappers that check the request (cam_check_request) and log "camera 'NAME'
 * [...]: ..." on failure, also kept in c->last_error. out is owned by the caller
 * (gn_frame_free_data). 0 or -errno. Bus worker. */
int cam_open(struct cam *c);
int cam_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out);

/* Streaming wrappers (see struct cam_ops); -EOPNOTSUPP when the backend cannot stream.
 * cam_stream_start checks req first. cam_stream_fd returns the fd or -errno and never
 * logs. cam_stream_dequeue returns 0, -EAGAIN (not logged) or -errno. Bus worker; the
 * loop thread may call cam_stream_fd in the done callback of the start job (the fd stays
 * valid until cam_stream_stop, but a failed dequeue may close and reopen it: ask again
 * after each dequeue). */
int cam_stream_start(struct cam *c, const struct cam_request *req);
int cam_stream_fd(struct cam *c);
int cam_stream_dequeue(struct cam *c, struct gn_frame *out);
void cam_stream_stop(struct cam *c);

/* The stream's next frame, waiting for it: cam_stream_dequeue, and while that gives -EAGAIN,
 * poll on cam_stream_fd for at most timeout_ms in all; then -ETIMEDOUT, logged ("no frame
 * within N ms"). A backend without an fd blocks in its dequeue (bounded by itself). Bus
 * worker; 0 or -errno as cam_stream_dequeue. */
int cam_stream_next(struct cam *c, int timeout_ms, struct gn_frame *out);

/* For backends: records the detail of the current op's failure without logging (see
 * axis_set_cause()). Returns -abs(err). */
int cam_set_cause(struct cam *c, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* Converts one row of width pixels of packed 4:2:2 Y'CbCr (YUYV, or UYVY when uyvy) with
 * BT.601 limited range (what UVC cameras send) to rgb8 (3 bytes a pixel). Pure; for the
 * backends whose devices deliver it. */
void cam_yuv422_row_to_rgb8(const uint8_t *src, uint8_t *rgb, int width, bool uyvy);
