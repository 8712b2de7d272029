/* api.c - the "sim" camera backend: asks gonio-sim's frame server for a rendered frame
 * over the sim transport (a Unix stream socket, drivers/transport/sim.c) and reads the
 * header line and the pixels, every wait bounded by one deadline per frame (see api.h,
 * docs/sim.md). Each camera has its own connection; streaming keeps one render request
 * in flight, so the socket turns readable when the next frame is on its way. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/sim/api.h"
#include "drivers/camera/sim/proto.h"
#include "drivers/transport/transport.h"

struct cam_sim {
        struct transport *t;
        struct cam_request stream_req;
        bool streaming;
        bool pending; /* a render request is in flight (streaming only) */
};

/* The rig file checks a camera's default controls against the same bounds (rigconf.h). */
static const struct opt_desc cam_sim_opts[] = {
        {OPT_EXPOSURE, OPT_GET | OPT_SET, .unit = "us", .min = RIG_EXPOSURE_US_MIN,
         .max = RIG_EXPOSURE_US_MAX},
        {OPT_GAIN, OPT_GET | OPT_SET, .min = RIG_GAIN_MIN, .max = RIG_GAIN_MAX},
        {OPT_BITS, OPT_GET | OPT_SET | OPT_LIST, .min = 8, .max = 16},
};

/* A failed read or write: the link is out of step, so it is closed; the transport's
 * cause becomes the camera's. Returns r. */
static int link_error(struct cam *c, struct cam_sim *s, int r)
{
        if (transport_cause(s->t)[0])
                cam_set_cause(c, r, "%s", transport_cause(s->t));
        else
                cam_set_cause(c, r, "%m");
        transport_close(s->t);
        return r;
}

static int send_request(struct cam *c, struct cam_sim *s, const struct cam_request *req,
                        int64_t deadline)
{
        const struct simproto_render rq = {.camera = c->conf->name,
                                           .exposure_us = req->exposure_us,
                                           .gain = req->gain,
                                           .bits = req->bits};
        char line[SIMPROTO_LINE_MAX];
        int r;

        r = simproto_encode_render(&rq, line, sizeof(line));
        if (r < 0)
                return cam_set_cause(c, r, "cannot encode the render request: %m");
        r = transport_write_all(s->t, line, (size_t)r, deadline);
        return r < 0 ? link_error(c, s, r) : 0;
}

/* Reads the frame announced by h into out. */
static int read_frame(struct cam *c, struct cam_sim *s, const struct simproto_header *h,
                      struct gn_frame *out, int64_t deadline)
{
        int r = gn_frame_alloc(out, h->width, h->height, h->channels, h->bits);

        if (r < 0)
                return cam_set_cause(c, r, "cannot allocate a %dx%d frame: %m", h->width,
                                     h->height);
        r = out->stride == h->stride ? transport_read_bytes(s->t, out->data, h->bytes, deadline)
                                     : -EBADMSG;
        if (r >= 0)
                r = transport_read_bytes(s->t, NULL, h->extra_bytes, deadline);
        if (r < 0) {
                gn_frame_free_data(out);
                return link_error(c, s, r);
        }
        out->timestamp_ns = h->timestamp_ns;
        out->exposure_us = h->exposure_us;
        out->gain = h->gain;
        out->seq = h->seq;
        return 0;
}

/* Reads one reply: a frame, or an error gonio-sim names (the link stays in step). */
static int receive(struct cam *c, struct cam_sim *s, struct gn_frame *out, int64_t deadline)
{
        char line[SIMPROTO_LINE_MAX], msg[256] = "";
        struct simproto_header h;
        ssize_t n;
        int r;

        n = transport_read_line(s->t, line, sizeof(line), deadline);
        if (n < 0)
                return link_error(c, s, (int)n);
        r = simproto_decode_header(line, (size_t)n, &h, msg, sizeof(msg));
        if (r == -EBADMSG)
                return link_error(c, s, cam_set_cause(c, r, "malformed reply header"));
        if (r < 0)
                return cam_set_cause(c, r, "gonio-sim: %s", msg);
        return read_frame(c, s, &h, out, deadline);
}

static int capture_once(struct cam *c, struct cam_sim *s, const struct cam_request *req,
                        struct gn_frame *out)
{
        int64_t deadline = transport_deadline(CAM_SIM_TIMEOUT_MS);
        int r = send_request(c, s, req, deadline);

        return r < 0 ? r : receive(c, s, out, deadline);
}

static int sim_open(struct cam *c)
{
        struct cam_sim *s = calloc(1, sizeof(*s));
        int r;

        if (!s)
                return -ENOMEM;
        r = transport_new(bus_conf(c->bus), &s->t);
        if (r >= 0)
                r = transport_open(s->t);
        if (r < 0) {
                if (s->t)
                        cam_set_cause(c, r, "%s", transport_cause(s->t));
                transport_free(s->t);
                free(s);
                return r;
        }
        c->priv = s;
        return 0;
}

static void sim_close(struct cam *c)
{
        struct cam_sim *s = c->priv;

        if (!s)
                return;
        transport_free(s->t);
        free(s);
        c->priv = NULL;
}

static int sim_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out)
{
        struct cam_sim *s = c->priv;

        if (!s)
                return -ENOTCONN;
        if (s->streaming)
                return cam_set_cause(c, -EBUSY, "the camera is streaming");
        int r = capture_once(c, s, req, out);
        if (r == -ECONNRESET || r == -EPIPE) {
                log_debug("camera '%s': frame socket broken, reconnecting", c->conf->name);
                c->cause[0] = '\0';
                r = capture_once(c, s, req, out);
        }
        return r;
}

static int sim_stream_start(struct cam *c, const struct cam_request *req)
{
        struct cam_sim *s = c->priv;
        int r;

        if (!s)
                return -ENOTCONN;
        if (s->streaming)
                return -EBUSY;
        r = send_request(c, s, req, transport_deadline(CAM_SIM_TIMEOUT_MS));
        if (r < 0)
                return r;
        s->stream_req = *req;
        s->streaming = s->pending = true;
        return 0;
}

static int sim_stream_fd(struct cam *c)
{
        struct cam_sim *s = c->priv;

        return s && s->streaming && s->t->is_open ? s->t->fd : -ENOTCONN;
}

/* Receives the frame in flight (asking for one first if none is), then asks for the next;
 * a failure to ask is reported by the next dequeue. */
static int sim_stream_dequeue(struct cam *c, struct gn_frame *out)
{
        struct cam_sim *s = c->priv;
        int64_t deadline = transport_deadline(CAM_SIM_TIMEOUT_MS);
        int r = 0;

        if (!s || !s->streaming)
                return -ENOTCONN;
        if (!s->pending)
                r = send_request(c, s, &s->stream_req, deadline);
        if (r >= 0)
                r = receive(c, s, out, deadline);
        s->pending = false;
        if (r < 0)
                return r;
        s->pending = send_request(c, s, &s->stream_req, deadline) >= 0;
        c->cause[0] = '\0';
        return 0;
}

static void sim_stream_stop(struct cam *c)
{
        struct cam_sim *s = c->priv;

        if (!s || !s->streaming)
                return;
        if (s->pending)
                transport_close(s->t); /* drops the frame in flight; reopened on next use */
        s->streaming = s->pending = false;
}

/* The map holds the bus alone: the camera's name is what gonio-sim renders by. */
static int sim_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                          void *conf, struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", NULL};

        return yconf_check_keys(yc, m, keys);
}

const struct rig_backend cam_sim_backend = {
        .name = "sim",
        .cls = RIG_CLASS_CAMERA,
        .bus_types = 1u << RIG_BUS_SIM,
        .parse_conf = sim_parse_conf,
        .ops = &cam_sim_ops,
};

const struct cam_ops cam_sim_ops = {
        .name = "sim",
        .opts = cam_sim_opts,
        .n_opts = ELEMENTSOF(cam_sim_opts),
        .open = sim_open,
        .close = sim_close,
        .capture = sim_capture,
        .stream_start = sim_stream_start,
        .stream_fd = sim_stream_fd,
        .stream_dequeue = sim_stream_dequeue,
        .stream_stop = sim_stream_stop,
};
