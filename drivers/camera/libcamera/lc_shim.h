/* lc_shim.h - the C face of libcamera: one camera, configured at open for one stream of a
 * given size and pixel format, started with exposure/gain controls, its completed requests
 * handed out as mapped frames. Plain C types only; no C++ type or exception crosses it
 * (lc_shim.cpp catches them all). Built without libcamera, lc_shim_none.c stands in and
 * every open fails with -EOPNOTSUPP.
 *
 * DESIGN: libcamera allows one CameraManager per process, so the shim keeps one, shared by
 * every open camera (refcounted under a mutex, started by the first open, stopped by the last
 * close). libcamera completes requests on its own thread: the shim queues them under a lock
 * and counts them on an eventfd (semaphore mode), the fd the caller polls. All other calls on
 * one camera come from one thread at a time (its bus worker). Errors are -errno with a message
 * in the caller's cause buffer (cause, len: NUL-terminated, may be truncated). */
#pragma once

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

struct lc_cam;

/* The exposure and gain controls a camera offers (libcamera ExposureTime, AnalogueGain). */
struct lc_caps {
        int has_exposure, has_gain;
        double exposure_min_us, exposure_max_us;
        double gain_min, gain_max;
};

/* A completed frame, borrowed from the shim: data stays mapped and unchanged until the next
 * lc_cam_next() or lc_cam_stop() on the camera. */
struct lc_frame {
        const uint8_t *data;
        size_t bytes;  /* bytes used in the plane */
        size_t stride; /* bytes per row */
        int width, height;
        uint32_t fourcc;    /* DRM fourcc, as libcamera's PixelFormat */
        uint64_t sensor_ns; /* CLOCK_MONOTONIC, start of exposure (SensorTimestamp) */
        uint64_t seq;       /* the frame's sequence number */
        int exposure_us;    /* applied, from the request's metadata; 0 when not reported */
        double gain;        /* applied, from the request's metadata; 0 when not reported */
};

/* Opens a camera: by id when id is not empty, else the index-th camera whose Model is model
 * (any model when model is empty); acquires it and configures one stream (StillCapture role)
 * of width x height in the first of the n fourccs it offers, and allocates and maps its
 * buffers. *ret is freed with lc_cam_close(). Returns 0; -ENODEV (no such camera: the cause
 * lists those there are), -EBUSY (acquired elsewhere), -EINVAL (no offered format, or the
 * size is not offered exactly), -ENOMEM, -EOPNOTSUPP (built without libcamera) or the
 * -errno libcamera gave. */
int lc_cam_open(const char *id, const char *model, int index, int width, int height,
                const uint32_t *fourccs, size_t n, struct lc_cam **ret, char *cause, size_t len);

/* Stops the camera if started, frees its buffers, releases it; NULL is a no-op. */
void lc_cam_close(struct lc_cam *cam);

/* The camera's libcamera id; valid until lc_cam_close(). */
const char *lc_cam_id(const struct lc_cam *cam);

/* Fills caps with what the camera offers. Never fails. */
void lc_cam_caps(const struct lc_cam *cam, struct lc_caps *caps);

/* Starts the camera and queues every buffer with the controls (exposure_us, gain; 0: leave
 * the camera's default, otherwise automatic exposure is turned off where offered).
 * Returns 0, -EBUSY when started, -EOPNOTSUPP for a control the camera lacks, or -errno. */
int lc_cam_start(struct lc_cam *cam, int exposure_us, double gain, char *cause, size_t len);

/* The eventfd that is readable while a completed request waits for lc_cam_next(); owned by
 * the camera, valid until lc_cam_close(). */
int lc_cam_fd(const struct lc_cam *cam);

/* Requeues the request of the previous frame, then takes the oldest completed one into out.
 * Returns 0; -EAGAIN when none has completed; -ENOTCONN when not started; -EIO for a request
 * or frame that failed (requeued by the next call); -errno when requeueing fails. Never blocks. */
int lc_cam_next(struct lc_cam *cam, struct lc_frame *out, char *cause, size_t len);

/* Stops the camera, dropping requests in flight and frames not taken; a no-op when stopped. */
void lc_cam_stop(struct lc_cam *cam);

struct lc_size {
        int width, height;
};

/* One pixel format a camera's StillCapture stream offers, and its sizes. */
struct lc_format_info {
        uint32_t fourcc;             /* DRM fourcc */
        const char *name;            /* libcamera's name of it ("YUYV", "BGR888") */
        const struct lc_size *sizes; /* the sizes it lists (may be none) */
        size_t nsizes;
        struct lc_size min, max; /* the range they lie in */
};

/* A camera as lc_list() describes it; every pointer is valid during the callback only. */
struct lc_camera_info {
        const char *id, *model; /* model: "" when the camera names none */
        const struct lc_format_info *formats;
        size_t nformats;
};

/* Calls fn(info, data) for each camera libcamera sees, without acquiring any. Returns the
 * number of cameras, -EOPNOTSUPP (built without libcamera) or the -errno libcamera gave. */
int lc_list(void (*fn)(const struct lc_camera_info *info, void *data), void *data, char *cause,
            size_t len);

#ifdef __cplusplus
}
#endif
