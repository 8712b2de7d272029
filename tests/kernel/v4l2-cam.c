/* v4l2-cam.c - kernel lane test of gonio's "v4l2" camera backend on vivid's two capture
 * nodes (platform:vivid-000 and -001), through the camera class on one bus worker per
 * camera, as goniod drives it: formats negotiated (and refused), vivid's colour bars through
 * the YUYV and UYVY conversions, GREY and Y16 levels, both cameras capturing at once,
 * controls set and read back (also by this program's own ioctls), timestamps in
 * CLOCK_REALTIME, streaming through the fd, faults vivid injects (dropped frames, a buffer
 * flagged bad), and a node that vanishes (the vivid device unbound) and returns (bound
 * again).
 *
 * Usage: kl-v4l2-cam [CASE] (every case, in order, without one). Needs root in the guest. */
#include <fcntl.h>
#include <glob.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <systemd/sd-event.h>
#include <time.h>

#include "common/cleanup.h"
#include "common/rigconf.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/camera.h"
#include "drivers/camera/v4l2/proto.h"
#include "drivers/registry.h"
#include "tests/test.h"

#define VIVID_SYSFS "/sys/bus/platform/drivers/vivid/"
/* vivid's fault injection controls (drivers/media/test-drivers/vivid/vivid-ctrls.c) */
#define VIVID_CID_PERCENTAGE_DROPPED 0x00f0f040 /* percentage_of_dropped_buffers */
#define VIVID_CID_BUF_FLAG_ERROR     0x00f0f042 /* inject_v4l2_buf_flag_error (button) */

static const char rig_yaml[] =
        "rig: klane-v4l2\n"
        "buses:\n"
        "  - { name: cams0, type: local }\n"
        "  - { name: cams1, type: local }\n"
        "cameras:\n"
        "  - name: cam0\n"
        "    v4l2: { bus: cams0, bus_info: 'platform:vivid-000', format: YUYV, skip: 2, fps: 25 }\n"
        "    elevation: 20\n"
        "    distance: 500\n"
        "    target: [0, 0, 0]\n"
        "    width: 640\n"
        "    height: 480\n"
        "    fx: 500\n"
        "    fy: 500\n"
        "    gain: 40\n"
        "  - name: cam1\n"
        "    v4l2: { bus: cams1, bus_info: 'platform:vivid-001', format: UYVY, buffers: 3, fps: "
        "30,\n"
        "            controls: { brightness: 200, gain_automatic: 0, timestamp_source: 1 } }\n"
        "    elevation: 20\n"
        "    distance: 500\n"
        "    target: [0, 0, 0]\n"
        "    width: 320\n"
        "    height: 180\n"
        "    fx: 250\n"
        "    fy: 250\n";

enum job_op { J_OPEN, J_CAPTURE, J_START, J_DEQUEUE, J_STOP };

struct job {
        struct cam *cam;
        enum job_op op;
        struct cam_request req;
        struct gn_frame fr;
        int r;
        bool done;
        int64_t t0, t1; /* CLOCK_REALTIME ns around the op, on the worker */
};

static struct {
        sd_event *event;
        struct rig_config *rc;
        struct bus *bus[2];
        struct cam *cam[2];
} F;

static int64_t realtime_ns(void)
{
        struct timespec t;

        clock_gettime(CLOCK_REALTIME, &t);
        return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static int job_run(struct bus *b, void *userdata)
{
        struct job *j = userdata;
        int r = 0;

        j->t0 = realtime_ns();
        switch (j->op) {
        case J_OPEN:
                r = cam_open(j->cam);
                break;
        case J_CAPTURE:
                r = cam_capture(j->cam, &j->req, &j->fr);
                break;
        case J_START:
                r = cam_stream_start(j->cam, &j->req);
                break;
        case J_DEQUEUE:
                r = cam_stream_dequeue(j->cam, &j->fr);
                break;
        case J_STOP:
                cam_stream_stop(j->cam);
                break;
        }
        j->t1 = realtime_ns();
        return r;
}

static void job_done(struct bus *b, int result, void *userdata)
{
        struct job *j = userdata;

        j->r = result;
        j->done = true;
}

/* Runs the jobs, each on its camera's bus worker, at once; waits for all (20 s at most). */
static void run_jobs(struct job *jobs, size_t n)
{
        time_t end = time(NULL) + 20;
        size_t done = 0;

        for (size_t i = 0; i < n; i++) {
                size_t k = jobs[i].cam == F.cam[0] ? 0 : 1;

                jobs[i].done = false;
                CHECK_INT(bus_submit(F.bus[k], job_run, job_done, &jobs[i], false), 0);
        }
        while (done < n) {
                CHECK(time(NULL) < end);
                CHECK(sd_event_run(F.event, 1000000) >= 0);
                done = 0;
                for (size_t i = 0; i < n; i++)
                        done += jobs[i].done;
        }
}

static int run1(struct job *j)
{
        run_jobs(j, 1);
        return j->r;
}

/* The capture node with this bus_info, found by this program itself. */
static void node_of(const char *bus_info, char *path, size_t len)
{
        _cleanup_(globfree) glob_t g = {0};

        path[0] = '\0';
        CHECK_INT(glob("/dev/video*", 0, NULL, &g), 0);
        for (size_t i = 0; i < g.gl_pathc; i++) {
                struct v4l2_capability cap = {0};
                _cleanup_close_ int fd = open(g.gl_pathv[i], O_RDWR | O_NONBLOCK);

                if (fd >= 0 && ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0 &&
                    strcmp((const char *)cap.bus_info, bus_info) == 0)
                        snprintf(path, len, "%s", g.gl_pathv[i]);
        }
        CHECK(path[0]);
}

/* A control's value read by this program on the node, not through the backend. */
static long read_ctrl(const char *bus_info, uint32_t id)
{
        char path[64];
        struct v4l2_control c = {.id = id};

        node_of(bus_info, path, sizeof(path));
        _cleanup_close_ int fd = open(path, O_RDWR | O_NONBLOCK);
        CHECK(fd >= 0);
        CHECK_INT(ioctl(fd, VIDIOC_G_CTRL, &c), 0);
        return c.value;
}

/* Sets a control on the node by this program's own ioctl (vivid's fault injection). */
static void write_ctrl(const char *bus_info, uint32_t id, int value)
{
        char path[64];
        struct v4l2_control c = {.id = id, .value = value};

        node_of(bus_info, path, sizeof(path));
        _cleanup_close_ int fd = open(path, O_RDWR | O_NONBLOCK);
        CHECK(fd >= 0);
        CHECK_INT(ioctl(fd, VIDIOC_S_CTRL, &c), 0);
}

/* The pixel at x, y of an rgb8 frame, near rgb (each channel within tol). */
static void check_rgb(const struct gn_frame *f, int x, int y, int r, int g, int b, int tol)
{
        const uint8_t *p = f->data + f->stride * (size_t)y + 3 * (size_t)x;

        CHECK_NEAR(p[0], r, tol);
        CHECK_NEAR(p[1], g, tol);
        CHECK_NEAR(p[2], b, tol);
}

/* vivid's default test pattern, 75% colour bars: white, yellow, cyan, green, magenta, red,
 * blue, black, each an eighth of the width; sampled mid-bar on the middle row. */
static void check_bars(const struct gn_frame *f)
{
        static const int bars[8][3] = {{191, 191, 191}, {191, 191, 0}, {0, 191, 191}, {0, 191, 0},
                                       {191, 0, 191},   {191, 0, 0},   {0, 0, 191},   {0, 0, 0}};

        for (int i = 0; i < 8; i++)
                check_rgb(f, f->width * (2 * i + 1) / 16, f->height / 2, bars[i][0], bars[i][1],
                          bars[i][2], 6);
}

/* The frame rate set on the node, read by this program's own VIDIOC_G_PARM. */
static double read_fps(const char *bus_info)
{
        char path[64];
        struct v4l2_streamparm p = {.type = V4L2_BUF_TYPE_VIDEO_CAPTURE};

        node_of(bus_info, path, sizeof(path));
        _cleanup_close_ int fd = open(path, O_RDWR | O_NONBLOCK);
        CHECK(fd >= 0);
        CHECK_INT(ioctl(fd, VIDIOC_G_PARM, &p), 0);
        CHECK(p.parm.capture.timeperframe.numerator > 0);
        return (double)p.parm.capture.timeperframe.denominator /
               p.parm.capture.timeperframe.numerator;
}

/* Open: the sizes, formats and rates asked are granted; the option tables are vivid's
 * ranges. */
static void t_negotiate(void)
{
        struct job j[2] = {{.cam = F.cam[0], .op = J_OPEN}, {.cam = F.cam[1], .op = J_OPEN}};
        char msg[128];
        int n;

        run_jobs(j, 2);
        CHECK_INT(j[0].r, 0);
        CHECK_INT(j[1].r, 0);
        CHECK_NEAR(read_fps("platform:vivid-000"), 25, 1e-9);
        CHECK_NEAR(read_fps("platform:vivid-001"), 30, 1e-9);
        const struct opt_desc *o = cam_opts(F.cam[0], &n);
        CHECK(opt_find(o, n, OPT_EXPOSURE) == NULL); /* vivid has no exposure control */
        CHECK_NEAR(opt_find(o, n, OPT_GAIN)->max, 255, 0);
        CHECK_NEAR(opt_find(o, n, OPT_BITS)->max, 8, 0);
        CHECK_INT(cam_check_request(F.cam[0], &(struct cam_request){.gain = 300}, msg, sizeof(msg)),
                  -ERANGE);
        CHECK_STR(msg, "gain 300 outside [0, 255]");
        CHECK_INT(cam_check_request(F.cam[0], &(struct cam_request){.exposure_us = 1000}, msg,
                                    sizeof(msg)),
                  -EOPNOTSUPP);
}

/* Both cameras capture at once, each on its worker; colours through YUYV and UYVY. */
static void t_two_at_once(void)
{
        struct job j[2] = {{.cam = F.cam[0], .op = J_CAPTURE}, {.cam = F.cam[1], .op = J_CAPTURE}};

        run_jobs(j, 2);
        CHECK_INT(j[0].r, 0);
        CHECK_INT(j[1].r, 0);
        CHECK(j[0].t0 < j[1].t1 && j[1].t0 < j[0].t1); /* the two captures overlapped */
        CHECK_INT(j[0].fr.seq, 2);                     /* cam0 skips two frames after each start */
        CHECK_INT(j[1].fr.seq, 0);
        CHECK_INT(j[0].fr.width, 640);
        CHECK_INT(j[0].fr.height, 480);
        CHECK_STR(gn_frame_format(&j[0].fr), "rgb8");
        CHECK_INT(j[1].fr.width, 320);
        CHECK_INT(j[1].fr.height, 180);
        CHECK_STR(gn_frame_format(&j[1].fr), "rgb8");
        check_bars(&j[0].fr);
        /* cam1's brightness 200 lifts every bar; yellow stays yellow, blue stays blue (on the
         * bottom row: vivid's text covers the top half of so small an image) */
        const uint8_t *y = j[1].fr.data + j[1].fr.stride * 170 + 3 * (320 * 3 / 16);
        const uint8_t *b = j[1].fr.data + j[1].fr.stride * 170 + 3 * (320 * 13 / 16);
        CHECK(y[0] > 200 && y[1] > 200 && y[2] + 80 < y[0]);
        CHECK(b[2] > b[0] + 80 && b[2] > b[1] + 80);
        gn_frame_free_data(&j[0].fr);
        gn_frame_free_data(&j[1].fr);
}

/* Gain set by a request is applied, read back into the frame and seen on the node; a
 * request's 0 restores the rig file's gain; the controls map holds. */
static void t_controls(void)
{
        struct job j = {.cam = F.cam[0], .op = J_CAPTURE, .req = {.gain = 42}};

        CHECK_INT(run1(&j), 0);
        CHECK_NEAR(j.fr.gain, 42, 0);
        CHECK_INT(j.fr.exposure_us, 0); /* no exposure control: unknown */
        CHECK_INT(read_ctrl("platform:vivid-000", V4L2_CID_GAIN), 42);
        CHECK_INT(read_ctrl("platform:vivid-000", V4L2_CID_AUTOGAIN), 0);
        gn_frame_free_data(&j.fr);
        j.req.gain = 0;
        CHECK_INT(run1(&j), 0);
        CHECK_NEAR(j.fr.gain, 40, 0); /* the rig file's gain */
        CHECK_INT(read_ctrl("platform:vivid-000", V4L2_CID_GAIN), 40);
        gn_frame_free_data(&j.fr);
        CHECK_INT(read_ctrl("platform:vivid-001", V4L2_CID_BRIGHTNESS), 200);
        CHECK_INT(read_ctrl("platform:vivid-000", V4L2_CID_BRIGHTNESS), 128);
}

/* Each capture's timestamp is CLOCK_REALTIME within the capture call, increasing (cam1:
 * vivid stamps the start of the frame, timestamp_source 1; its end-of-frame stamps are
 * emulated ahead of delivery). */
static void t_timestamps(void)
{
        uint64_t last = 0;

        for (int i = 0; i < 3; i++) {
                struct job j = {.cam = F.cam[1], .op = J_CAPTURE};

                CHECK_INT(run1(&j), 0);
                fprintf(stderr, "capture %d: at %lld of %lld ns of the call, seq %llu\n", i,
                        (long long)((int64_t)j.fr.timestamp_ns - j.t0), (long long)(j.t1 - j.t0),
                        (unsigned long long)j.fr.seq);
                CHECK((int64_t)j.fr.timestamp_ns >= j.t0 && (int64_t)j.fr.timestamp_ns <= j.t1);
                CHECK(j.fr.timestamp_ns > last);
                last = j.fr.timestamp_ns;
                gn_frame_free_data(&j.fr);
        }
}

/* Streaming: the fd polled as goniod's loop would, frames dequeued on the worker in order,
 * capture refused meanwhile, the fd gone after stop and capture back. */
static void t_stream(void)
{
        struct job j = {.cam = F.cam[1], .op = J_START, .req = {.gain = 7}};
        uint64_t first_ts = 0, first_seq = 0, last_ts = 0, last_seq = 0;
        int got = 0, fd;

        CHECK_INT(cam_stream_fd(F.cam[1]), -ENOTCONN);
        CHECK_INT(run1(&j), 0);
        fd = cam_stream_fd(F.cam[1]);
        CHECK(fd >= 0);
        j.op = J_CAPTURE;
        CHECK_INT(run1(&j), -EBUSY);
        while (got < 16) {
                struct pollfd p = {.fd = cam_stream_fd(F.cam[1]), .events = POLLIN};

                CHECK_INT(poll(&p, 1, 3000), 1);
                j.op = J_DEQUEUE;
                if (run1(&j) == -EAGAIN)
                        continue;
                CHECK_INT(j.r, 0);
                CHECK_NEAR(j.fr.gain, 7, 0);
                CHECK(j.fr.timestamp_ns > last_ts && (got == 0 || j.fr.seq > last_seq));
                if (got == 0) {
                        first_ts = j.fr.timestamp_ns;
                        first_seq = j.fr.seq;
                }
                last_ts = j.fr.timestamp_ns;
                last_seq = j.fr.seq;
                got++;
                gn_frame_free_data(&j.fr);
        }
        /* 30 fps: frames 33.3 ms apart (vivid stamps them when its thread fills them, which a
         * loaded host delays by milliseconds: 15 intervals absorb 20 ms of it, and 25 or 60 fps
         * or a unit error still fail) */
        CHECK_NEAR((double)(last_ts - first_ts) / (double)(last_seq - first_seq), 1e9 / 30, 1.5e6);
        j.op = J_STOP;
        run1(&j);
        CHECK_INT(cam_stream_fd(F.cam[1]), -ENOTCONN);
        j.op = J_CAPTURE;
        CHECK_INT(run1(&j), 0);
        gn_frame_free_data(&j.fr);
}

/* Faults vivid injects: every frame dropped (a bounded wait, -ETIMEDOUT naming the node,
 * capture fine again once frames flow); a buffer flagged V4L2_BUF_FLAG_ERROR (skipped: the
 * capture returns the next frame). */
static void t_faults(void)
{
        struct job j = {.cam = F.cam[1], .op = J_CAPTURE};

        write_ctrl("platform:vivid-001", VIVID_CID_PERCENTAGE_DROPPED, 100);
        CHECK_INT(run1(&j), -ETIMEDOUT);
        CHECK(j.t1 - j.t0 < 4000000000LL);
        CHECK_STR_CONTAINS(F.cam[1]->last_error, "[v4l2@cams1]: Failed to capture: /dev/video");
        CHECK_STR_CONTAINS(F.cam[1]->last_error, ": no frame within 3000 ms");
        write_ctrl("platform:vivid-001", VIVID_CID_PERCENTAGE_DROPPED, 0);
        CHECK_INT(run1(&j), 0);
        CHECK_INT(j.fr.seq, 0);
        gn_frame_free_data(&j.fr);
        write_ctrl("platform:vivid-001", VIVID_CID_BUF_FLAG_ERROR, 1);
        CHECK_INT(run1(&j), 0);
        CHECK_INT(j.fr.seq, 1); /* frame 0 came flagged bad */
        gn_frame_free_data(&j.fr);
}

/* Opens a camera built from cam0's entry changed by fn, and captures into fr (unless NULL)
 * when it opened; returns the first failure or 0, last_error in err. */
static int open_variant(void (*fn)(struct rig_camera_conf *, struct cam_v4l2_conf *), char *err,
                        size_t len, struct gn_frame *fr)
{
        struct rig_camera_conf cc = F.rc->cameras[0];
        struct cam_v4l2_conf vc = *(const struct cam_v4l2_conf *)cc.backend.conf;
        struct cam *c;
        struct job j = {.op = J_OPEN};

        fn(&cc, &vc);
        cc.backend.conf = &vc;
        CHECK_INT(cam_new(&cc, F.bus[0], &c), 0);
        j.cam = c;
        if (run1(&j) == 0 && fr) {
                j.op = J_CAPTURE;
                run1(&j);
                *fr = j.fr;
        }
        snprintf(err, len, "%s", c->last_error);
        fprintf(stderr, "%s\n", err);
        cam_free(c);
        return j.r;
}

static void odd_size(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        cc->width = 123;
}

static void odd_rate(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        vc->fps = 7;
}

static void bad_name(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        vc->ctrls[vc->n_ctrls++] = (struct v4l2p_ctrl){"no_such_control", 1};
}

static void bad_value(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        vc->ctrls[vc->n_ctrls++] = (struct v4l2p_ctrl){"brightness", 999};
}

static void by_card(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        vc->bus_info[0] = '\0';
        snprintf(vc->card, sizeof(vc->card), "vivid");
}

static void by_path(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        vc->bus_info[0] = '\0';
        node_of("platform:vivid-000", vc->device, sizeof(vc->device));
        vc->fourcc = 0; /* the first 8-bit format vivid lists that gonio converts */
}

static void sixteen_bits(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        cc->bits = 16;
        vc->fourcc = 0; /* the first 16-bit one: Y16 */
}

static void grey(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        v4l2p_fourcc_parse("GREY", &vc->fourcc);
}

static void yuyv_16(struct rig_camera_conf *cc, struct cam_v4l2_conf *vc)
{
        cc->bits = 16; /* with format YUYV */
}

/* cam0 closed for variants of its entry (a node whose buffers another fd holds refuses
 * VIDIOC_S_FMT: EBUSY), and opened again. */
static void cam0_close(void)
{
        F.cam[0] = cam_free(F.cam[0]);
}

static void cam0_reopen(void)
{
        struct job j = {.op = J_OPEN};

        CHECK_INT(cam_new(&F.rc->cameras[0], F.bus[0], &F.cam[0]), 0);
        j.cam = F.cam[0];
        CHECK_INT(run1(&j), 0);
}

/* Other formats: 16 bits picks Y16 (mono16), GREY gives mono8, both with the bars' levels
 * (white above, black below); YUYV with 16 bits refused. */
static void t_formats(void)
{
        struct gn_frame f = {0};
        char e[DEV_ERROR_MAX];

        cam0_close();
        CHECK_INT(open_variant(sixteen_bits, e, sizeof(e), &f), 0);
        CHECK_STR(gn_frame_format(&f), "mono16");
        const uint16_t *w = (const uint16_t *)(f.data + f.stride * 240) + 40;
        const uint16_t *k = (const uint16_t *)(f.data + f.stride * 240) + 600;
        fprintf(stderr, "Y16: white %u black %u\n", w[0], k[0]);
        CHECK(w[0] > 150 * 256 && k[0] < 40 * 256);
        gn_frame_free_data(&f);
        CHECK_INT(open_variant(grey, e, sizeof(e), &f), 0);
        CHECK_STR(gn_frame_format(&f), "mono8");
        fprintf(stderr, "GREY: white %u black %u\n", f.data[f.stride * 240 + 40],
                f.data[f.stride * 240 + 600]);
        CHECK(f.data[f.stride * 240 + 40] > 150 && f.data[f.stride * 240 + 600] < 40);
        gn_frame_free_data(&f);
        CHECK_INT(open_variant(yuyv_16, e, sizeof(e), NULL), -EINVAL);
        CHECK_STR_CONTAINS(e, "format YUYV gives 8-bit samples, not 16");
        cam0_reopen();
}

/* What open refuses, each with node, ioctl or control and cause in the message (cam0
 * closed meanwhile); the node by path opens. */
static void t_refusals(void)
{
        char e[DEV_ERROR_MAX];

        cam0_close();

        CHECK_INT(open_variant(odd_size, e, sizeof(e), NULL), -EINVAL);
        CHECK_STR_CONTAINS(e, "VIDIOC_S_FMT: asked 123x480 YUYV, the driver chose");
        CHECK_INT(open_variant(odd_rate, e, sizeof(e), NULL), -EINVAL);
        CHECK_STR_CONTAINS(e, "VIDIOC_S_PARM: asked 7 fps, the driver chose");
        CHECK_INT(open_variant(bad_name, e, sizeof(e), NULL), -ENOENT);
        CHECK_STR_CONTAINS(e, "has no control 'no_such_control'");
        CHECK_INT(open_variant(bad_value, e, sizeof(e), NULL), -ERANGE);
        CHECK_STR_CONTAINS(e, "control brightness=999 outside [0, 255]");
        CHECK_INT(open_variant(by_card, e, sizeof(e), NULL), -ENOTUNIQ);
        CHECK_STR_CONTAINS(e, "card 'vivid' names both /dev/video");
        CHECK_INT(open_variant(by_path, e, sizeof(e), NULL), 0);
        cam0_reopen();
}

static void sysfs_write(const char *file, const char *text)
{
        _cleanup_close_ int fd = open(file, O_WRONLY);

        CHECK(fd >= 0);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
}

/* The vivid device unbound while cam0 streams and idles: errors name the node and cause;
 * bound again, the next capture reopens by bus_info; so does a second open (fault.clear). */
static void t_vanish(void)
{
        struct job j = {.cam = F.cam[0], .op = J_START};

        CHECK_INT(run1(&j), 0);
        sysfs_write(VIVID_SYSFS "unbind", "vivid.0");
        j.op = J_DEQUEUE;
        CHECK_INT(run1(&j), -ENODEV);
        CHECK_STR_CONTAINS(F.cam[0]->last_error,
                           "camera 'cam0' [v4l2@cams0]: Failed to dequeue a frame: /dev/video");
        CHECK_STR_CONTAINS(F.cam[0]->last_error, ": VIDIOC_DQBUF: No such device");
        CHECK_INT(run1(&j), -ENOTCONN);
        j.op = J_CAPTURE;
        CHECK_INT(run1(&j), -ENOENT);
        CHECK_STR_CONTAINS(F.cam[0]->last_error, "no video capture node has bus_info");
        sysfs_write(VIVID_SYSFS "bind", "vivid.0");
        CHECK_INT(run1(&j), 0);
        CHECK_NEAR(j.fr.gain, 40, 0);
        gn_frame_free_data(&j.fr);
        j.op = J_OPEN;
        CHECK_INT(run1(&j), 0);
}

static void setup(void)
{
        char path[] = "/tmp/kl-v4l2-XXXXXX", err[512] = "";
        int fd = mkstemp(path);

        CHECK(fd >= 0);
        CHECK(write(fd, rig_yaml, strlen(rig_yaml)) == (ssize_t)strlen(rig_yaml));
        close(fd);
        if (rigconf_load(path, registry_backends, &F.rc, err, sizeof(err)) < 0) {
                fprintf(stderr, "%s\n", err);
                exit(1);
        }
        unlink(path);
        CHECK_INT(sd_event_new(&F.event), 0);
        for (int i = 0; i < 2; i++) {
                CHECK_INT(bus_new(F.event, rigconf_bus(F.rc, F.rc->cameras[i].bus), &F.bus[i]), 0);
                CHECK_INT(cam_new(&F.rc->cameras[i], F.bus[i], &F.cam[i]), 0);
        }
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"negotiate", t_negotiate}, {"two-at-once", t_two_at_once},
                {"controls", t_controls},   {"timestamps", t_timestamps},
                {"stream", t_stream},       {"formats", t_formats},
                {"faults", t_faults},       {"refusals", t_refusals},
                {"vanish", t_vanish},
        };

        setup();
        if (argc > 1 && strcmp(argv[1], "negotiate") != 0)
                t_negotiate();
        TEST_RUN_CASES(cases, argc, argv);
        for (int i = 0; i < 2; i++) {
                F.cam[i] = cam_free(F.cam[i]);
                F.bus[i] = bus_free(F.bus[i]);
        }
        sd_event_unref(F.event);
        rigconf_free(F.rc);
        return 0;
}
