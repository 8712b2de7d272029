/* api.c - the "libcamera" camera backend's class ops (see api.h) over the C shim lc_shim.h:
 * open and configure at the rig file's size, capture as start / one frame / stop, streaming
 * on the shim's eventfd, frames converted by proto.c. Runs on the camera's local bus worker. */
#include <errno.h>
#include <poll.h>
#include <stdlib.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/camera/libcamera/api.h"
#include "drivers/camera/libcamera/lc_shim.h"
#include "drivers/camera/libcamera/proto.h"

struct cam_lc {
        struct lc_cam *lc;
        struct cam_ops ops; /* cam_lc_ops with opts below; c->ops while open */
        struct opt_desc opts[LCPROTO_OPTS_MAX];
        bool streaming;
        uint64_t next_seq; /* of the stream's next frame (lcproto_check_seq) */
};

/* Until open: every control a libcamera camera may offer, with the rig file's bounds. */
static const struct opt_desc cam_lc_opts[] = {
        {OPT_EXPOSURE, OPT_GET | OPT_SET, .unit = "us", .min = RIG_EXPOSURE_US_MIN,
         .max = RIG_EXPOSURE_US_MAX},
        {OPT_GAIN, OPT_GET | OPT_SET, .min = RIG_GAIN_MIN, .max = RIG_GAIN_MAX},
        {OPT_BITS, OPT_GET | OPT_SET | OPT_LIST, .min = 8, .max = 8},
};

static int lc_open(struct cam *c)
{
        static const struct lccam_conf any = {0};
        const struct lccam_conf *conf = c->conf->backend.conf ? c->conf->backend.conf : &any;
        uint32_t fourccs[LCPROTO_N_FORMATS];
        char cause[DEV_ERROR_MAX] = "";
        struct lc_caps caps;
        struct cam_lc *s;
        int r;

        if (c->priv)
                return 0; /* open already */
        for (size_t i = 0; i < LCPROTO_N_FORMATS; i++)
                fourccs[i] = lcproto_format_at(i);
        s = calloc(1, sizeof(*s));
        if (!s)
                return -ENOMEM;
        r = lc_cam_open(conf->id, conf->model, conf->index, c->conf->width, c->conf->height,
                        fourccs, LCPROTO_N_FORMATS, &s->lc, cause, sizeof(cause));
        if (r < 0) {
                free(s);
                return cam_set_cause(c, r, "%s", cause);
        }
        lc_cam_caps(s->lc, &caps);
        s->ops = *c->ops;
        s->ops.opts = s->opts;
        s->ops.n_opts = lcproto_opts(&caps, s->opts);
        c->priv = s;
        c->ops = &s->ops;
        log_debug("camera '%s': libcamera camera '%s'", c->conf->name, lc_cam_id(s->lc));
        return 0;
}

static void lc_close(struct cam *c)
{
        struct cam_lc *s = c->priv;

        if (!s)
                return;
        c->ops = &cam_lc_ops;
        lc_cam_close(s->lc);
        free(s);
        c->priv = NULL;
}

/* Takes the next completed frame into out, converted, with its timestamp on the wall clock. */
static int take_frame(struct cam *c, struct cam_lc *s, struct gn_frame *out)
{
        char cause[DEV_ERROR_MAX] = "";
        struct lc_frame f;
        int r = lc_cam_next(s->lc, &f, cause, sizeof(cause));

        if (r == -EAGAIN)
                return r;
        if (r < 0)
                return cam_set_cause(c, r, "%s", cause[0] ? cause : "cannot take a frame");
        r = lcproto_convert(f.fourcc, f.data, f.bytes, f.stride, f.width, f.height, out);
        if (r < 0)
                return cam_set_cause(c, r, "frame %llu: %zu bytes of %s %dx%d, stride %zu: %m",
                                     (unsigned long long)f.seq, f.bytes,
                                     lcproto_format_name(f.fourcc), f.width, f.height, f.stride);
        out->timestamp_ns =
                lcproto_mono_to_realtime(f.sensor_ns, gn_monotonic_ns(), gn_realtime_ns());
        out->seq = f.seq;
        out->exposure_us = f.exposure_us;
        out->gain = f.gain;
        return 0;
}

/* Waits (bounded by deadline_ns on CLOCK_MONOTONIC) for the next frame and takes it. */
static int wait_frame(struct cam *c, struct cam_lc *s, uint64_t deadline_ns, struct gn_frame *out)
{
        struct pollfd p = {.fd = lc_cam_fd(s->lc), .events = POLLIN};
        int r;

        while ((r = take_frame(c, s, out)) == -EAGAIN) {
                uint64_t now = gn_monotonic_ns();

                if (now >= deadline_ns)
                        return cam_set_cause(c, -ETIMEDOUT, "no frame within %llu ms",
                                             (unsigned long long)(LCCAM_TIMEOUT_MS));
                if (poll(&p, 1, (int)((deadline_ns - now + 999999) / 1000000)) < 0 &&
                    errno != EINTR)
                        return cam_set_cause(c, -errno, "poll: %m");
        }
        return r;
}

static int lc_stream_start(struct cam *c, const struct cam_request *req)
{
        struct cam_lc *s = c->priv;
        char cause[DEV_ERROR_MAX] = "";
        int r;

        if (!s)
                return -ENOTCONN;
        if (s->streaming)
                return cam_set_cause(c, -EBUSY, "the camera is streaming");
        if (req->bits > 8)
                return cam_set_cause(c, -EOPNOTSUPP,
                                     "%d-bit samples: gonio converts 8-bit formats only",
                                     req->bits);
        r = lc_cam_start(s->lc, req->exposure_us, req->gain, cause, sizeof(cause));
        if (r < 0)
                return cam_set_cause(c, r, "%s", cause);
        s->streaming = true;
        s->next_seq = LCPROTO_SEQ_NONE;
        return 0;
}

static void lc_stream_stop(struct cam *c)
{
        struct cam_lc *s = c->priv;

        if (!s || !s->streaming)
                return;
        lc_cam_stop(s->lc);
        s->streaming = false;
}

/* Whether frame f shows the requested exposure (or cannot: no metadata, no request). */
static bool settled(const struct cam_request *req, const struct gn_frame *f)
{
        return req->exposure_us <= 0 || f->exposure_us <= 0 ||
               abs(f->exposure_us - req->exposure_us) <= req->exposure_us / 50 + 1;
}

static int lc_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out)
{
        struct cam_lc *s = c->priv;
        uint64_t wait_ns = (LCCAM_TIMEOUT_MS * 1000ull + (uint64_t)req->exposure_us) * 1000;
        struct gn_frame f = {0};
        int r;

        if (s && s->streaming)
                return cam_set_cause(c, -EBUSY, "the camera is streaming");
        r = lc_stream_start(c, req);
        for (int i = 0; r >= 0 && i < LCCAM_SETTLE_FRAMES; i++) {
                gn_frame_free_data(&f);
                r = wait_frame(c, s, gn_monotonic_ns() + wait_ns, &f);
                if (r >= 0 && settled(req, &f))
                        break;
        }
        if (r >= 0 && !settled(req, &f))
                log_debug("camera '%s': exposure %d us not shown after %d frames (%d us)",
                          c->conf->name, req->exposure_us, LCCAM_SETTLE_FRAMES, f.exposure_us);
        lc_stream_stop(c);
        if (r >= 0)
                *out = f;
        return r;
}

static int lc_stream_fd(struct cam *c)
{
        struct cam_lc *s = c->priv;

        return s && s->streaming ? lc_cam_fd(s->lc) : -ENOTCONN;
}

/* The next frame of the stream; a gap in the sequence numbers (frames libcamera dropped)
 * is an error naming the frames: a stream's frames are its angles. */
static int lc_stream_dequeue(struct cam *c, struct gn_frame *out)
{
        struct cam_lc *s = c->priv;
        char cause[DEV_ERROR_MAX];
        int r;

        if (!s || !s->streaming)
                return -ENOTCONN;
        r = take_frame(c, s, out);
        if (r < 0)
                return r;
        r = lcproto_check_seq(&s->next_seq, out->seq, cause, sizeof(cause));
        if (r < 0) {
                gn_frame_free_data(out);
                return cam_set_cause(c, r, "%s", cause);
        }
        return 0;
}

const struct rig_backend cam_lc_backend = {
        .name = "libcamera",
        .cls = RIG_CLASS_CAMERA,
        .bus_types = 1u << RIG_BUS_LOCAL,
        .conf_size = sizeof(struct lccam_conf),
        .parse_conf = lcproto_parse_conf,
        .ops = &cam_lc_ops,
};

const struct cam_ops cam_lc_ops = {
        .name = "libcamera",
        .opts = cam_lc_opts,
        .n_opts = ELEMENTSOF(cam_lc_opts),
        .open = lc_open,
        .close = lc_close,
        .capture = lc_capture,
        .stream_start = lc_stream_start,
        .stream_fd = lc_stream_fd,
        .stream_dequeue = lc_stream_dequeue,
        .stream_stop = lc_stream_stop,
};
