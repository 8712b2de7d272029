/* frame_server.c - gonio-sim's frame socket (protocol: docs/sim.md, "Frame socket").
 *
 * DESIGN: one thread polls the listening sockets and up to FS_MAX_CLIENTS clients
 * and serves one request at a time: a render request takes a snapshot of the
 * emulated rig (sim_emu_snapshot), renders (sim_render) and sends the header line
 * and the bytes before the next request is read. Clients' sends are bounded by
 * SO_SNDTIMEO so a stuck client cannot hold the server. Camera faults (dropped
 * frames, disconnects) and frame counters belong to this thread alone. */
#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <jansson.h>

#include "common/clock.h"
#include "common/log.h"
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
};

struct cam_faults {
        long drop, disconnect; /* render requests still to fail that way */
};

struct sim_frame_server {
        struct rig_config *rc;
        struct sim_scene *scene;
        struct sim_emu *emu;
        int listen[RIG_MAX_BUSES];
        const char *paths[RIG_MAX_BUSES];
        size_t n_listen;
        struct fs_client clients[FS_MAX_CLIENTS];
        struct cam_faults faults[RIG_MAX_CAMERAS];
        uint64_t seq[RIG_MAX_CAMERAS];
        atomic_bool stop;
        pthread_t thread;
        bool started;
};

/* One request being served. */
struct fs_req {
        struct sim_frame_server *fs;
        struct fs_client *cl;
        json_t *req;
        char msg[256]; /* message of an error reply */
        bool hangup;   /* close the connection instead of replying */
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

/* Records an error reply; returns -err. */
static int fail(struct fs_req *rq, int err, const char *fmt, ...) _printf_(3, 4);
static int fail(struct fs_req *rq, int err, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(rq->msg, sizeof rq->msg, fmt, ap);
        va_end(ap);
        return -err;
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
                return fail(rq, ENOMEM, "out of memory");
        size_t n = strlen(s);
        int r = send_bytes(rq, s, n);
        if (r >= 0)
                r = send_bytes(rq, "\n", 1);
        free(s);
        return r;
}

static int send_ok(struct fs_req *rq)
{
        return send_json(rq, json_pack("{s:b}", "ok", 1));
}

static void send_error(struct fs_req *rq, int r)
{
        const char *name = strerrorname_np(-r);

        (void)send_json(rq, json_pack("{s:b, s:s, s:s}", "ok", 0, "error", name ? name : "EIO",
                                      "message", rq->msg[0] ? rq->msg : strerror(-r)));
}

/* ---- request fields ---- */

/* Reads optional integer key into *out (kept when absent). */
static int opt_int(struct fs_req *rq, const char *key, long min, long max, long *out)
{
        json_t *v = json_object_get(rq->req, key);

        if (!v)
                return 0;
        if (!json_is_integer(v) || json_integer_value(v) < min || json_integer_value(v) > max)
                return fail(rq, EINVAL, "'%s' must be an integer in [%ld, %ld]", key, min, max);
        *out = (long)json_integer_value(v);
        return 1;
}

static int opt_num(struct fs_req *rq, const char *key, double min, double max, double *out)
{
        json_t *v = json_object_get(rq->req, key);

        if (!v)
                return 0;
        if (!json_is_number(v) || json_number_value(v) < min || json_number_value(v) > max)
                return fail(rq, EINVAL, "'%s' must be a number in [%g, %g]", key, min, max);
        *out = json_number_value(v);
        return 1;
}

static int opt_bool(struct fs_req *rq, const char *key, bool *out)
{
        json_t *v = json_object_get(rq->req, key);

        if (!v)
                return 0;
        if (!json_is_boolean(v))
                return fail(rq, EINVAL, "'%s' must be true or false", key);
        *out = json_is_true(v);
        return 1;
}

/* The index of the camera named by the request's "camera" field. */
static int camera_arg(struct fs_req *rq, int *ci)
{
        const struct rig_config *rc = rq->fs->rc;
        const char *name = json_string_value(json_object_get(rq->req, "camera"));

        if (!name)
                return fail(rq, EINVAL, "'camera' must be a camera name");
        for (size_t i = 0; i < rc->n_cameras; i++)
                if (strcmp(rc->cameras[i].name, name) == 0) {
                        *ci = (int)i;
                        return 0;
                }
        return fail(rq, ENOENT, "no camera '%s' in the rig", name);
}

static int truth_arg(struct fs_req *rq, unsigned *flags)
{
        json_t *list = json_object_get(rq->req, "truth"), *v;
        size_t i, k;

        if (list && !json_is_array(list))
                return fail(rq, EINVAL, "'truth' must be a list of names");
        json_array_foreach(list, i, v)
        {
                const char *name = json_string_value(v);
                for (k = 0; name && k < ELEMENTSOF(truths); k++)
                        if (strcmp(name, truths[k].name) == 0)
                                break;
                if (!name || k == ELEMENTSOF(truths))
                        return fail(rq, EINVAL, "'truth' names are depth, normal, point, lamp");
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

        if ((r = opt_int(rq, "exposure_us", 0, 100000000, &exp)) < 0 ||
            (r = opt_num(rq, "gain", 0.0, 1000.0, &ex->gain)) < 0 ||
            (r = opt_int(rq, "bits", 0, 16, &bits)) < 0 ||
            (r = opt_bool(rq, "no_noise", &ex->no_noise)) < 0)
                return r;
        if (bits != 0 && bits != 8 && bits != 16)
                return fail(rq, EINVAL, "'bits' must be 8 or 16");
        ex->exposure_us = exp ? (int)exp : c->exposure_us;
        ex->gain = ex->gain > 0.0 ? ex->gain : c->gain;
        ex->bits = bits ? (int)bits : c->bits;
        return 0;
}

/* ---- JSON of the rig ---- */

static json_t *reals(const double *v, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                if (json_array_append_new(a, json_real(v[i])) < 0) {
                        json_decref(a);
                        return NULL;
                }
        return a;
}

static bool lamp_lit(const struct gn_pose *st, size_t i)
{
        return i < GN_POSE_MAX_LAMPS && (st->lamps & (UINT32_C(1) << i));
}

/* {"turntable": deg or null, "light_arm": ..., "camera_arm": ..., "lamps": [bool], "laser": b} */
static json_t *state_json(const struct rig_config *rc, const struct gn_pose *st)
{
        json_t *o = json_pack("{s:o, s:b}", "lamps", json_array(), "laser", st->laser);
        json_t *lamps = json_object_get(o, "lamps");

        for (size_t i = 0; lamps && i < rc->n_lamps; i++)
                if (json_array_append_new(lamps, json_boolean(lamp_lit(st, i))) < 0)
                        json_decref(TAKE_PTR(o));
        for (int i = 0; o && i < GN_ROLE_COUNT; i++)
                if (json_object_set_new(o, gn_role_name(i),
                                        gn_pose_has(st, i) ? json_real(st->deg[i]) : json_null()) <
                    0)
                        json_decref(TAKE_PTR(o));
        return o;
}

static json_t *camera_json(struct sim_frame_server *fs, const struct gn_pose *st, int ci)
{
        struct sim_cam_geom g;

        if (sim_camera_geom(fs->scene, st, ci, &g) < 0)
                return NULL;
        return json_pack("{s:s, s:i, s:i, s:f, s:f, s:f, s:f, s:o, s:o, s:o}", "name",
                         fs->rc->cameras[ci].name, "width", g.width, "height", g.height, "fx", g.fx,
                         "fy", g.fy, "cx", g.cx, "cy", g.cy, "dist", reals(g.dist, 5), "R",
                         reals(g.R, 9), "t", reals(g.t, 3));
}

static json_t *lamp_json(struct sim_frame_server *fs, const struct gn_pose *st, int i)
{
        double p[3];

        if (sim_lamp_position(fs->scene, st, i, p) < 0)
                return NULL;
        return json_pack("{s:s, s:o, s:b}", "name", fs->rc->lamps[i].name, "position", reals(p, 3),
                         "on", lamp_lit(st, (size_t)i));
}

static json_t *laser_json(struct sim_frame_server *fs, const struct gn_pose *st)
{
        double n[3], d;

        if (!fs->rc->has_laser || sim_laser_plane(fs->scene, n, &d) < 0)
                return json_null();
        return json_pack("{s:o, s:f, s:b}", "n", reals(n, 3), "d", d, "on", st->laser);
}

/* ---- commands ---- */

static int do_state(struct fs_req *rq)
{
        struct gn_pose st;

        sim_emu_snapshot(rq->fs->emu, &st);
        return send_json(rq,
                         json_pack("{s:b, s:o}", "ok", 1, "state", state_json(rq->fs->rc, &st)));
}

static int do_geometry(struct fs_req *rq)
{
        struct sim_frame_server *fs = rq->fs;
        struct gn_pose st;
        json_t *cams = json_array(), *lamps = json_array();
        int r = 0;

        sim_emu_snapshot(fs->emu, &st);
        for (size_t i = 0; r >= 0 && i < fs->rc->n_cameras; i++)
                r = json_array_append_new(cams, camera_json(fs, &st, (int)i));
        for (size_t i = 0; r >= 0 && i < fs->rc->n_lamps; i++)
                r = json_array_append_new(lamps, lamp_json(fs, &st, (int)i));
        if (r < 0) {
                json_decref(cams);
                json_decref(lamps);
                return fail(rq, EIO, "geometry of the scene unavailable");
        }
        return send_json(rq, json_pack("{s:b, s:o, s:o, s:o, s:o}", "ok", 1, "state",
                                       state_json(fs->rc, &st), "cameras", cams, "lamps", lamps,
                                       "laser", laser_json(fs, &st)));
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

static int send_frame(struct fs_req *rq, int ci, const struct gn_pose *st,
                      const struct sim_expose *ex, const struct gn_frame *f,
                      const struct sim_truth *t, unsigned flags)
{
        size_t pixels = (size_t)f->width * (size_t)f->height;
        json_t *h = json_pack(
                "{s:b, s:s, s:I, s:I, s:i, s:i, s:i, s:i, s:I, s:I, s:i, s:f, s:o, s:o}", "ok", 1,
                "camera", rq->fs->rc->cameras[ci].name, "seq", (json_int_t)f->seq, "timestamp_ns",
                (json_int_t)f->timestamp_ns, "width", f->width, "height", f->height, "channels",
                f->channels, "bits", f->bits, "stride", (json_int_t)f->stride, "bytes",
                (json_int_t)gn_frame_bytes(f), "exposure_us", ex->exposure_us, "gain", ex->gain,
                "state", state_json(rq->fs->rc, st), "truth", truth_list(t, flags, pixels));

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

/* Applies a pending camera fault to this render request. */
static int camera_fault(struct fs_req *rq, int ci)
{
        struct cam_faults *cf = &rq->fs->faults[ci];

        if (cf->disconnect > 0) {
                cf->disconnect--;
                rq->hangup = true;
                return -ECONNABORTED;
        }
        if (cf->drop > 0) {
                cf->drop--;
                return fail(rq, ETIMEDOUT, "frame dropped (injected fault)");
        }
        return 0;
}

static int do_render(struct fs_req *rq)
{
        struct sim_frame_server *fs = rq->fs;
        struct sim_expose ex = {0};
        struct gn_pose st;
        struct gn_frame f = {0};
        struct sim_truth t = {0};
        unsigned flags = 0;
        int ci = 0;

        int r = camera_arg(rq, &ci);
        if (r >= 0)
                r = expose_args(rq, ci, &ex);
        if (r >= 0)
                r = truth_arg(rq, &flags);
        if (r >= 0)
                r = camera_fault(rq, ci);
        if (r < 0)
                return r;

        sim_emu_snapshot(fs->emu, &st);
        uint64_t seq = fs->seq[ci]++, ts = gn_realtime_ns();
        r = sim_render(fs->scene, &st, ci, &ex, seq, &f, flags, &t);
        if (r < 0)
                return fail(rq, -r, "rendering failed: %s", strerror(-r));
        f.seq = seq;
        f.timestamp_ns = ts;
        r = send_frame(rq, ci, &st, &ex, &f, &t, flags);
        gn_frame_free_data(&f);
        sim_truth_free(&t);
        return r;
}

static int inject_camera(struct fs_req *rq, const char *fault)
{
        long count = 1;
        int ci = 0;

        int r = camera_arg(rq, &ci);
        if (r >= 0)
                r = opt_int(rq, "count", 0, 1000000, &count);
        if (r < 0)
                return r;
        struct cam_faults *cf = &rq->fs->faults[ci];
        if (strcmp(fault, "drop") == 0)
                cf->drop = count;
        else if (strcmp(fault, "disconnect") == 0)
                cf->disconnect = count;
        else if (strcmp(fault, "none") == 0)
                *cf = (struct cam_faults){0};
        else
                return fail(rq, EINVAL, "camera faults are drop, disconnect, none");
        return 0;
}

static int inject_modbus(struct fs_req *rq, const char *fault)
{
        static const char *const names[] = {
                [SIM_FAULT_NONE] = "none",   [SIM_FAULT_TIMEOUT] = "timeout",
                [SIM_FAULT_CRC] = "crc",     [SIM_FAULT_EXCEPTION] = "exception",
                [SIM_FAULT_STALL] = "stall", [SIM_FAULT_SHORT] = "short",
        };
        const char *bus = json_string_value(json_object_get(rq->req, "bus"));
        long unit = -1;
        size_t f;

        int r = opt_int(rq, "unit", 0, 255, &unit);
        if (r < 0)
                return r;
        if (!bus || unit < 0)
                return fail(rq, EINVAL, "inject needs 'camera', or 'bus' and 'unit'");
        for (f = 0; f < ELEMENTSOF(names) && strcmp(names[f], fault) != 0; f++)
                ;
        if (f == ELEMENTSOF(names))
                return fail(rq, EINVAL,
                            "Modbus faults are none, timeout, crc, exception, stall, short");
        r = sim_emu_inject(rq->fs->emu, bus, (int)unit, (enum sim_fault)f);
        if (r == -ENOENT)
                return fail(rq, ENOENT, "no emulated device at bus '%s' unit %ld", bus, unit);
        if (r < 0)
                return fail(rq, -r, "bus '%s' unit %ld is no axis drive", bus, unit);
        return 0;
}

static int do_inject(struct fs_req *rq)
{
        const char *fault = json_string_value(json_object_get(rq->req, "fault"));

        if (!fault)
                return fail(rq, EINVAL, "'fault' must be a string");
        int r = json_object_get(rq->req, "camera") ? inject_camera(rq, fault)
                                                   : inject_modbus(rq, fault);
        return r < 0 ? r : send_ok(rq);
}

/* ---- connections ---- */

static void handle_line(struct sim_frame_server *fs, struct fs_client *cl, const char *line,
                        size_t len)
{
        static const struct {
                const char *name;
                int (*fn)(struct fs_req *rq);
        } cmds[] = {
                {"render", do_render},
                {"state", do_state},
                {"geometry", do_geometry},
                {"inject", do_inject},
        };
        struct fs_req rq = {.fs = fs, .cl = cl};
        json_error_t jerr;
        int r;

        rq.req = json_loadb(line, len, 0, &jerr);
        const char *cmd = json_string_value(json_object_get(rq.req, "cmd"));
        if (!rq.req)
                r = fail(&rq, EINVAL, "malformed JSON: %s", jerr.text);
        else if (!cmd)
                r = fail(&rq, EINVAL, "a request is an object with a string 'cmd'");
        else {
                size_t i;
                for (i = 0; i < ELEMENTSOF(cmds) && strcmp(cmds[i].name, cmd) != 0; i++)
                        ;
                r = i < ELEMENTSOF(cmds) ? cmds[i].fn(&rq)
                                         : fail(&rq, EINVAL, "unknown cmd '%s'", cmd);
        }
        if (r < 0 && !rq.hangup)
                send_error(&rq, r);
        json_decref(rq.req);
        if (rq.hangup)
                client_close(cl);
}

/* A line filled the buffer without a newline: one error reply, then the rest of it
 * up to the next newline is dropped. */
static void overlong_line(struct sim_frame_server *fs, struct fs_client *cl)
{
        struct fs_req rq = {.fs = fs, .cl = cl};

        if (!cl->overlong) {
                send_error(&rq, fail(&rq, EMSGSIZE, "request line longer than %d bytes",
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

static void accept_client(struct sim_frame_server *fs, int lfd)
{
        struct timeval tv = {.tv_sec = FS_SEND_TIMEOUT};
        int fd = accept4(lfd, NULL, NULL, SOCK_CLOEXEC);

        if (fd < 0)
                return;
        (void)setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
        for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                if (fs->clients[i].fd < 0) {
                        fs->clients[i].fd = fd;
                        return;
                }
        struct fs_client tmp = {.fd = fd};
        struct fs_req rq = {.fs = fs, .cl = &tmp};
        send_error(&rq, fail(&rq, EBUSY, "more than %d clients", FS_MAX_CLIENTS));
        close(fd);
}

static void *server_thread(void *userdata)
{
        struct sim_frame_server *fs = userdata;
        struct pollfd p[RIG_MAX_BUSES + FS_MAX_CLIENTS];

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
                                accept_client(fs, fs->listen[i]);
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

static int listen_on(struct sim_frame_server *fs, const char *path)
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
        fs->listen[fs->n_listen++] = TAKE_FD(fd);
        if (listen(fs->listen[fs->n_listen - 1], FS_MAX_CLIENTS) < 0)
                return log_error_errno(errno, "frame socket %s: %m", path);
        return 0;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_frame_server *, sim_frame_server_free);

int sim_frame_server_new(struct rig_config *rc, struct sim_scene *scene, struct sim_emu *emu,
                         struct sim_frame_server **ret)
{
        if (!rc || !scene || !emu || !ret)
                return -EINVAL;

        _cleanup_(sim_frame_server_freep) struct sim_frame_server *fs = calloc(1, sizeof *fs);
        if (!fs)
                return -ENOMEM;
        *fs = (struct sim_frame_server){.rc = rc, .scene = scene, .emu = emu};
        for (size_t i = 0; i < FS_MAX_CLIENTS; i++)
                fs->clients[i].fd = -1;
        for (size_t i = 0; i < rc->n_buses; i++) {
                if (rc->buses[i].type != RIG_BUS_SIM)
                        continue;
                int r = listen_on(fs, rc->buses[i].port);
                if (r < 0)
                        return r;
        }
        if (fs->n_listen == 0)
                return log_error_errno(SYNTHETIC_ERRNO(ENOENT), "the rig has no bus of type sim");
        int r = -pthread_create(&fs->thread, NULL, server_thread, fs);
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
        free(fs);
        return NULL;
}
