/* camera.h - the camera device class.
 *
 * capture() is blocking and runs on the camera's bus worker; it returns a frame
 * with the controls actually applied. */
#pragma once

#include <stdbool.h>

#include "common/frame.h"
#include "common/rigconf.h"
#include "drivers/opt.h"

struct bus;
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
};

struct cam {
        const struct cam_ops *ops;
        const struct rig_camera_conf *conf; /* borrowed */
        struct bus *bus;                    /* borrowed */
        void *priv;
};

/* Creates the camera for conf (drivers/registry.c). Returns 0, -ENOENT or -errno. No I/O. */
int cam_new(const struct rig_camera_conf *conf, struct bus *bus, struct cam **ret);

/* Closes and frees; NULL is a no-op. Returns NULL. */
struct cam *cam_free(struct cam *c);

/* Open/capture wrappers that check the request against the driver's options and log
 * "camera 'NAME' [...]: ..." on failure. out is owned by the caller (gn_frame_free_data). */
int cam_open(struct cam *c);
int cam_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out);
