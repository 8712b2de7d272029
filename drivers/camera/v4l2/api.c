/* api.c - the "v4l2" camera backend: a V4L2 capture node driven with raw ioctls, mmap
 * buffers and poll (see api.h, docs/drivers.md "V4L2 cameras"). The device stays stopped
 * between captures: a capture sets the request's controls, queues every buffer, starts,
 * keeps the first frame whose exposure began after the controls were set, and stops; so no
 * buffer filled before the request can be returned. Pixel conversion, control names and
 * timestamps are in proto.c. */
#include <errno.h>
#include <fcntl.h>
#include <glob.h>
#include <linux/videodev2.h>
#include <math.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "common/clock.h"
#include "common/log.h"
#include "drivers/camera/v4l2/api.h"
#include "drivers/camera/v4l2/proto.h"

#define CAP_TYPE V4L2_BUF_TYPE_VIDEO_CAPTURE

struct v4l2_map {
        void *p;
        size_t len;
};

/* A control of the device the camera class maps (exposure, gain). */
struct v4l2_ctl {
        bool present;
        long min, max;
};

struct cam_v4l2 {
        int fd; /* -1: closed, reopened by the next op */
        char path[RIG_PATH_MAX];
        const struct v4l2p_format *fmt;
        int width, height;
        size_t stride;
        struct v4l2_map bufs[V4L2P_BUFFERS_MAX];
        unsigned n_bufs;
        bool on;        /* VIDIOC_STREAMON in effect */
        bool streaming; /* between stream_start and stream_stop */
        int to_skip;    /* frames still to drop since the start (the map's skip) */
        struct v4l2_ctl exposure, gain;
        long def_exposure, def_gain; /* device units: what a request's 0 means */
        int exposure_us;             /* read back when the last request was applied */
        double gain_applied;
        int64_t applied_ns; /* CLOCK_MONOTONIC when the last request was applied */
        struct opt_desc opts[3];
};

/* CLOCK_REALTIME - CLOCK_MONOTONIC now, in ns (realtime read between two monotonic reads). */
static int64_t mono_to_real_ns(void)
{
        int64_t m0 = (int64_t)gn_monotonic_ns(), r = (int64_t)gn_realtime_ns();
        int64_t m1 = (int64_t)gn_monotonic_ns();

        return r - (m0 + m1) / 2;
}

/* ioctl with EINTR retried: >= 0 or -errno, no cause. */
static int raw_ioctl(int fd, unsigned long req, void *arg)
{
        int r;

        do
                r = ioctl(fd, req, arg);
        while (r < 0 && errno == EINTR);
        return r < 0 ? -errno : r;
}

/* raw_ioctl() whose failure becomes the cause "NODE: IOCTL: error". */
static int xioctl(struct cam *c, struct cam_v4l2 *s, unsigned long req, const char *name, void *arg)
{
        int r = raw_ioctl(s->fd, req, arg);

        return r < 0 ? cam_set_cause(c, r, "%s: %s: %m", s->path, name) : r;
}

#define IOC(c, s, req, arg) xioctl(c, s, req, #req, arg)

/* Whether fd is a single-planar video capture node that streams; fills cap. */
static bool is_capture(int fd, struct v4l2_capability *cap)
{
        uint32_t caps;

        if (raw_ioctl(fd, VIDIOC_QUERYCAP, cap) < 0)
                return false;
        caps = cap->capabilities & V4L2_CAP_DEVICE_CAPS ? cap->device_caps : cap->capabilities;
        return (caps & V4L2_CAP_VIDEO_CAPTURE) && (caps & V4L2_CAP_STREAMING) &&
               !(caps & V4L2_CAP_TOUCH);
}

/* Finds the one capture node whose card or bus_info is the map's, into s->path. */
static int find_node(struct cam *c, struct cam_v4l2 *s, const struct cam_v4l2_conf *vc)
{
        const char *key = vc->card[0] ? "card" : "bus_info";
        const char *want = vc->card[0] ? vc->card : vc->bus_info;
        _cleanup_(globfree) glob_t g = {0};
        int found = 0;

        if (glob("/dev/video*", 0, NULL, &g) != 0)
                return cam_set_cause(c, -ENOENT, "no /dev/video* node for %s '%s'", key, want);
        for (size_t i = 0; i < g.gl_pathc; i++) {
                struct v4l2_capability cap = {0};
                _cleanup_close_ int fd = open(g.gl_pathv[i], O_RDWR | O_NONBLOCK | O_CLOEXEC);

                if (fd < 0 || !is_capture(fd, &cap) ||
                    strcmp((const char *)(vc->card[0] ? cap.card : cap.bus_info), want) != 0)
                        continue;
                if (found++)
                        return cam_set_cause(c, -ENOTUNIQ, "%s '%s' names both %s and %s", key,
                                             want, s->path, g.gl_pathv[i]);
                snprintf(s->path, sizeof(s->path), "%s", g.gl_pathv[i]);
        }
        return found ? 0
                     : cam_set_cause(c, -ENOENT, "no video capture node has %s '%s'", key, want);
}

static int open_node(struct cam *c, struct cam_v4l2 *s, const struct cam_v4l2_conf *vc)
{
        struct v4l2_capability cap = {0};
        int r = 0;

        if (vc->device[0])
                snprintf(s->path, sizeof(s->path), "%s", vc->device);
        else
                r = find_node(c, s, vc);
        if (r < 0)
                return r;
        s->fd = open(s->path, O_RDWR | O_NONBLOCK | O_CLOEXEC);
        if (s->fd < 0)
                return cam_set_cause(c, -errno, "cannot open %s: %m", s->path);
        if (!is_capture(s->fd, &cap))
                return cam_set_cause(c, -ENODEV, "%s is not a video capture node that streams",
                                     s->path);
        return 0;
}

/* The format to ask for: the map's, or the first the driver lists that gonio converts with
 * the rig file's sample size. */
static int pick_format(struct cam *c, struct cam_v4l2 *s, uint32_t *fourcc)
{
        const struct cam_v4l2_conf *vc = c->conf->backend.conf;
        const struct v4l2p_format *f;
        char name[5];

        if (vc->fourcc) {
                *fourcc = vc->fourcc;
                f = v4l2p_format_find(vc->fourcc);
                return f->bits == c->conf->bits
                               ? 0
                               : cam_set_cause(c, -EINVAL, "format %s gives %d-bit samples, not %d",
                                               v4l2p_fourcc_str(*fourcc, name), f->bits,
                                               c->conf->bits);
        }
        for (uint32_t i = 0;; i++) {
                struct v4l2_fmtdesc d = {.index = i, .type = CAP_TYPE};

                if (raw_ioctl(s->fd, VIDIOC_ENUM_FMT, &d) < 0)
                        break;
                f = v4l2p_format_find(d.pixelformat);
                if (f && f->bits == c->conf->bits) {
                        *fourcc = d.pixelformat;
                        return 0;
                }
        }
        return cam_set_cause(c, -EOPNOTSUPP,
                             "%s offers no %d-bit format among YUYV UYVY RGB3 GREY Y16", s->path,
                             c->conf->bits);
}

/* Sets the rig file's size in the picked format; refuses what the driver changes. */
static int negotiate(struct cam *c, struct cam_v4l2 *s)
{
        struct v4l2_format f = {.type = CAP_TYPE};
        uint32_t fourcc = 0;
        char a[5], b[5];
        int r = pick_format(c, s, &fourcc);

        if (r < 0)
                return r;
        f.fmt.pix = (struct v4l2_pix_format){.width = (uint32_t)c->conf->width,
                                             .height = (uint32_t)c->conf->height,
                                             .pixelformat = fourcc,
                                             .field = V4L2_FIELD_NONE};
        if ((r = IOC(c, s, VIDIOC_S_FMT, &f)) < 0)
                return r;
        if (f.fmt.pix.pixelformat != fourcc || (int)f.fmt.pix.width != c->conf->width ||
            (int)f.fmt.pix.height != c->conf->height)
                return cam_set_cause(c, -EINVAL,
                                     "%s: VIDIOC_S_FMT: asked %dx%d %s, the driver chose %ux%u %s",
                                     s->path, c->conf->width, c->conf->height,
                                     v4l2p_fourcc_str(fourcc, a), f.fmt.pix.width, f.fmt.pix.height,
                                     v4l2p_fourcc_str(f.fmt.pix.pixelformat, b));
        s->fmt = v4l2p_format_find(fourcc);
        s->width = c->conf->width;
        s->height = c->conf->height;
        s->stride = f.fmt.pix.bytesperline ? f.fmt.pix.bytesperline
                                           : (size_t)s->width * (size_t)s->fmt->bytes_pp;
        return 0;
}

/* Sets the map's frame rate (VIDIOC_S_PARM); refuses a rate the driver changes. */
static int set_rate(struct cam *c, struct cam_v4l2 *s, double fps)
{
        struct v4l2_streamparm p = {.type = CAP_TYPE};
        double got;
        int r;

        if (fps <= 0)
                return 0;
        if ((r = IOC(c, s, VIDIOC_G_PARM, &p)) < 0)
                return r;
        if (!(p.parm.capture.capability & V4L2_CAP_TIMEPERFRAME))
                return cam_set_cause(c, -EOPNOTSUPP, "%s sets no frame rate (VIDIOC_S_PARM)",
                                     s->path);
        p.parm.capture.timeperframe = v4l2p_interval(fps);
        if ((r = IOC(c, s, VIDIOC_S_PARM, &p)) < 0)
                return r;
        got = v4l2p_fps(&p.parm.capture.timeperframe);
        if (fabs(got - fps) > fps * 0.005)
                return cam_set_cause(c, -EINVAL,
                                     "%s: VIDIOC_S_PARM: asked %g fps, the driver chose %g fps",
                                     s->path, fps, got);
        return 0;
}

/* The control id's range; !present when the device lacks it or has it disabled. */
static struct v4l2_ctl query_ctl(struct cam_v4l2 *s, uint32_t id)
{
        struct v4l2_queryctrl q = {.id = id};

        if (raw_ioctl(s->fd, VIDIOC_QUERYCTRL, &q) < 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED))
                return (struct v4l2_ctl){0};
        return (struct v4l2_ctl){.present = true, .min = q.minimum, .max = q.maximum};
}

/* Sets control id (named name in messages) to v; with got, reads back what the driver kept. */
static int set_ctl(struct cam *c, struct cam_v4l2 *s, uint32_t id, const char *name, long v,
                   long *got)
{
        struct v4l2_control ct = {.id = id, .value = (int32_t)v};
        int r = raw_ioctl(s->fd, VIDIOC_S_CTRL, &ct);

        if (r < 0)
                return cam_set_cause(c, r, "%s: VIDIOC_S_CTRL %s=%ld: %m", s->path, name, v);
        if (!got)
                return 0;
        ct.value = 0;
        r = raw_ioctl(s->fd, VIDIOC_G_CTRL, &ct);
        if (r < 0)
                return cam_set_cause(c, r, "%s: VIDIOC_G_CTRL %s: %m", s->path, name);
        *got = ct.value;
        return 0;
}

static bool opts_equal(const struct opt_desc *a, const struct opt_desc *b, int n)
{
        for (int i = 0; i < n; i++)
                if (a[i].key != b[i].key || a[i].flags != b[i].flags || a[i].unit != b[i].unit ||
                    a[i].min != b[i].min || a[i].max != b[i].max)
                        return false;
        return true;
}

/* Fills the camera's option table from the device: its exposure and gain ranges. */
static void learn_ranges(struct cam *c, struct cam_v4l2 *s)
{
        struct opt_desc opts[ELEMENTSOF(s->opts)];
        int n = 0;

        s->exposure = query_ctl(s, V4L2_CID_EXPOSURE_ABSOLUTE);
        s->gain = query_ctl(s, V4L2_CID_GAIN);
        opts[n++] = (struct opt_desc){OPT_BITS, OPT_GET | OPT_SET | OPT_LIST, .min = s->fmt->bits,
                                      .max = s->fmt->bits};
        if (s->exposure.present)
                opts[n++] = (struct opt_desc){OPT_EXPOSURE, OPT_GET | OPT_SET, .unit = "us",
                                              .min = v4l2p_exposure_from_dev(s->exposure.min),
                                              .max = v4l2p_exposure_from_dev(s->exposure.max)};
        if (s->gain.present)
                opts[n++] = (struct opt_desc){OPT_GAIN, OPT_GET | OPT_SET, .min = s->gain.min,
                                              .max = s->gain.max};
        /* written only when they change (a reopen finds the same device), since other
         * threads read the table (cam_check_request) */
        if (c->opts != s->opts || c->n_opts != n || !opts_equal(s->opts, opts, n)) {
                memcpy(s->opts, opts, sizeof(*opts) * n);
                c->opts = s->opts;
                c->n_opts = n;
        }
}

/* Sets id to v when the device has it and v is in its range; else keeps the device's. */
static int set_default(struct cam *c, struct cam_v4l2 *s, const struct v4l2_ctl *ct, uint32_t id,
                       const char *name, long v)
{
        if (!ct->present)
                return 0;
        if (v < ct->min || v > ct->max) {
                log_info("camera '%s': %s: rig-file %s %ld outside the device's [%ld, %ld], kept",
                         c->conf->name, s->path, name, v, ct->min, ct->max);
                return 0;
        }
        return set_ctl(c, s, id, name, v, NULL);
}

/* Manual exposure and gain where the device has them, at the rig file's exposure_us and
 * gain when its ranges allow. */
static int class_defaults(struct cam *c, struct cam_v4l2 *s)
{
        int r = 0;

        if (s->exposure.present && query_ctl(s, V4L2_CID_EXPOSURE_AUTO).present)
                r = set_ctl(c, s, V4L2_CID_EXPOSURE_AUTO, "auto_exposure", V4L2_EXPOSURE_MANUAL,
                            NULL);
        if (r >= 0 && s->gain.present && query_ctl(s, V4L2_CID_AUTOGAIN).present)
                r = set_ctl(c, s, V4L2_CID_AUTOGAIN, "gain_automatic", 0, NULL);
        if (r >= 0)
                r = set_default(c, s, &s->exposure, V4L2_CID_EXPOSURE_ABSOLUTE,
                                "exposure_time_absolute",
                                v4l2p_exposure_to_dev(c->conf->exposure_us));
        if (r >= 0)
                r = set_default(c, s, &s->gain, V4L2_CID_GAIN, "gain", lround(c->conf->gain));
        return r;
}

/* Finds the settable integer-valued control called name (v4l2-ctl's spelling) into q. */
static int find_ctl(struct cam *c, struct cam_v4l2 *s, const char *name,
                    struct v4l2_query_ext_ctrl *q)
{
        char n[V4L2P_CTRL_NAME];

        *q = (struct v4l2_query_ext_ctrl){.id = V4L2_CTRL_FLAG_NEXT_CTRL};
        while (raw_ioctl(s->fd, VIDIOC_QUERY_EXT_CTRL, q) >= 0) {
                v4l2p_ctrl_name(q->name, n, sizeof(n));
                if (q->type != V4L2_CTRL_TYPE_CTRL_CLASS && strcmp(n, name) == 0) {
                        if (q->type > V4L2_CTRL_TYPE_INTEGER_MENU ||
                            q->type == V4L2_CTRL_TYPE_INTEGER64 ||
                            q->type == V4L2_CTRL_TYPE_STRING ||
                            (q->flags & (V4L2_CTRL_FLAG_READ_ONLY | V4L2_CTRL_FLAG_DISABLED)))
                                return cam_set_cause(c, -EOPNOTSUPP,
                                                     "%s: control %s is not a settable integer",
                                                     s->path, name);
                        return 0;
                }
                q->id |= V4L2_CTRL_FLAG_NEXT_CTRL;
        }
        return cam_set_cause(c, -ENOENT, "%s has no control '%s' (see v4l2-ctl -d %s -l)", s->path,
                             name, s->path);
}

/* Applies the map's controls, each by name, within the device's range. */
static int map_controls(struct cam *c, struct cam_v4l2 *s, const struct cam_v4l2_conf *vc)
{
        struct v4l2_query_ext_ctrl q;
        int r;

        for (int i = 0; i < vc->n_ctrls; i++) {
                const struct v4l2p_ctrl *ct = &vc->ctrls[i];

                if ((r = find_ctl(c, s, ct->name, &q)) < 0)
                        return r;
                if (ct->value < q.minimum || ct->value > q.maximum)
                        return cam_set_cause(c, -ERANGE, "%s: control %s=%ld outside [%lld, %lld]",
                                             s->path, ct->name, ct->value, (long long)q.minimum,
                                             (long long)q.maximum);
                if ((r = set_ctl(c, s, q.id, ct->name, ct->value, NULL)) < 0)
                        return r;
        }
        return 0;
}

/* What a request's 0 means: exposure and gain as open left them, read back. */
static int read_defaults(struct cam *c, struct cam_v4l2 *s)
{
        struct v4l2_control e = {.id = V4L2_CID_EXPOSURE_ABSOLUTE}, g = {.id = V4L2_CID_GAIN};
        int r = 0;

        if (s->exposure.present && (r = IOC(c, s, VIDIOC_G_CTRL, &e)) >= 0)
                s->def_exposure = e.value;
        if (r >= 0 && s->gain.present && (r = IOC(c, s, VIDIOC_G_CTRL, &g)) >= 0)
                s->def_gain = g.value;
        return r;
}

static void unmap_buffers(struct cam_v4l2 *s)
{
        for (unsigned i = 0; i < s->n_bufs; i++)
                munmap(s->bufs[i].p, s->bufs[i].len);
        s->n_bufs = 0;
}

static int map_buffers(struct cam *c, struct cam_v4l2 *s, int count)
{
        struct v4l2_requestbuffers rb = {
                .count = (uint32_t)count, .type = CAP_TYPE, .memory = V4L2_MEMORY_MMAP};
        int r = IOC(c, s, VIDIOC_REQBUFS, &rb);

        if (r < 0)
                return r;
        if (rb.count < 2)
                return cam_set_cause(c, -ENOMEM, "%s: VIDIOC_REQBUFS: %u buffers granted", s->path,
                                     rb.count);
        for (unsigned i = 0; i < MIN(rb.count, (unsigned)V4L2P_BUFFERS_MAX); i++) {
                struct v4l2_buffer b = {.index = i, .type = CAP_TYPE, .memory = V4L2_MEMORY_MMAP};
                void *p;

                if ((r = IOC(c, s, VIDIOC_QUERYBUF, &b)) < 0)
                        return r;
                p = mmap(NULL, b.length, PROT_READ, MAP_SHARED, s->fd, b.m.offset);
                if (p == MAP_FAILED)
                        return cam_set_cause(c, -errno, "%s: mmap of buffer %u: %m", s->path, i);
                s->bufs[s->n_bufs++] = (struct v4l2_map){p, b.length};
        }
        return 0;
}

static void stream_off(struct cam_v4l2 *s)
{
        int type = CAP_TYPE;

        if (s->on)
                (void)raw_ioctl(s->fd, VIDIOC_STREAMOFF, &type); /* dequeues every buffer */
        s->on = false;
}

static void dev_close(struct cam_v4l2 *s)
{
        if (s->fd < 0)
                return;
        stream_off(s);
        unmap_buffers(s);
        close(s->fd);
        s->fd = -1;
}

/* Opens the node and readies it for capture (api.h); closed again on failure. */
static int dev_open(struct cam *c, struct cam_v4l2 *s)
{
        const struct cam_v4l2_conf *vc = c->conf->backend.conf;
        int r;

        if ((r = open_node(c, s, vc)) >= 0 && (r = negotiate(c, s)) >= 0 &&
            (r = set_rate(c, s, vc->fps)) >= 0) {
                learn_ranges(c, s);
                if ((r = class_defaults(c, s)) >= 0 && (r = map_controls(c, s, vc)) >= 0 &&
                    (r = read_defaults(c, s)) >= 0)
                        r = map_buffers(c, s, vc->buffers);
        }
        if (r < 0)
                dev_close(s);
        else
                log_info("camera '%s': %s, %dx%d %s, %u buffers", c->conf->name, s->path, s->width,
                         s->height, v4l2p_fourcc_str(s->fmt->fourcc, (char[5]){0}), s->n_bufs);
        return r;
}

static int ensure_open(struct cam *c, struct cam_v4l2 *s)
{
        return s->fd >= 0 ? 0 : dev_open(c, s);
}

/* A node that vanished is closed, so that the next op reopens it. Returns r. */
static int gone(struct cam_v4l2 *s, int r)
{
        if (r == -ENODEV)
                dev_close(s);
        return r;
}

/* Sets the request's exposure and gain (0: the defaults) and reads back what was applied. */
static int apply_request(struct cam *c, struct cam_v4l2 *s, const struct cam_request *req)
{
        long e = 0, g = 0;
        int r = 0;

        if (req->bits && req->bits != s->fmt->bits)
                return cam_set_cause(c, -EINVAL, "%s gives %d-bit samples, not %d", s->path,
                                     s->fmt->bits, req->bits);
        if (s->exposure.present)
                r = set_ctl(c, s, V4L2_CID_EXPOSURE_ABSOLUTE, "exposure_time_absolute",
                            req->exposure_us ? v4l2p_exposure_to_dev(req->exposure_us)
                                             : s->def_exposure,
                            &e);
        if (r >= 0 && s->gain.present)
                r = set_ctl(c, s, V4L2_CID_GAIN, "gain",
                            req->gain > 0 ? lround(req->gain) : s->def_gain, &g);
        s->exposure_us = v4l2p_exposure_from_dev(e);
        s->gain_applied = (double)g;
        s->applied_ns = (int64_t)gn_monotonic_ns();
        return r;
}

static int stream_on(struct cam *c, struct cam_v4l2 *s)
{
        int type = CAP_TYPE, r;

        s->on = true; /* so that stream_off() takes back buffers queued before a failure */
        s->to_skip = ((const struct cam_v4l2_conf *)c->conf->backend.conf)->skip;
        for (unsigned i = 0; i < s->n_bufs; i++) {
                struct v4l2_buffer b = {.index = i, .type = CAP_TYPE, .memory = V4L2_MEMORY_MMAP};

                if ((r = IOC(c, s, VIDIOC_QBUF, &b)) < 0)
                        return r;
        }
        return IOC(c, s, VIDIOC_STREAMON, &type);
}

/* Converts buffer b into out with what was applied. */
static int to_frame(struct cam *c, struct cam_v4l2 *s, const struct v4l2_buffer *b, uint64_t ts,
                    struct gn_frame *out)
{
        int r = gn_frame_alloc(out, s->width, s->height, s->fmt->channels, s->fmt->bits);

        if (r < 0)
                return cam_set_cause(c, r, "cannot allocate a %dx%d frame: %m", s->width,
                                     s->height);
        r = v4l2p_convert(s->fmt, s->bufs[b->index].p, b->bytesused, s->stride, out);
        if (r < 0) {
                gn_frame_free_data(out);
                return cam_set_cause(c, r, "%s: buffer %u holds %u bytes, short of a %dx%d image",
                                     s->path, b->index, b->bytesused, s->width, s->height);
        }
        out->timestamp_ns = ts;
        out->exposure_us = s->exposure_us;
        out->gain = s->gain_applied;
        out->seq = b->sequence;
        return 0;
}

/* Dequeues one done buffer into out and queues it again: 0; -EAGAIN when none is done, or
 * the buffer was marked bad, or (fresh) its exposure began before the request was applied,
 * or it is one of the first skip frames since the start. */
static int take(struct cam *c, struct cam_v4l2 *s, struct gn_frame *out, bool fresh)
{
        struct v4l2_buffer b = {.type = CAP_TYPE, .memory = V4L2_MEMORY_MMAP};
        int64_t off = mono_to_real_ns();
        uint64_t ts;
        int r = raw_ioctl(s->fd, VIDIOC_DQBUF, &b), q;

        if (r == -EAGAIN)
                return r;
        if (r < 0)
                return cam_set_cause(c, r, "%s: VIDIOC_DQBUF: %m", s->path);
        if (b.index >= s->n_bufs)
                return cam_set_cause(c, -EIO, "%s: VIDIOC_DQBUF: buffer %u of %u", s->path, b.index,
                                     s->n_bufs);
        ts = v4l2p_timestamp_ns(&b.timestamp, b.flags, off, s->exposure_us);
        if ((b.flags & V4L2_BUF_FLAG_ERROR) || (fresh && ts && (int64_t)ts - off < s->applied_ns))
                r = -EAGAIN;
        else if (s->to_skip > 0 && s->to_skip-- > 0)
                r = -EAGAIN; /* one of the first skip frames since the start */
        else
                r = to_frame(c, s, &b, ts ? ts : gn_realtime_ns(), out);
        q = IOC(c, s, VIDIOC_QBUF, &b);
        if (q < 0 && r >= 0)
                gn_frame_free_data(out);
        return q < 0 ? q : r;
}

/* Waits (poll) for the first fresh frame, at most CAM_V4L2_TIMEOUT_MS beyond the exposure. */
static int wait_frame(struct cam *c, struct cam_v4l2 *s, struct gn_frame *out)
{
        int64_t ms = CAM_V4L2_TIMEOUT_MS + s->exposure_us / 1000;
        int64_t deadline = (int64_t)gn_monotonic_ns() + ms * 1000000;

        for (;;) {
                int64_t left = (deadline - (int64_t)gn_monotonic_ns()) / 1000000;
                struct pollfd p = {.fd = s->fd, .events = POLLIN};
                int r = poll(&p, 1, left > 0 ? (int)left : 0);

                if (r < 0 && errno != EINTR)
                        return cam_set_cause(c, -errno, "%s: poll: %m", s->path);
                if (r > 0 && (r = take(c, s, out, true)) != -EAGAIN)
                        return r;
                if (left <= 0)
                        return cam_set_cause(c, -ETIMEDOUT, "%s: no frame within %lld ms", s->path,
                                             (long long)ms);
        }
}

static int v4l2_open(struct cam *c)
{
        struct cam_v4l2 *s = c->priv;

        if (!c->conf->backend.conf)
                return cam_set_cause(c, -EINVAL, "no v4l2 map in the rig file");
        if (!s) {
                s = calloc(1, sizeof(*s));
                if (!s)
                        return -ENOMEM;
                s->fd = -1;
                c->priv = s;
        }
        s->streaming = false;
        dev_close(s); /* a second open (fault.clear) starts afresh */
        return dev_open(c, s);
}

static void v4l2_close(struct cam *c)
{
        struct cam_v4l2 *s = c->priv;

        if (!s)
                return;
        dev_close(s);
        free(s);
        c->priv = NULL;
        c->opts = NULL;
        c->n_opts = 0;
}

static int v4l2_capture(struct cam *c, const struct cam_request *req, struct gn_frame *out)
{
        struct cam_v4l2 *s = c->priv;
        int r;

        if (!s)
                return -ENOTCONN;
        if (s->streaming)
                return cam_set_cause(c, -EBUSY, "the camera is streaming");
        if ((r = ensure_open(c, s)) >= 0 && (r = apply_request(c, s, req)) >= 0 &&
            (r = stream_on(c, s)) >= 0)
                r = wait_frame(c, s, out);
        if (s->fd >= 0)
                stream_off(s);
        return gone(s, r);
}

static int v4l2_stream_start(struct cam *c, const struct cam_request *req)
{
        struct cam_v4l2 *s = c->priv;
        int r;

        if (!s)
                return -ENOTCONN;
        if (s->streaming)
                return -EBUSY;
        if ((r = ensure_open(c, s)) >= 0 && (r = apply_request(c, s, req)) >= 0)
                r = stream_on(c, s);
        if (r < 0) {
                if (s->fd >= 0)
                        stream_off(s);
                return gone(s, r);
        }
        s->streaming = true;
        return 0;
}

static int v4l2_stream_fd(struct cam *c)
{
        struct cam_v4l2 *s = c->priv;

        return s && s->streaming && s->fd >= 0 ? s->fd : -ENOTCONN;
}

/* A vanished node ends the stream: the next dequeue gives -ENOTCONN. */
static int v4l2_stream_dequeue(struct cam *c, struct gn_frame *out)
{
        struct cam_v4l2 *s = c->priv;
        int r;

        if (!s || !s->streaming || s->fd < 0)
                return -ENOTCONN;
        r = take(c, s, out, false);
        if (r == -ENODEV)
                s->streaming = false;
        return gone(s, r);
}

static void v4l2_stream_stop(struct cam *c)
{
        struct cam_v4l2 *s = c->priv;

        if (!s || !s->streaming)
                return;
        if (s->fd >= 0)
                stream_off(s);
        s->streaming = false;
}

const struct rig_backend cam_v4l2_backend = {
        .name = "v4l2",
        .cls = RIG_CLASS_CAMERA,
        .bus_types = 1u << RIG_BUS_LOCAL,
        .conf_size = sizeof(struct cam_v4l2_conf),
        .parse_conf = cam_v4l2_parse_conf,
        .ops = &cam_v4l2_ops,
};

/* Without a device, the class's own ranges; open replaces them with the device's. */
static const struct opt_desc cam_v4l2_opts[] = {
        {OPT_EXPOSURE, OPT_GET | OPT_SET, .unit = "us", .min = RIG_EXPOSURE_US_MIN,
         .max = RIG_EXPOSURE_US_MAX},
        {OPT_GAIN, OPT_GET | OPT_SET, .min = RIG_GAIN_MIN, .max = RIG_GAIN_MAX},
        {OPT_BITS, OPT_GET | OPT_SET | OPT_LIST, .min = 8, .max = 16},
};

const struct cam_ops cam_v4l2_ops = {
        .name = "v4l2",
        .opts = cam_v4l2_opts,
        .n_opts = ELEMENTSOF(cam_v4l2_opts),
        .open = v4l2_open,
        .close = v4l2_close,
        .capture = v4l2_capture,
        .stream_start = v4l2_stream_start,
        .stream_fd = v4l2_stream_fd,
        .stream_dequeue = v4l2_stream_dequeue,
        .stream_stop = v4l2_stream_stop,
};
