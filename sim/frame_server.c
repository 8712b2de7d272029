/* frame_server.c - gonio-sim's frame socket (protocol: docs/sim.md, "Frame socket").
 *
 * DESIGN: one thread polls the listening sockets and up to FS_MAX_CLIENTS clients
 * and serves one request at a time: a render request takes a snapshot of the
 * emulated rig (sim_emu_snapshot) at the start of the exposure, one at its middle and
 * one at its end (sleeping on the time scale in between), renders (sim_render) in the
 * middle state (the centre of the motion blur, where a real camera's image of a moving
 * rig is centred), appends the exposure to the render log and sends
 * the header line and the bytes before the next request is read. Every other request
 * goes to the control module (control.c). Clients' sends are bounded by SO_SNDTIMEO
 * so a stuck client cannot hold the server. The control module (camera faults), the
 * frame counters and the render log belong to this thread alone. */
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <jansson.h>

#include "common/cleanup.h"
#include "common/clock.h"
#include "common/log.h"
#include "sim/control.h"
#include "sim/frame_server.h"

/* Samples go out in host byte order; the protocol says little-endian. */
_Static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "docs/sim.md: samples are little-endian");

#define FS_MAX_CLIENTS  8
#define FS_POLL_MS      50 /* stop-flag latency */
#define FS_SEND_TIMEOUT 10 /* s */

struct fs_client {
        int fd; /* -1: free slot */
        char buf[SIM_FS_LINE_MAX];
        size_t len;
        bool overlong; /* discarding the rest of a too long line */
        bool control;  /* came in on the control socket: no frames */
};

struct sim_frame_server {
        struct rig_config *rc;
        struct sim_scene *scene;
        struct sim_emu *emu;
        int listen[RIG_MAX_BUSES + 1]; /* frame sockets, then the control socket */
        const char *paths[RIG_MAX_BUSES + 1];
        bool control[RIG_MAX_BUSES + 1];
        size_t n_listen;
        struct fs_client clients[FS_MAX_CLIENTS];
        struct sim_control *ctl;
        double time_scale;
        int render_log; /* O_APPEND, -1: none */
        uint64_t seq[RIG_MAX_CAMERAS];
        uint64_t next_start_ns[RIG_MAX_CAMERAS]; /* CLOCK_MONOTONIC: the frame rate's bound */
        atomic_bool stop;
        pthread_t thread;
        bool started;
};

/* One request being served. */
struct fs_req {
        struct sim_req base; /* the request object and the message of an error reply */
        struct sim_frame_server *fs;
        struct fs_client *cl;
        bool hangup; /* close the connection instead of replying */
};

/* Ground-truth arrays, in the order they follow the pixels. */
static const struct truth_desc {
        const char *name;
        unsigned flag;
        const char *type;
        int components;
} truths[] = {
        {"depth", SIM_TRUTH_DEPTH, "f32", 1},
        {"normal", SIM_TRUTH_NORMAL, "f32", 3},
        {"point", SIM_TRUTH_POINT, "f32", 3},
        {"lamp", SIM_TRUTH_LAMP, "u32", 1},
};

static const void *truth_array(const struct sim_truth *t, unsigned flag)
{
        switch (flag) {
        case SIM_TRUTH_DEPTH:
                return t->depth;
        case SIM_TRUTH_NORMAL:
                return t->normal;
        case SIM_TRUTH_POINT:
                return t->point;
        default:
                return t->lamp_mask;
        }
}

/* ---- replies ---- */

static void client_close(struct fs_client *cl)
{
        if (cl->fd >= 0)
                close(cl->fd);
        *cl = (struct fs_client){.fd = -1};
}

static int send_bytes(struct fs_req *rq, const void *p, size_t n)
{
        const char *c = p;

        while (n > 0 && !rq->hangup) {
                ssize_t k = send(rq->cl->fd, c, n, MSG_NOSIGNAL);
                if (k < 0 && errno == EINTR)
                        continue;
                if (k <= 0) {
                        rq->hangup = true; /* peer gone or stuck past SO_SNDTIMEO */
                        return -EPIPE;
                }
                c += k;
                n -= (size_t)k;
        }
        return rq->hangup ? -EPIPE : 0;
}

/* Sends o (a new reference, consumed; NULL means out of memory) as one line. */
static int send_json(struct fs_req *rq, json_t *o)
{
        char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;

        json_decref(o);
        if (!s)
                return sim_req_fail(&rq->base, ENOMEM, "out of memory");
        size_t n = strlen(s);
        int r = send_bytes(rq, s, n);
        if (r >= 0)
                r = send_bytes(rq, "\n", 1);
        free(s);
        return r;
}

static void send_error(struct fs_req *rq, int r)
{
        (void)send_json(rq, sim_req_error_json(&rq->base, r));
}

/* ---- request fields ---- */

static int truth_arg(struct fs_req *rq, unsigned *flags)
{
        json_t *list = json_object_get(rq->base.req, "truth"), *v;
        size_t i, k;

        if (list && !json_is_array(list))
                return sim_req_fail(&rq->base, EINVAL, "'truth' must be a list of names");
        json_array_foreach(list, i, v)
        {
                const char *name = json_string_value(v);
                for (k = 0; name && k < ELEMENTSOF(truths); k++)
                        if (strcmp(name, truths[k].name) == 0)
                                break;
                if (!name || k == ELEMENTSOF(truths))
                        return sim_req_fail(&rq->base, EINVAL,
                                            "'truth' names are depth, normal, point, lamp");
                *flags |= truths[k].flag;
        }
        return 0;
}

/* Exposure settings of a render request, 0 fields filled with the camera's defaults. */
static int expose_args(struct fs_req *rq, int ci, struct sim_expose *ex)
{
        const struct rig_camera_conf *c = &rq->fs->rc->cameras[ci];
        long exp = 0, bits = 0;
        int r;

        struct sim_req *q = &rq->base;
        if ((r = sim_req_int(q, "exposure_us", 0, SIM_FS_EXPOSURE_MAX_US, &exp)) < 0 ||
            (r = sim_req_num(q, "gain", 0.0, 1000.0, &ex->gain)) < 0 ||
            (r = sim_req_int(q, "bits", 0, 16, &bits)) < 0 ||
            (r = sim_req_bool(q, "no_noise", &ex->no_noise)) < 0)
                return r;
        if (bits != 0 && bits != 8 && bits != 16)
                return sim_req_fail(q, EINVAL, "'bits' must be 8 or 16");
        ex->exposure_us = exp ? (int)exp : c->exposure_us;
        ex->gain = ex->gain > 0.0 ? ex->gain : c->gain;
        ex->bits = bits ? (int)bits : c->bits;
        return 0;
}

static json_t *truth_list(const struct sim_truth *t, unsigned flags, size_t pixels)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < ELEMENTSOF(truths); i++) {
                if (!(flags & truths[i].flag) || !truth_array(t, truths[i].flag))
                        continue;
                size_t bytes = pixels * (size_t)truths[i].components * 4;
                if (json_array_append_new(a, json_pack("{s:s, s:s, s:i, s:I}", "name",
                                                       truths[i].name, "type", truths[i].type,
                                                       "components", truths[i].components, "bytes",
                                                       (json_int_t)bytes)) < 0)
                        json_decref(TAKE_PTR(a));
        }
        return a;
}

/* What a frame was exposed with: the part of its header that the render log repeats. */
struct exposure {
        int cam;
        uint64_t seq, timestamp_ns;
        struct sim_expose ex;
        struct gn_pose start, mid, end; /* the rig's state at the start, middle (rendered) and
                                         * end of the exposure */
};

static json_t *exposure_json(const struct sim_frame_server *fs, const struct exposure *x)
{
        return json_pack("{s:I, s:s, s:I, s:i, s:f, s:o, s:o, s:o}", "seq", (json_int_t)x->seq,
                         "camera", fs->rc->cameras[x->cam].name, "timestamp_ns",
                         (json_int_t)x->timestamp_ns, "exposure_us", x->ex.exposure_us, "gain",
                         x->ex.gain, "state", sim_pose_json(fs->rc, &x->start), "state_mid",
                         sim_pose_json(fs->rc, &x->mid), "state_end",
                         sim_pose_json(fs->rc, &x->end));
}

/* Appends x to the render log as one line in one write(2), so that a kill of gonio-sim at
 * any moment leaves whole lines; a failed write is logged. */
static void log_exposure(struct sim_frame_server *fs, const struct exposure *x)
{
        json_t *o = fs->render_log >= 0 ? exposure_json(fs, x) : NULL;
        _cleanup_free_ char *line = o ? json_dumps(o, JSON_COMPACT) : NULL;
        size_t n = line ? strlen(line) : 0;

        if (line)
                line[n] = '\n'; /* over the NUL: json_dumps gave n + 1 bytes */
        if (o && (!line || write(fs->render_log, line, n + 1) != (ssize_t)(n + 1)))
                log_warning("render log: cannot write frame %s#%" PRIu64 ", ignoring",
                            fs->rc->cameras[x->cam].name, x->seq);
        json_decref(o);
}

static int send_frame(struct fs_req *rq, const struct exposure *x, const struct gn_frame *f,
                      const struct sim_truth *t, unsigned flags)
{
        size_t pixels = (size_t)f->width * (size_t)f->height;
        json_t *h = exposure_json(rq->fs, x);

        if (h && json_object_update_new(h, json_pack("{s:b, s:i, s:i, s:i, s:i, s:I, s:I, s:o}",
                                                     "ok", 1, "width", f->width, "height",
                                                     f->height, "channels", f->channels, "bits",
                                                     f->bits, "stride", (json_int_t)f->stride,
                                                     "bytes", (json_int_t)gn_frame_bytes(f),
                                                     "truth", truth_list(t, flags, pixels))) < 0)
                json_decref(TAKE_PTR(h));
        int r = send_json(rq, h);
        if (r >= 0)
                r = send_bytes(rq, f->data, gn_frame_bytes(f));
        for (size_t i = 0; r >= 0 && i < ELEMENTSOF(truths); i++) {
                const void *a = flags & truths[i].flag ? truth_array(t, truths[i].flag) : NULL;
                if (a)
                        r = send_bytes(rq, a, pixels * (size_t)truths[i].components * 4);
        }
        return r;
}

/* Sleeps on the server thread until CLOCK_MONOTONIC end, in slices so that
 * sim_frame_server_free() is not held up. */
static void sleep_until(struct sim_frame_server *fs, uint64_t end)
{
        for (uint64_t now; !atomic_load(&fs->stop) && (now = gn_monotonic_ns()) < end;) {
                uint64_t ns = MIN(end - now, FS_POLL_MS * UINT64_C(1000000));
                struct timespec ts = {.tv_sec = (time_t)(ns / 1000000000u),
                                      .tv_nsec = (long)(ns % 1000000000u)};
                (void)nanosleep(&ts, NULL);
        }
}

/* Sleeps until us microseconds of emulated time after t0 (CLOCK_MONOTONIC, ns). */
static void expose_wait(struct sim_frame_server *fs, uint64_t t0, double us)
{
        sleep_until(fs, t0 + (uint64_t)(us * 1e3 / fs->time_scale));
}

/* Waits until camera cam may start its next exposure: successive exposures of one camera
 * start at least 1/frame_rate of emulated time apart, as a real sensor's frames do. */
static void frame_rate_wait(struct sim_frame_server *fs, int cam)
{
        double fps = fs->rc->cameras[cam].frame_rate;
        uint64_t period = fps > 0 ? (uint64_t)(1e9 / (fps * fs->time_scale)) : 0, now;

        sleep_until(fs, fs->next_start_ns[cam]);
        now = gn_monotonic_ns();
        /* A steady cadence while frames are asked for in time; after a pause, from now. */
        if (now < fs->next_start_ns[cam] + period)
                fs->next_start_ns[cam] += period;
        else
                fs->next_start_ns[cam] = now + period;
}

/* The request's camera, exposure and truth flags, and its pending camera fault. */
static int render_args(struct fs_req *rq, struct exposure *x, unsigned *flags)
{
        int r = sim_req_camera(&rq->base, rq->fs->rc, &x->cam);
        if (r >= 0)
                r = expose_args(rq, x->cam, &x->ex);
        if (r >= 0)
                r = truth_arg(rq, flags);
        if (r < 0)
                return r;
        r = sim_control_camera_fault(rq->fs->ctl, x->cam);
        if (r == -ECONNABORTED)
                rq->hangup = true;
        else if (r < 0)
                return sim_req_fail(&rq->base, -r, "frame dropped (injected fault)");
        return r;
}

static int do_render(struct fs_req *rq)
{
        struct sim_frame_server *fs = rq->fs;
        struct exposure x = {0};
        struct gn_frame f = {0};
        struct sim_truth t = {0};
        unsigned flags = 0;
        double half_us;
        uint64_t t_mid;

        int r = render_args(rq, &x, &flags);
        if (r < 0)
                return r;
        frame_rate_wait(fs, x.cam);
        sim_emu_snapshot(fs->emu, &x.start);
        x.seq = fs->seq[x.cam]++;
        half_us = x.ex.exposure_us / 2.0;
        expose_wait(fs, gn_monotonic_ns(), half_us);
        /* the rendered state and the timestamp are of one instant, however late the wake-up */
        sim_emu_snapshot(fs->emu, &x.mid);
        t_mid = gn_monotonic_ns();
        x.timestamp_ns = gn_realtime_ns() - (uint64_t)(half_us * 1e3 / fs->time_scale);
        expose_wait(fs, t_mid, half_us);
        sim_emu_snapshot(fs->emu, &x.end);
        r = sim_render(fs->scene, &x.mid, x.cam, &x.ex, x.seq, &f, flags, &t);
        if (r < 0)
                return sim_req_fail(&rq->base, -r, "rendering failed: %s", strerror(-r));
        f.seq = x.seq;
        f.timestamp_ns = x.timestamp_ns;
        log_exposure(fs, &x);
        r = send_frame(rq, &x, &f, &t, flags);
        gn_frame_free_data(&f);
        sim_truth_free(&t);
        return r;
}

/* ---- connections ---- */

static void handle_line(struct sim_frame_server *fs, struct fs_client *cl, const char *line,
                        size_t len)
{
        struct fs_req rq = {.fs = fs, .cl = cl};
        json_error_t jerr;
        json_t *reply = NULL;
        int r;

        rq.base.req = json_loadb(line, len, 0, &jerr);
        const char *cmd = json_string_value(json_object_get(rq.base.req, "cmd"));
        if (!rq.base.req)
                r = sim_req_fail(&rq.base, EINVAL, "malformed JSON: %s", jerr.text);
        else if (!cmd)
                r = sim_req_fail(&rq.base, EINVAL, "a request is an object with a string 'cmd'");
        else if (strcmp(cmd, "render") == 0 && cl->control)
                r = sim_req_fail(&rq.base, EINVAL,
                                 "the control socket renders nothing: ask a camera bus's socket");
        else if (strcmp(cmd, "render") == 0)
                r = do_render(&rq);
        else if ((r = sim_control_handle(fs->ctl, &rq.base, cmd, &reply)) >= 0)
                r = send_json(&rq, reply);
        if (r < 0 && !rq.hangup)
                send_error(&rq, r);
        json_decref(rq.base.req);
        if (rq.hangup)
                client_close(cl);
}

/* A line filled the buffer without a newline: one error reply, then the rest of it
 * up to the next newline is dropped. */
static void overlong_line(struct sim_frame_server *fs, struct fs_client *cl)
{
        struct fs_req rq = {.fs = fs, .cl = cl};

        if (!cl->overlong) {
                send_error(&rq,
                           sim_req_fail(&rq.base, EMSGSIZE, "request line longer than %d bytes",
                                        SIM_FS_LINE_MAX - 1));
                if (rq.hangup) {
                        client_close(cl);
                        return;
                }
        }
        cl->overlong = true;
        cl->len = 0;
}

static void client_input(struct sim_frame_server *fs, struct fs_client *cl)
{
        ssize_t k = recv(cl->fd, cl->buf + cl->len, sizeof cl->buf - cl->len, MSG_DONTWAIT);

        if (k == 0 || (k < 0 && errno != EAGAIN && errno != EINTR)) {
                client_close(cl);
                return;
        }
        cl->len += k > 0 ? (size_t)k : 0;
        while (cl->fd >= 0) {
                char *nl = memchr(cl->buf, '\n', cl->len);
                if (!nl) {
                        if (cl->len == sizeof cl->buf)
                                overlong_line(fs, cl);
                        return;
                }
                size_t n = (size_t)(nl - cl->buf);
                if (cl->overlong)
                        cl->overlong = false;
                else
                        handle_line(fs, cl, cl->buf, n);
                if (cl->fd < 0)
                        return;
                memmove(cl->buf, nl + 1, cl->len - n - 1);
                cl->len -= n + 1;
        }
}

static void accept_client(struct sim_frame_server *fs, size_t li)
{
        struct timeval tv = {.tv_sec = FS_SEND_TIMEOUT};
        int fd = accept4(fs->listen[li], NULL, NULL, SOCK_CLOEXEC);

        if (fd < 0)
                return;
        (void)setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
        for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                if (fs->clients[i].fd < 0) {
                        fs->clients[i] = (struct fs_client){.fd = fd, .control = fs->control[li]};
                        return;
                }
        struct fs_client tmp = {.fd = fd};
        struct fs_req rq = {.fs = fs, .cl = &tmp};
        send_error(&rq, sim_req_fail(&rq.base, EBUSY, "more than %d clients", FS_MAX_CLIENTS));
        close(fd);
}

static void *server_thread(void *userdata)
{
        struct sim_frame_server *fs = userdata;
        struct pollfd p[RIG_MAX_BUSES + 1 + FS_MAX_CLIENTS];

        while (!atomic_load(&fs->stop)) {
                size_t n = 0;
                for (size_t i = 0; i < fs->n_listen; i++)
                        p[n++] = (struct pollfd){.fd = fs->listen[i], .events = POLLIN};
                for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                        p[n++] = (struct pollfd){.fd = fs->clients[i].fd, .events = POLLIN};
                if (poll(p, n, FS_POLL_MS) <= 0)
                        continue;
                for (size_t i = 0; i < fs->n_listen; i++)
                        if (p[i].revents)
                                accept_client(fs, i);
                for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                        if (p[fs->n_listen + i].revents && fs->clients[i].fd >= 0)
                                client_input(fs, &fs->clients[i]);
        }
        return NULL;
}

/* ---- setup ---- */

/* Removes a socket file nobody listens on any more; refuses anything else. */
static int clear_stale(const char *path, const struct sockaddr_un *sa)
{
        struct stat st;

        if (lstat(path, &st) < 0)
                return 0;
        if (!S_ISSOCK(st.st_mode))
                return log_error_errno(SYNTHETIC_ERRNO(EEXIST),
                                       "frame socket %s: exists and is not a socket", path);
        _cleanup_close_ int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd >= 0 && connect(fd, (const struct sockaddr *)sa, sizeof *sa) == 0)
                return log_error_errno(SYNTHETIC_ERRNO(EADDRINUSE),
                                       "frame socket %s: another server is listening", path);
        (void)unlink(path);
        return 0;
}

static int listen_on(struct sim_frame_server *fs, const char *path, bool control)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};

        if (strlen(path) >= sizeof sa.sun_path)
                return log_error_errno(SYNTHETIC_ERRNO(ENAMETOOLONG),
                                       "frame socket %s: path too long", path);
        strcpy(sa.sun_path, path);
        int r = clear_stale(path, &sa);
        if (r < 0)
                return r;
        _cleanup_close_ int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd < 0 || bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0)
                return log_error_errno(errno, "frame socket %s: %m", path);
        fs->paths[fs->n_listen] = path; /* bound: removed by sim_frame_server_free */
        fs->control[fs->n_listen] = control;
        fs->listen[fs->n_listen++] = TAKE_FD(fd);
        if (listen(fs->listen[fs->n_listen - 1], FS_MAX_CLIENTS) < 0)
                return log_error_errno(errno, "frame socket %s: %m", path);
        return 0;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_frame_server *, sim_frame_server_free);

static int listen_all(struct sim_frame_server *fs, const char *control)
{
        const struct rig_config *rc = fs->rc;

        for (size_t i = 0; i < rc->n_buses; i++) {
                if (rc->buses[i].type != RIG_BUS_SIM)
                        continue;
                int r = listen_on(fs, rc->buses[i].port, false);
                if (r < 0)
                        return r;
        }
        if (control)
                return listen_on(fs, control, true);
        if (fs->n_listen == 0)
                return log_error_errno(SYNTHETIC_ERRNO(ENOENT),
                                       "the rig has no bus of type sim and no control socket");
        return 0;
}

static int apply_options(struct sim_frame_server *fs, const struct sim_fs_options *opt)
{
        fs->time_scale = opt && opt->time_scale > 0.0 ? opt->time_scale : 1.0;
        if (!opt || !opt->render_log)
                return 0;
        fs->render_log = open(opt->render_log, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
        if (fs->render_log < 0)
                return log_error_errno(errno, "render log %s: %m", opt->render_log);
        return 0;
}

int sim_frame_server_new(struct rig_config *rc, struct sim_scene *scene, struct sim_emu *emu,
                         const struct sim_fs_options *opt, struct sim_frame_server **ret)
{
        if (!rc || !scene || !emu || !ret)
                return -EINVAL;

        _cleanup_(sim_frame_server_freep) struct sim_frame_server *fs = calloc(1, sizeof *fs);
        if (!fs)
                return -ENOMEM;
        *fs = (struct sim_frame_server){.rc = rc, .scene = scene, .emu = emu, .render_log = -1};
        for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                fs->clients[i].fd = -1;
        int r = sim_control_new(rc, scene, emu, &fs->ctl);
        if (r >= 0)
                r = apply_options(fs, opt);
        if (r >= 0)
                r = listen_all(fs, opt ? opt->control : NULL);
        if (r < 0)
                return r;
        r = -pthread_create(&fs->thread, NULL, server_thread, fs);
        if (r < 0)
                return log_error_errno(r, "frame server: cannot start thread: %m");
        fs->started = true;
        *ret = TAKE_PTR(fs);
        return 0;
}

struct sim_frame_server *sim_frame_server_free(struct sim_frame_server *fs)
{
        if (!fs)
                return NULL;
        atomic_store(&fs->stop, true);
        if (fs->started)
                pthread_join(fs->thread, NULL);
        for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                client_close(&fs->clients[i]);
        for (size_t i = 0; i < fs->n_listen; i++) {
                close(fs->listen[i]);
                (void)unlink(fs->paths[i]);
        }
        if (fs->render_log >= 0)
                close(fs->render_log);
        sim_control_free(fs->ctl);
        free(fs);
        return NULL;
}
