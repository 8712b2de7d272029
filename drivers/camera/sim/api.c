/* api.c - the "sim" camera backend: asks gonio-sim's frame server for a rendered
 * frame over a Unix stream socket and reads the header line and the pixels, every
 * wait bounded by one deadline per capture (see api.h, docs/sim.md). */
#include <errno.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/sim/api.h"
#include "drivers/camera/sim/proto.h"

struct cam_sim {
        int fd;                      /* -1 while disconnected */
        char buf[SIMPROTO_LINE_MAX]; /* received bytes not consumed yet */
        size_t len;
};

static const struct opt_desc cam_sim_opts[] = {
        {OPT_EXPOSURE, OPT_GET | OPT_SET, .unit = "us", .min = 1, .max = 10000000},
        {OPT_GAIN, OPT_GET | OPT_SET, .min = 0.1, .max = 64},
        {OPT_BITS, OPT_GET | OPT_SET | OPT_LIST, .min = 8, .max = 16},
};

static int64_t now_ms(void)
{
        return (int64_t)(gn_monotonic_ns() / 1000000);
}

/* Waits for events on fd until deadline (ms). Returns 0 or -ETIMEDOUT/-errno. */
static int wait_fd(int fd, short events, int64_t deadline)
{
        struct pollfd p = {.fd = fd, .events = events};

        for (;;) {
                int64_t left = deadline - now_ms();
                if (left <= 0)
                        return -ETIMEDOUT;
                int r = poll(&p, 1, (int)left);
                if (r > 0)
                        return 0;
                if (r < 0 && errno != EINTR)
                        return -errno;
        }
}

static void disconnect(struct cam_sim *s)
{
        if (s->fd >= 0)
                close(s->fd);
        s->fd = -1;
        s->len = 0;
}

static int sim_connect(struct cam *c, struct cam_sim *s)
{
        const char *path = bus_conf(c->bus)->port;
        struct sockaddr_un sa = {.sun_family = AF_UNIX};

        if (strlen(path) >= sizeof sa.sun_path)
                return -ENAMETOOLONG;
        strcpy(sa.sun_path, path);
        int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
        if (fd < 0)
                return -errno;
        if (connect(fd, (struct sockaddr *)&sa, sizeof sa) < 0) {
                int r = -errno;
                close(fd);
                return r;
        }
        disconnect(s);
        s->fd = fd;
        return 0;
}

static int send_all(int fd, const char *p, size_t n, int64_t deadline)
{
        while (n > 0) {
                ssize_t k = send(fd, p, n, MSG_NOSIGNAL);
                if (k < 0 && errno == EAGAIN) {
                        int r = wait_fd(fd, POLLOUT, deadline);
                        if (r < 0)
                                return r;
                        continue;
                }
                if (k < 0 && errno != EINTR)
                        return -errno;
                if (k > 0) {
                        p += k;
                        n -= (size_t)k;
                }
        }
        return 0;
}

/* Receives at most n bytes before deadline. Returns the count, -ECONNRESET at end of
 * stream, -ETIMEDOUT or -errno. */
static ssize_t recv_some(int fd, void *p, size_t n, int64_t deadline)
{
        for (;;) {
                ssize_t k = recv(fd, p, n, 0);
                if (k > 0)
                        return k;
                if (k == 0)
                        return -ECONNRESET;
                if (errno == EINTR)
                        continue;
                if (errno != EAGAIN)
                        return -errno;
                int r = wait_fd(fd, POLLIN, deadline);
                if (r < 0)
                        return r;
        }
}

/* Receives until s->buf holds a whole line; its length (without newline) goes to *n. */
static int read_line(struct cam_sim *s, size_t *n, int64_t deadline)
{
        for (;;) {
                char *nl = memchr(s->buf, '\n', s->len);
                if (nl) {
                        *n = (size_t)(nl - s->buf);
                        return 0;
                }
                if (s->len == sizeof s->buf)
                        return -EBADMSG;
                ssize_t k = recv_some(s->fd, s->buf + s->len, sizeof s->buf - s->len, deadline);
                if (k < 0)
                        return (int)k;
                s->len += (size_t)k;
        }
}

static void consume(struct cam_sim *s, size_t n)
{
        memmove(s->buf, s->buf + n, s->len - n);
        s->len -= n;
}

/* Reads n bytes into dst (NULL: discards them), buffered bytes first. */
static int read_bytes(struct cam_sim *s, uint8_t *dst, size_t n, int64_t deadline)
{
        while (n > 0) {
                size_t k = MIN(n, s->len);
                if (k > 0) {
                        if (dst)
                                memcpy(dst, s->buf, k);
                        consume(s, k);
                } else {
                        ssize_t r = dst ? recv_some(s->fd, dst, n, deadline)
                                        : recv_some(s->fd, s->buf, MIN(n, sizeof s->buf), deadline);
                        if (r < 0)
                                return (int)r;
                        k = (size_t)r;
                }
                if (dst)
                        dst += k;
                n -= k;
        }
        return 0;
}

/* Reads the frame announced by h into out. */
static int read_frame(struct cam_sim *s, const struct simproto_header *h, struct gn_frame *out,
                      int64_t deadline)
{
        int r = gn_frame_alloc(out, h->width, h->height, h->channels, h->bits);
        if (r < 0)
                return r;
        if (out->stride != h->stride)
                r = -EBADMSG;
        if (r >= 0)
                r = read_bytes(s, out->data, h->bytes, deadline);
        if (r >= 0)
                r = read_bytes(s, NULL, h->extra_bytes, deadline);
        if (r < 0) {
                gn_frame_free_data(out);
                return r;
        }
        out->timestamp_ns = h->timestamp_ns;
        out->exposure_us = h->exposure_us;
        out->gain = h->gain;
        out->seq = h->seq;
        return 0;
}

/* One request and its reply. Transport errors close the connection (it is out of step);
 * an error reply of gonio-sim leaves it open. */
static int capture_once(struct cam *c, struct cam_sim *s, const struct cam_request *req,
                        struct gn_frame *out)
{
        const struct simproto_render rq = {.camera = c->conf->name,
                                           .exposure_us = req->exposure_us,
                                           .gain = req->gain,
                                           .bits = req->bits};
        int64_t deadline = now_ms() + CAM_SIM_TIMEOUT_MS;
        struct simproto_header h;
        char line[SIMPROTO_LINE_MAX], msg[256] = "";
        size_t n = 0;

        int r = s->fd < 0 ? sim_connect(c, s) : 0;
        if (r < 0)
                return r;
        r = simproto_encode_render(&rq, line, sizeof line);
        if (r < 0)
                return r;
        r = send_all(s->fd, line, (size_t)r, deadline);
        if (r >= 0)
                r = read_line(s, &n, deadline);
        if (r >= 0) {
                r = simproto_decode_header(s->buf, n, &h, msg, sizeof msg);
                consume(s, n + 1);
                if (r < 0 && r != -EBADMSG) {
                        log_debug("camera '%s': gonio-sim: %s", c->conf->name, msg);
                        return r;
                }
        }
        if (r >= 0)
                r = read_frame(s, &h, out, deadline);
        if (r < 0)
                disconnect(s);
        return r;
}

static int sim_open(struct cam *c)
{
        struct cam_sim *s = calloc(1, sizeof *s);

        if (!s)
                return -ENOMEM;
        s->fd = -1;
        int r = sim_connect(c, s);
        if (r < 0) {
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
        disconnect(s);
        free(s);
        c->priv = NULL;
}

static int sim_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out)
{
        struct cam_sim *s = c->priv;

        if (!s)
                return -ENOTCONN;
        int r = capture_once(c, s, req, out);
        if (r == -ECONNRESET || r == -EPIPE) {
                log_debug("camera '%s': frame socket broken, reconnecting", c->conf->name);
                r = capture_once(c, s, req, out);
        }
        return r;
}

const struct cam_ops cam_sim_ops = {
        .name = "sim",
        .opts = cam_sim_opts,
        .n_opts = ELEMENTSOF(cam_sim_opts),
        .open = sim_open,
        .close = sim_close,
        .capture = sim_capture,
};
