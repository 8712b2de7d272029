/* camera.c - the camera class: backend lookup, request checks against the backend's
 * option table (the one source of control ranges), logging wrappers with the backend's
 * cause, and the optional streaming ops. Backends live in drivers/camera/<backend>/. */
#include <errno.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/camera.h"
#include "drivers/registry.h"

static int cam_log_full(struct cam *c, int level, int err, const char *fmt, ...) _printf_(4, 5);

static int cam_log_full(struct cam *c, int level, int err, const char *fmt, ...)
{
        const struct bus_dev_ref ref = {"camera",      c->conf->name,
                                        c->ops->name,  &c->conf->backend.addr,
                                        c->last_error, sizeof(c->last_error)};
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_log_dev(c->bus, &ref, level, err, fmt, ap);
        va_end(ap);
        return r;
}

int cam_set_cause(struct cam *c, int err, const char *fmt, ...)
{
        va_list ap;
        int r;

        va_start(ap, fmt);
        r = bus_dev_cause(c->cause, sizeof(c->cause), err, fmt, ap);
        va_end(ap);
        return r;
}

/* Logs the failure of the op WHAT with the backend's cause, or strerror(r). */
static int fail(struct cam *c, int r, const char *what)
{
        if (c->cause[0])
                return cam_log_full(c, GN_LOG_ERR, r, "Failed to %s: %s", what, c->cause);
        return cam_log_full(c, GN_LOG_ERR, r, "Failed to %s: %m", what);
}

int cam_new(const struct rig_camera_conf *conf, struct bus *bus, struct cam **ret)
{
        const struct cam_ops *ops;
        struct cam *c;

        if (!conf || !bus || !ret)
                return -EINVAL;
        ops = registry_camera(conf->backend.name);
        if (!ops)
                return log_error_errno(SYNTHETIC_ERRNO(ENOENT), "camera '%s': Unknown backend '%s'",
                                       conf->name, conf->backend.name);
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
        if (c->ops->stream_stop)
                c->ops->stream_stop(c);
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
        c->cause[0] = '\0';
        r = c->ops->open(c);
        if (r < 0)
                return fail(c, r, "open");
        return 0;
}

const struct opt_desc *cam_opts(const struct cam *c, int *n)
{
        *n = c->opts ? c->n_opts : c->ops->n_opts;
        return c->opts ? c->opts : c->ops->opts;
}

/* Checks a requested control (0 = default, always fine) against the option table:
 * -EOPNOTSUPP when not settable, -ERANGE outside [min, max] (when max > min). */
static int check_control(const struct cam *c, enum opt_key key, double v, char *msg, size_t len)
{
        const struct opt_desc *o, *opts;
        int n;

        if (v == 0)
                return 0;
        opts = cam_opts(c, &n);
        o = opt_find(opts, n, key);
        if (!o || !(o->flags & OPT_SET)) {
                snprintf(msg, len, "cannot set %s", opt_key_name(key));
                return -EOPNOTSUPP;
        }
        if (o->max > o->min && (v < o->min || v > o->max)) {
                snprintf(msg, len, "%s %.10g outside [%.10g, %.10g]", opt_key_name(key), v, o->min,
                         o->max);
                return -ERANGE;
        }
        return 0;
}

int cam_check_request(const struct cam *c, const struct cam_request *req, char *msg, size_t len)
{
        static const struct cam_request defaults = {};
        char dummy[1];
        int r;

        if (!msg || len == 0) {
                msg = dummy;
                len = sizeof(dummy);
        }
        msg[0] = '\0';
        if (!req)
                req = &defaults;
        if (req->bits != 0 && req->bits != 8 && req->bits != 16) {
                snprintf(msg, len, "unsupported sample size %d bits", req->bits);
                return -EINVAL;
        }
        r = check_control(c, OPT_EXPOSURE, req->exposure_us, msg, len);
        if (r >= 0)
                r = check_control(c, OPT_GAIN, req->gain, msg, len);
        if (r >= 0)
                r = check_control(c, OPT_BITS, req->bits, msg, len);
        return r;
}

/* cam_check_request() with its message as the cause of WHAT's failure. */
static int check_logged(struct cam *c, const struct cam_request *req, const char *what)
{
        int r;

        c->cause[0] = '\0';
        r = cam_check_request(c, req, c->cause, sizeof(c->cause));
        return r < 0 ? fail(c, r, what) : 0;
}

int cam_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out)
{
        static const struct cam_request defaults = {};
        int r = check_logged(c, req, "capture");

        if (r < 0)
                return r;
        r = c->ops->capture(c, req ? req : &defaults, out);
        return r < 0 ? fail(c, r, "capture") : 0;
}

int cam_stream_start(struct cam *c, const struct cam_request *req)
{
        static const struct cam_request defaults = {};
        int r;

        if (!c->ops->stream_start)
                return -EOPNOTSUPP;
        r = check_logged(c, req, "start streaming");
        if (r < 0)
                return r;
        r = c->ops->stream_start(c, req ? req : &defaults);
        return r < 0 ? fail(c, r, "start streaming") : 0;
}

int cam_stream_fd(struct cam *c)
{
        return c->ops->stream_fd ? c->ops->stream_fd(c) : -EOPNOTSUPP;
}

int cam_stream_dequeue(struct cam *c, struct gn_frame *out)
{
        int r;

        if (!c->ops->stream_dequeue)
                return -EOPNOTSUPP;
        c->cause[0] = '\0';
        r = c->ops->stream_dequeue(c, out);
        return r < 0 && r != -EAGAIN ? fail(c, r, "dequeue a frame") : r;
}

int cam_stream_next(struct cam *c, int timeout_ms, struct gn_frame *out)
{
        uint64_t deadline = gn_monotonic_ns() + (uint64_t)timeout_ms * 1000000;
        int r;

        while ((r = cam_stream_dequeue(c, out)) == -EAGAIN) {
                struct pollfd p = {.fd = cam_stream_fd(c), .events = POLLIN};
                uint64_t now = gn_monotonic_ns();

                if (p.fd < 0)
                        return r;
                if (now >= deadline)
                        return cam_log_full(c, GN_LOG_ERR, -ETIMEDOUT,
                                            "Failed to dequeue a frame: no frame within %d ms",
                                            timeout_ms);
                if (poll(&p, 1, (int)((deadline - now + 999999) / 1000000)) < 0 && errno != EINTR)
                        return cam_log_full(c, GN_LOG_ERR, -errno,
                                            "Failed to dequeue a frame: poll: %m");
        }
        return r;
}

void cam_stream_stop(struct cam *c)
{
        if (c->ops->stream_stop)
                c->ops->stream_stop(c);
}

static uint8_t clip8(int v)
{
        return v < 0 ? 0 : v > 255 ? 255 : (uint8_t)v;
}

/* One pixel of BT.601 limited-range Y'CbCr to R'G'B' (integer form, 8 fractional bits). */
static void yuv_to_rgb(int y, int u, int v, uint8_t *rgb)
{
        int c = 298 * (y - 16), d = u - 128, e = v - 128;

        rgb[0] = clip8((c + 409 * e + 128) >> 8);
        rgb[1] = clip8((c - 100 * d - 208 * e + 128) >> 8);
        rgb[2] = clip8((c + 516 * d + 128) >> 8);
}

void cam_yuv422_row_to_rgb8(const uint8_t *src, uint8_t *rgb, int width, bool uyvy)
{
        const int y0 = uyvy ? 1 : 0, u = uyvy ? 0 : 1, y1 = uyvy ? 3 : 2, v = uyvy ? 2 : 3;

        for (int x = 0; x + 1 < width; x += 2, src += 4, rgb += 6) {
                yuv_to_rgb(src[y0], src[u], src[v], rgb);
                yuv_to_rgb(src[y1], src[u], src[v], rgb + 3);
        }
        if (width % 2)
                yuv_to_rgb(src[y0], src[u], src[v], rgb);
}
