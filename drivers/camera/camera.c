/* camera.c - the camera class: backend lookup, request checks against the backend's
 * option table, logging wrappers. Backends live in drivers/camera/<backend>/. */
#include <stdarg.h>
#include <stdlib.h>

#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/camera.h"
#include "drivers/registry.h"

static int cam_log_full(const struct cam *c, int level, int err, const char *fmt, ...)
        _printf_(4, 5);

static int cam_log_full(const struct cam *c, int level, int err, const char *fmt, ...)
{
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_log_dev(c->bus, level, err, "camera", c->conf->name, c->ops->name, -1, fmt, ap);
        va_end(ap);
        return r;
}

int cam_new(const struct rig_camera_conf *conf, struct bus *bus, struct cam **ret)
{
        const struct cam_ops *ops;
        struct cam *c;

        if (!conf || !bus || !ret)
                return -EINVAL;
        ops = registry_camera(conf->backend);
        if (!ops)
                return log_error_errno(SYNTHETIC_ERRNO(ENOENT), "camera '%s': Unknown backend '%s'",
                                       conf->name, conf->backend);
        c = calloc(1, sizeof(*c));
        if (!c)
                return -ENOMEM;
        *c = (struct cam){.ops = ops, .conf = conf, .bus = bus};
        *ret = c;
        return 0;
}

struct cam *cam_free(struct cam *c)
{
        if (!c)
                return NULL;
        if (c->ops->close)
                c->ops->close(c);
        free(c);
        return NULL;
}

int cam_open(struct cam *c)
{
        int r;

        if (!c->ops->open)
                return 0;
        r = c->ops->open(c);
        if (r < 0)
                return cam_log_full(c, GN_LOG_ERR, r, "Failed to open: %m");
        return 0;
}

/* Checks a requested control (0 = default, always fine) against the option table:
 * -EOPNOTSUPP when not settable, -ERANGE outside [min, max] (when max > min). */
static int check_control(const struct cam *c, enum opt_key key, double v)
{
        const struct opt_desc *o;

        if (v == 0)
                return 0;
        o = opt_find(c->ops->opts, c->ops->n_opts, key);
        if (!o || !(o->flags & OPT_SET))
                return cam_log_full(c, GN_LOG_ERR, SYNTHETIC_ERRNO(EOPNOTSUPP), "Cannot set %s",
                                    opt_key_name(key));
        if (o->max > o->min && (v < o->min || v > o->max))
                return cam_log_full(c, GN_LOG_ERR, SYNTHETIC_ERRNO(ERANGE),
                                    "%s %g outside [%g, %g]", opt_key_name(key), v, o->min, o->max);
        return 0;
}

int cam_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out)
{
        static const struct cam_request defaults = {};
        int r;

        if (!req)
                req = &defaults;
        if (req->bits != 0 && req->bits != 8 && req->bits != 16)
                return cam_log_full(c, GN_LOG_ERR, SYNTHETIC_ERRNO(EINVAL),
                                    "Unsupported sample size %d bits", req->bits);
        r = check_control(c, OPT_EXPOSURE, req->exposure_us);
        if (r >= 0)
                r = check_control(c, OPT_GAIN, req->gain);
        if (r >= 0)
                r = check_control(c, OPT_BITS, req->bits);
        if (r < 0)
                return r;
        r = c->ops->capture(c, req, out);
        if (r < 0)
                return cam_log_full(c, GN_LOG_ERR, r, "Failed to capture: %m");
        return 0;
}
