/* test-session-faults.c - sessions under adverse conditions, end to end (issue 8): a full
 * disk (ENOSPC) pauses the session with its cause and it resumes once space is freed; the
 * timing model's estimate matches a run at the simulator's real speed; a client that never
 * reads and 100 watching clients neither stall the session nor starve each other; abort
 * stops motion and leaves a consistent dataset; a paused session survives kill -9 of goniod;
 * sessions aborted the moment they run, many times, each end recorded (run-abort); SIGTERM
 * at any moment of a session, many times, ends goniod with status 0 and the laser and the
 * lamps off (sigterm), and as soon as it answers, while it starts (sigterm-start); drive faults
 * cleared and resumed at once, again and again, never leave the session waiting for nothing
 * (fault-resume). One case per run: goniod gonioctl gonio-sim CASE. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/pose.h"
#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "harness.h"
#include "tests/test.h"

/* 4 turntable x 2 light-arm positions x (2 lamps + laser) x 2 cameras + a dark per camera:
 * 50 captures (checked against session.plan). */
static const char *const session_text = "sweep:\n"
                                        "  turntable: { from: 0, to: 270, step: 90 }\n"
                                        "  light_arm: [0, 120]\n"
                                        "cameras: [cam0, cam1]\n"
                                        "lamps: [lamp0, lamp1]\n"
                                        "laser: true\n"
                                        "dark_frames: 1\n"
                                        "skip_occluded: false\n"
                                        "skip_glare: false\n";

/* Writes session body as DIR/NAME.yaml with its name and dataset; returns its path. */
static const char *write_session(struct rigenv *e, const char *name, const char *dataset,
                                 const char *body, char *path, size_t len)
{
        char text[2048], base[64];

        snprintf(text, sizeof(text), "name: %s\ndataset: %s\n%s", name, dataset, body);
        snprintf(base, sizeof(base), "%s.yaml", name);
        return sess_write(e, base, text, path, len);
}

/* gonio-sim's actual state (angles, lamps, laser). */
static json_t *sim_state(struct rigenv *e)
{
        json_t *r = sim_query(e, "{\"cmd\":\"state\"}\n");
        json_t *st = json_incref(json_object_get(r, "state"));

        json_decref(r);
        return st;
}

/* The rig is safe as gonio-sim sees it: every lamp and the laser off, no angle changing over
 * 300 ms; and goniod reports no axis moving. */
static void check_safe(struct rigenv *e)
{
        json_t *a = sim_state(e), *b, *v, *st;
        size_t i;

        usleep(300000);
        b = sim_state(e);
        json_array_foreach(json_object_get(b, "lamps"), i, v) CHECK(!json_is_true(v));
        CHECK(!json_is_true(json_object_get(b, "laser")));
        for (int r = 0; r < GN_ROLE_COUNT; r++) {
                json_t *x = json_object_get(a, gn_role_name(r)),
                       *y = json_object_get(b, gn_role_name(r));
                if (json_is_number(x))
                        CHECK_NEAR(json_number_value(y), json_number_value(x), 1e-6);
        }
        st = ctl_ok(e, "status", NULL);
        json_array_foreach(json_object_get(st, "axes"), i, v)
                CHECK(!json_is_true(json_object_get(v, "moving")));
        json_decref(st);
        json_decref(a);
        json_decref(b);
}

/* ---- enospc ---- */

/* Every file of the dataset's images/ has its row and no other file is there: ds_check on a
 * dataset goniod holds open takes an image past the last row for a store in flight. */
static void check_no_orphan(struct rigenv *e, const char *dataset)
{
        char path[400];
        struct dirent *de;
        struct ds *d = NULL;
        int64_t files = 0;
        DIR *dir;

        snprintf(path, sizeof(path), "%s/%s/images", e->data, dataset);
        dir = opendir(path);
        CHECK(dir);
        while ((de = readdir(dir)))
                files += de->d_name[0] != '.';
        closedir(dir);
        snprintf(path, sizeof(path), "%s/%s", e->data, dataset);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(files, ds_count(d));
        ds_close(d);
}

static char mounted[300]; /* the tmpfs to unmount (also when a check fails) */

static void unmount_data(void)
{
        char cmd[400];

        snprintf(cmd, sizeof(cmd), "umount -l %s", mounted);
        if (mounted[0] && system(cmd) != 0)
                fprintf(stderr, "cannot unmount %s\n", mounted);
}

/* Fills the file system of dir up to about room free bytes with dir/filler. */
static void fill_disk(const char *dir, long room)
{
        char path[400];
        struct statvfs sv;
        long free_b;
        int fd;

        CHECK(statvfs(dir, &sv) == 0);
        free_b = (long)(sv.f_bavail * sv.f_frsize);
        CHECK(free_b > room);
        snprintf(path, sizeof(path), "%s/filler", dir);
        fd = open(path, O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
        CHECK(fd >= 0);
        CHECK(posix_fallocate(fd, 0, free_b - room) == 0);
        close(fd);
}

/* A session into a small tmpfs pauses with the disk as cause, the rig safe and the dataset
 * consistent; once the filler is removed, resume completes it. Needs root for the tmpfs:
 * returns TEST_SKIP without, else 0. */
static int test_enospc(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char cmd[700], file[400];
        const char *reason;
        int64_t n;
        json_t *st;
        int r;

        snprintf(cmd, sizeof(cmd), "mkdir -p %s && mount -t tmpfs -o size=8m tmpfs %s", e->data,
                 e->data);
        if (system(cmd) != 0) {
                fprintf(stderr, "enospc case skipped: cannot mount a tmpfs\n");
                return TEST_SKIP;
        }
        snprintf(mounted, sizeof(mounted), "%s", e->data);
        atexit(unmount_data);
        write_session(e, "s1", "ds1", session_text, file, sizeof(file));
        n = sess_planned(e, file, NULL);
        fill_disk(e->data, 600 << 10); /* the index and a few images fit, not 50 images */
        r = ctl(e, NULL, "session", "run", file, NULL);
        st = ctl_ok(e, "session", "status", NULL);
        fprintf(stderr, "gonioctl session run: exit %d\n", r);
        print_json("then session.status", st);
        CHECK_INT(r, 7); /* paused: storage error */
        CHECK_STR(json_string_value(json_object_get(st, "state")), "paused");
        reason = json_string_value(json_object_get(st, "reason"));
        fprintf(stderr, "paused: %s\n", reason);
        CHECK(strstr(reason, "space") || strstr(reason, "ENOSPC") || strstr(reason, "full"));
        CHECK_INT(json_integer_value(json_object_get(st, "code")), -32006);
        CHECK(json_integer_value(json_object_get(st, "captured")) < n);
        json_decref(st);
        check_safe(e);
        CHECK_INT(sess_problems(e, "ds1"), 0); /* no torn file, counts right */
        check_no_orphan(e, "ds1");
        sess_info(e, "ds1", "s1", &info);
        CHECK_STR(info.state, "paused");
        ds_session_info_clear(&info);
        snprintf(cmd, sizeof(cmd), "%s/filler", e->data);
        CHECK(unlink(cmd) == 0);
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        sess_check_complete(e, "ds1", "s1", n);
        unmount_data();
        mounted[0] = 0;
        return 0;
}

/* ---- estimate ---- */

/* Motion dominates: 7 moves of 40 to 120 degrees, 8 captures of 160 x 120. */
static const char *const motion_text = "sweep:\n"
                                       "  turntable: { from: 0, to: 180, step: 60 }\n"
                                       "  camera_arm: [0, 40]\n"
                                       "cameras: [cam0]\n"
                                       "lamps: [lamp0]\n"
                                       "skip_occluded: false\n"
                                       "skip_glare: false\n";

/* Runs file from a homed rig and returns its wall time: from session.run answered (the
 * session runs) to the session.state notification of its end. */
static double timed_run(struct rigenv *e, const char *file)
{
        double t0;
        json_t *end;
        int fd;

        fd = sess_start_raw(e, file);
        t0 = now_s();
        end = raw_wait_note(fd, "session.state", "none", 120);
        CHECK_STR(json_string_value(json_object_get(end, "ended")), "done");
        json_decref(end);
        close(fd);
        return now_s() - t0;
}

/* At time scale 1 the run takes session.plan's estimate, within 10%. */
static void test_estimate(struct rigenv *e)
{
        char file[400];
        double est, wall;
        int64_t n;

        json_decref(ctl_ok(e, "home", NULL));
        write_session(e, "est", "est", motion_text, file, sizeof(file));
        n = sess_planned(e, file, &est);
        wall = timed_run(e, file);
        fprintf(stderr, "estimate %.3f s, run %.3f s (%+.1f%%)\n", est, wall,
                100 * (wall - est) / est);
        sess_check_complete(e, "est", "est", n);
        CHECK(fabs(wall - est) <= 0.1 * est);
}

/* ---- noread ---- */

#define WATCHERS 100

/* A connection that reads everything, counting notifications as they come. */
struct watcher {
        int fd;
        char buf[1 << 16];
        size_t len, bytes;
        int progress, progress_at_drop;
        bool ended;
};

static const char hello[] =
        "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"hello\",\"params\":{\"client\":\"e2e\","
        "\"protocol\":1}}\n";

static void watcher_line(struct watcher *w, const char *line)
{
        json_t *msg, *params;
        const char *st;

        if (strstr(line, "\"session.progress\""))
                w->progress++;
        if (!strstr(line, "\"session.state\""))
                return;
        msg = json_loads(line, 0, NULL);
        CHECK(msg);
        params = json_object_get(msg, "params");
        st = json_string_value(json_object_get(params, "state"));
        w->ended |= st && strcmp(st, "none") == 0;
        json_decref(msg);
}

/* Reads what w has and handles each whole line. */
static void watcher_read(struct watcher *w)
{
        ssize_t n = read(w->fd, w->buf + w->len, sizeof(w->buf) - 1 - w->len);
        char *line = w->buf, *nl;

        CHECK(n > 0);
        w->bytes += n;
        w->len += n;
        w->buf[w->len] = 0;
        while ((nl = strchr(line, '\n'))) {
                *nl = 0;
                watcher_line(w, line);
                line = nl + 1;
        }
        w->len -= line - w->buf;
        memmove(w->buf, line, w->len + 1);
}

static bool all_ended(const struct watcher *w)
{
        for (int i = 0; i < WATCHERS; i++)
                if (!w[i].ended)
                        return false;
        return true;
}

/* Reads what the watchers have, waiting up to 20 ms. */
static void watchers_read(struct watcher *w)
{
        struct pollfd p[WATCHERS];

        for (int i = 0; i < WATCHERS; i++)
                p[i] = (struct pollfd){.fd = w[i].fd, .events = POLLIN};
        CHECK(poll(p, WATCHERS, 20) >= 0);
        for (int i = 0; i < WATCHERS; i++)
                if (p[i].revents)
                        watcher_read(&w[i]);
}

/* Sends status requests to fd without reading the replies, as many as the socket takes.
 * Returns false once goniod has closed the connection. */
static bool flood(int fd)
{
        static const char req[] = "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"status\"}\n";

        for (int i = 0; i < 256; i++) {
                ssize_t n = send(fd, req, sizeof(req) - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
                if (n < 0 && (errno == EPIPE || errno == ECONNRESET))
                        return false;
                if (n < 0) {
                        CHECK(errno == EAGAIN);
                        break;
                }
        }
        return true;
}

/* Runs file with 100 watchers and a client that never reads; returns the wall time from
 * session.run answered to the end. */
static double crowded_run(struct rigenv *e, const char *file, struct watcher *w)
{
        int quiet = raw_connect(e), fd;
        bool dropped = false;
        double t0, t_end = 0, t_drop = 0;

        CHECK(quiet >= 0 && write(quiet, hello, strlen(hello)) == (ssize_t)strlen(hello));
        for (int i = 0; i < WATCHERS; i++) {
                w[i].fd = raw_connect(e);
                CHECK(w[i].fd >= 0 &&
                      write(w[i].fd, hello, strlen(hello)) == (ssize_t)strlen(hello));
        }
        fd = sess_start_raw(e, file);
        t0 = now_s();
        while (!all_ended(w)) {
                CHECK(now_s() - t0 < 120);
                if (!dropped && !flood(quiet)) {
                        dropped = true;
                        t_drop = now_s() - t0;
                        for (int i = 0; i < WATCHERS; i++)
                                w[i].progress_at_drop = w[i].progress;
                }
                watchers_read(w);
                if (!t_end && w[0].ended)
                        t_end = now_s() - t0;
        }
        fprintf(stderr,
                "the client that never reads was dropped after %.2f s; a watcher received %zu "
                "bytes of notifications in %.2f s\n",
                t_drop, w[0].bytes, t_end);
        CHECK(dropped);
        close(quiet);
        close(fd);
        return t_end;
}

/* A session with 100 watchers and a client that never reads (flooding requests): it ends
 * at the pace of a run without them (< 2x: a benchmark measures it precisely), the silent
 * client is dropped, and every watcher receives progress after that and the end. */
static void test_noread(struct rigenv *e)
{
        static struct watcher w[WATCHERS];
        char file[400];
        double alone, crowded;
        int64_t n;

        write_session(e, "s1", "ds1", session_text, file, sizeof(file));
        n = sess_planned(e, file, NULL);
        json_decref(ctl_ok(e, "home", NULL));
        alone = timed_run(e, file);
        sess_check_complete(e, "ds1", "s1", n);
        json_decref(ctl_ok(e, "home", NULL));
        write_session(e, "s2", "ds2", session_text, file, sizeof(file));
        crowded = crowded_run(e, file, w);
        fprintf(stderr, "alone %.3f s, with %d watchers and a client that never reads %.3f s\n",
                alone, WATCHERS, crowded);
        for (int i = 0; i < WATCHERS; i++) {
                CHECK(w[i].ended);
                CHECK(w[i].progress > w[i].progress_at_drop);
                close(w[i].fd);
        }
        sess_check_complete(e, "ds2", "s2", n);
        CHECK(crowded < 2 * alone);
}

/* ---- abort ---- */

/* Long turntable moves at time scale 1: 120 degrees take about 1.8 s. */
static const char *const turn_text = "sweep:\n"
                                     "  turntable: [0, 120, 240]\n"
                                     "cameras: [cam0]\n"
                                     "lamps: [lamp0]\n"
                                     "skip_occluded: false\n"
                                     "skip_glare: false\n";

static const double turn_angles[] = {0, 120, 240};

/* Degrees from angle to the nearest of the session's turntable angles. */
static double off_sweep(double angle)
{
        double d = 360;

        for (size_t i = 0; i < sizeof(turn_angles) / sizeof(turn_angles[0]); i++)
                d = fmin(d, gn_angle_distance(angle, turn_angles[i]));
        return d;
}

/* The turntable's angle in goniod's status over fd, NAN when it is not moving. */
static double turntable_moving(int fd)
{
        json_t *r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"status\"}\n");
        json_t *ax = json_array_get(json_object_get(json_object_get(r, "result"), "axes"), 0);
        double a = json_is_true(json_object_get(ax, "moving"))
                           ? json_number_value(json_object_get(ax, "position"))
                           : NAN;

        json_decref(r);
        return a;
}

/* Abort in the middle of a move: the turntable stops short of its target, lamps and laser go
 * off, the session is recorded aborted with a consistent dataset, and there is nothing left
 * to resume. */
static void test_abort(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char file[400], err[1024];
        double a = NAN;
        json_t *r;
        int fd, ctl_fd = raw_connect(e);

        json_decref(ctl_ok(e, "home", NULL));
        write_session(e, "turn", "turn", turn_text, file, sizeof(file));
        fd = sess_start_raw(e, file);
        for (double t0 = now_s(); isnan(a) || off_sweep(a) < 30; usleep(2000)) {
                CHECK(now_s() - t0 < 30);
                a = turntable_moving(ctl_fd);
        }
        r = raw_call(ctl_fd, "{\"jsonrpc\":\"2.0\",\"id\":4,\"method\":\"session.abort\"}\n");
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        json_decref(raw_wait_note(fd, "session.state", "none", 10));
        check_safe(e);
        r = sim_state(e);
        a = json_number_value(json_object_get(r, "turntable"));
        fprintf(stderr, "aborted 30 deg or more into a move; the turntable stopped at %.2f deg\n",
                a);
        CHECK(off_sweep(a) > 5); /* stopped, not taken to its target */
        json_decref(r);
        sess_info(e, "turn", "turn", &info);
        CHECK_STR(info.state, "aborted");
        CHECK(info.captured < info.planned);
        ds_session_info_clear(&info);
        CHECK_INT(sess_problems(e, "turn"), 0);
        {
                char *argv[] = {(char *)e->gonioctl, "--socket", e->sock,
                                "session",           "resume",   NULL};
                CHECK_INT(run_capture(argv, NULL, 0, err, sizeof(err)), 6); /* not found */
                CHECK(strstr(err, "no unfinished session"));
        }
        close(fd);
        close(ctl_fd);
}

/* ---- restart-paused ---- */

/* A paused session survives kill -9 of goniod: resume without arguments finds and completes
 * it. */
static void test_restart_paused(struct rigenv *e)
{
        struct ds_session_info info = {0};
        char file[400], state[32];
        json_t *p;
        int64_t n;
        int fd;

        write_session(e, "s1", "ds1", session_text, file, sizeof(file));
        n = sess_planned(e, file, NULL);
        fd = sess_start_raw(e, file);
        p = raw_wait_note(fd, "session.progress", NULL, 30);
        json_decref(p);
        json_decref(ctl_ok(e, "session", "pause", NULL));
        sess_wait(e, "paused", 30);
        close(fd);
        rigenv_crash_daemon(e);
        CHECK_STR(sess_state(e, state, sizeof(state)), "none"); /* nothing in memory */
        sess_info(e, "ds1", "s1", &info);
        CHECK_STR(info.state, "paused");
        CHECK(info.captured > 0 && info.captured < n);
        ds_session_info_clear(&info);
        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        sess_check_complete(e, "ds1", "s1", n);
}

/* ---- run-abort and sigterm: many short sessions ---- */

/* Dark frames first (lamps and laser off, so the abort has nothing to switch off), then
 * lit shots. */
static const char *const dark_text = "sweep:\n"
                                     "  turntable: [0, 90]\n"
                                     "cameras: [cam0, cam1]\n"
                                     "lamps: [lamp0]\n"
                                     "laser: true\n"
                                     "dark_frames: 3\n"
                                     "skip_occluded: false\n"
                                     "skip_glare: false\n";

#define CYCLES_MAX    40 /* short sessions per case */
#define CYCLES_BUDGET 60 /* seconds: fewer cycles on a slow machine */

/* Session i of the case: named name-i, into dataset name-i; its file into path. */
static const char *cycle_session(struct rigenv *e, const char *name, int i, char *path, size_t len)
{
        char sname[32];

        snprintf(sname, sizeof(sname), "%s%d", name, i);
        return write_session(e, sname, sname, dark_text, path, len);
}

/* Each session is aborted as soon as it runs, while its first stores are in flight (the
 * last store's answer records the end): goniod survives every one and records it aborted,
 * with a consistent dataset. */
static void test_run_abort(struct rigenv *e)
{
        struct ds_session_info info = {0};
        double end = now_s() + CYCLES_BUDGET;
        char file[400], name[32];
        int i;

        for (i = 0; i < CYCLES_MAX && now_s() < end; i++) {
                int fd = sess_start_raw(e, cycle_session(e, "ra", i, file, sizeof(file)));
                json_t *r;

                usleep(rand() % 3000);
                r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"session.abort\"}\n");
                CHECK(json_object_get(r, "result"));
                json_decref(r);
                json_decref(raw_wait_note(fd, "session.state", "none", 20));
                close(fd);
                snprintf(name, sizeof(name), "ra%d", i);
                sess_info(e, name, name, &info);
                CHECK_STR(info.state, "aborted");
                ds_session_info_clear(&info);
                CHECK_INT(sess_problems(e, name), 0);
        }
        fprintf(stderr, "%d sessions aborted the moment they ran\n", i);
        CHECK(i >= 5);
}

/* SIGTERM at a random moment of a session (sent, loading, preparing, running, or pausing):
 * goniod exits with status 0 every time (rigenv_term_daemon) and gonio-sim has the laser and
 * every lamp off. */
static void test_sigterm(struct rigenv *e)
{
        static const char pause_req[] =
                "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"session.pause\"}\n";
        double end = now_s() + CYCLES_BUDGET;
        char file[400];
        int i;

        for (i = 0; i < CYCLES_MAX && now_s() < end; i++) {
                int fd = sess_send_run(e, cycle_session(e, "t", i, file, sizeof(file)));
                json_t *st, *v;
                size_t k;

                usleep(rand() % 400000);
                if (i % 3 == 2) /* pausing: the pause is in flight when the signal comes */
                        CHECK(write(fd, pause_req, strlen(pause_req)) ==
                              (ssize_t)strlen(pause_req));
                usleep(rand() % 20000);
                rigenv_term_daemon(e);
                close(fd);
                st = sim_state(e);
                CHECK(!json_is_true(json_object_get(st, "laser")));
                json_array_foreach(json_object_get(st, "lamps"), k, v) CHECK(!json_is_true(v));
                json_decref(st);
        }
        fprintf(stderr, "goniod stopped by SIGTERM %d times during a session\n", i);
        CHECK(i >= 5);
}

/* SIGTERM at every moment of goniod's start, 2 ms apart over 120 ms (it opens the devices,
 * running its loop, in that time): status 0, or the signal's default action before goniod
 * takes its signals, never a start ended half built with status 1. */
static void test_sigterm_start(struct rigenv *e)
{
        rigenv_term_starting(e, 60, 0.002);
}

/* ---- fault-resume ---- */

/* 12 turntable x 2 light-arm positions x 2 lamps, one camera: 48 shots. */
static const char *const resume_text = "sweep:\n"
                                       "  turntable: { from: 0, to: 330, step: 30 }\n"
                                       "  light_arm: [0, 10]\n"
                                       "cameras: [cam0]\n"
                                       "lamps: [lamp0, lamp1]\n"
                                       "skip_occluded: false\n"
                                       "skip_glare: false\n";

#define RESUME_CYCLES 8
#define STALL_S       10 /* seconds without a capture after a resume: stalled */

static const char resume_req[] = "{\"jsonrpc\":\"2.0\",\"id\":10,\"method\":\"session.resume\"}\n";

/* The session's state and capture count over fd. */
static int64_t raw_progress(int fd, char *state, size_t len)
{
        json_t *r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":7,\"method\":\"session.status\"}\n");
        json_t *st = json_object_get(r, "result");
        int64_t n = json_integer_value(json_object_get(st, "captured"));

        snprintf(state, len, "%s", json_string_value(json_object_get(st, "state")) ?: "");
        json_decref(r);
        return n;
}

/* Waits until the session has more than *got captures (or has ended), resuming it whenever it
 * is paused (a timeout under load); fails the test when nothing is captured for STALL_S s. */
static void wait_capture(int fd, int64_t *got, char *state, size_t len)
{
        for (double end = now_s() + STALL_S;; usleep(20000)) {
                int64_t n = raw_progress(fd, state, len);

                if (n > *got || strcmp(state, "none") == 0) {
                        *got = n;
                        return;
                }
                if (strcmp(state, "paused") == 0)
                        json_decref(raw_call(fd, resume_req));
                if (now_s() > end)
                        fprintf(stderr, "stalled: %s for %d s at %lld captures\n", state, STALL_S,
                                (long long)n);
                CHECK(now_s() <= end);
        }
}

/* Drive unit stops answering until goniod faults and answers again delay_us later, while the
 * safe state's stop of it may still be retried; fault.clear and session.resume go out at once
 * on one connection, the resume not waiting for the clear's answer. */
static void fault_and_resume(struct rigenv *e, int fd, int unit, int delay_us)
{
        static const char clear_req[] =
                "{\"jsonrpc\":\"2.0\",\"id\":9,\"method\":\"fault.clear\"}\n";
        char req[200], state[32] = "";
        json_t *r;

        for (int on = 1; on >= 0; on--) {
                snprintf(req, sizeof(req),
                         "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":%d,\"fault\":\"%s\"}\n",
                         unit, on ? "timeout" : "none");
                sim_request(e, req);
                for (double end = now_s() + 10; on && strcmp(state, "fault") != 0; usleep(5000)) {
                        r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":8,\"method\":\"status\"}\n");
                        snprintf(state, sizeof(state), "%s",
                                 json_string_value(
                                         json_object_get(json_object_get(r, "result"), "state"))
                                         ?: "");
                        json_decref(r);
                        CHECK(now_s() < end);
                }
                usleep(on ? delay_us : 0);
        }
        CHECK(write(fd, clear_req, strlen(clear_req)) == (ssize_t)strlen(clear_req));
        json_decref(raw_call(fd, resume_req)); /* the clear's answer, then the resume's */
        json_decref(raw_call(fd, ""));
}

/* A drive times out again and again during a session (the soak's faults, closer together):
 * each time the injection ends while the safe state's stop of that drive is retried, and
 * fault.clear and session.resume follow at once. The session captures again after every
 * resume (no wait without an end: it never stays running with nothing happening) and ends
 * with every capture once. */
static void test_fault_resume(struct rigenv *e)
{
        char file[400], state[32];
        int64_t n, got = 0;
        int fd, i;

        write_session(e, "fr", "fr", resume_text, file, sizeof(file));
        n = sess_planned(e, file, NULL);
        fd = sess_start_raw(e, file);
        for (i = 0; i < RESUME_CYCLES; i++) {
                wait_capture(fd, &got, state, sizeof(state));
                if (strcmp(state, "none") == 0)
                        break;
                fault_and_resume(e, fd, 1 + i % 2, (i * 7 % 6) * 60000);
        }
        fprintf(stderr, "%d drive faults cleared and resumed at once\n", i);
        while (strcmp(state, "none") != 0)
                wait_capture(fd, &got, state, sizeof(state));
        close(fd);
        sess_check_complete(e, "fr", "fr", n);
}

int main(int argc, char **argv)
{
        const char *c = argc == 5 ? argv[4] : "";
        struct rigenv e;
        int r = 0;

        /* goniod gonioctl gonio-sim CASE */
        CHECK(argc == 5);
        /* estimate and abort at the simulator's real speed; noread at 2 so that motion, not
         * the CPU, sets the pace */
        if (strcmp(c, "fault-resume") == 0) { /* one retry: a drive fault is found sooner */
                char *rig = rig_insert(NULL, "/drives\", ", "retries: 1, ");
                rigenv_start_rig(&e, argv, 10, rig);
                free(rig);
        } else
                rigenv_start(&e, argv,
                             strcmp(c, "estimate") == 0 || strcmp(c, "abort") == 0 ? 1
                             : strcmp(c, "noread") == 0                            ? 2
                                                                                   : 10);
        if (strcmp(c, "enospc") == 0)
                r = test_enospc(&e);
        else if (strcmp(c, "estimate") == 0)
                test_estimate(&e);
        else if (strcmp(c, "noread") == 0)
                test_noread(&e);
        else if (strcmp(c, "abort") == 0)
                test_abort(&e);
        else if (strcmp(c, "restart-paused") == 0)
                test_restart_paused(&e);
        else if (strcmp(c, "run-abort") == 0)
                test_run_abort(&e);
        else if (strcmp(c, "sigterm") == 0)
                test_sigterm(&e);
        else if (strcmp(c, "sigterm-start") == 0)
                test_sigterm_start(&e);
        else if (strcmp(c, "fault-resume") == 0)
                test_fault_resume(&e);
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return r;
}
