/* harness.c - process and socket helpers for gonio's end-to-end tests. */
#include <arpa/inet.h>
#include <inttypes.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "common/clock.h"
#include "common/pose.h"
#include "dataset/ds.h"
#include "dataset/ds_session.h"
#include "harness.h"
#include "tests/test.h"

static const char *const test_rig =
        "rig: e2e\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\", timeout_ms: 300 "
        "}\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\", timeout_ms: 300 "
        "}\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "  - { name: light_arm, modbus: { bus: drives, unit: 2 }, continuous: true,\n"
        "      max_speed: 60, accel: 120, settle_ms: 20 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3 }, limits: [-170, 170],\n"
        "      max_speed: 30, accel: 60, settle_ms: 20 }\n"
        "lamps:\n"
        "  - { name: lamp0, modbus-coil: { bus: relays, unit: 10, coil: 0 }, elevation: 20,\n"
        "      radius: 450, intensity: 2.0e6 }\n"
        "  - { name: lamp1, modbus-coil: { bus: relays, unit: 10, coil: 1 }, elevation: 60,\n"
        "      radius: 450, intensity: 2.0e6 }\n"
        /* one-shot `gonioctl laser on`: the tests check the laser after gonioctl left */
        "laser: { name: laser, off_on_disconnect: false, modbus-coil: { bus: relays, unit: 10, "
        "coil: 7 } }\n"
        "cameras:\n"
        "  - { name: cam0, sim: { bus: frames }, elevation: 15, distance: 600, azimuth: 30,\n"
        "      target: [0, 0, 40], width: 160, height: 120, fx: 400, fy: 400,\n"
        "      exposure_us: 20000 }\n"
        "  - { name: cam1, sim: { bus: frames }, elevation: 50, distance: 600, azimuth: 30,\n"
        "      target: [0, 0, 40], width: 160, height: 120, fx: 400, fy: 400,\n"
        "      exposure_us: 20000, bits: 16 }\n"
        "scene:\n"
        "  seed: 7\n"
        "  object:\n"
        "    shape: sphere\n"
        "    size: 60\n"
        "    pose: { translate: [50, 0, 30] }\n"
        "    material: { albedo: [0.7, 0.6, 0.5] }\n"
        "  turntable: { radius: 150, albedo: [0.3, 0.3, 0.3] }\n";

void write_file(const char *path, const char *text)
{
        FILE *f = fopen(path, "we");

        CHECK(f);
        CHECK(fputs(text, f) >= 0);
        CHECK(fclose(f) == 0);
}

double now_s(void)
{
        return (double)gn_monotonic_ns() * 1e-9;
}

/* Starts argv with stdout on a pipe (the read end in *out_fd) and stderr appended to
 * err_path (NULL: inherited). */
/* Every child spawn() started, for the exit handler. Kept here, not in the caller's
 * rigenv: a handler that read a struct on main's stack after main returned read garbage and
 * SIGKILLed whatever process had that number. */
static pid_t spawned[64];
static unsigned n_spawned;

/* A failed check exits the test: take the daemon and the simulator down with it. */
static void kill_children(void)
{
        for (unsigned i = 0; i < n_spawned && i < ELEMENTSOF(spawned); i++)
                kill_own_child(spawned[i]);
}

static void remember_child(pid_t pid)
{
        if (n_spawned == 0)
                atexit(kill_children);
        spawned[n_spawned++ % ELEMENTSOF(spawned)] = pid;
}

static pid_t spawn(char *const argv[], int *out_fd, const char *err_path)
{
        int p[2];
        pid_t pid;

        CHECK(pipe2(p, O_CLOEXEC) == 0);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                dup2(p[1], STDOUT_FILENO);
                if (err_path) {
                        int fd = open(err_path, O_WRONLY | O_CREAT | O_APPEND, 0644);
                        if (fd < 0 || dup2(fd, STDERR_FILENO) < 0)
                                _exit(127);
                }
                execv(argv[0], argv);
                _exit(127);
        }
        close(p[1]);
        remember_child(pid);
        *out_fd = p[0];
        return pid;
}

/* Reads the child's stdout until a line equal to word, within timeout seconds. */
static bool wait_word(int fd, const char *word, double timeout)
{
        char buf[8192];
        size_t len = 0;
        double end = now_s() + timeout;

        while (now_s() < end) {
                struct pollfd pfd = {.fd = fd, .events = POLLIN};
                ssize_t n;

                if (poll(&pfd, 1, 200) <= 0)
                        continue;
                n = read(fd, buf + len, sizeof(buf) - 1 - len);
                if (n <= 0)
                        return false;
                len += n;
                buf[len] = 0;
                if (strstr(buf, word))
                        return true;
                if (len > sizeof(buf) / 2)
                        memmove(buf, buf + len / 2, len - len / 2), len -= len / 2;
        }
        return false;
}

int tcp_connect(const char *ip, int port)
{
        struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};

        CHECK(inet_pton(AF_INET, ip, &sa.sin_addr) == 1);
        for (double end = now_s() + 10; now_s() < end; usleep(50000)) {
                int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
                CHECK(fd >= 0);
                if (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0)
                        return fd;
                close(fd);
        }
        CHECK(!"goniod does not listen on TCP");
        return -1;
}

void rigenv_make_certs(struct rigenv *e, const char *script, const char *san)
{
        char cmd[1000];
        int r;

        snprintf(cmd, sizeof(cmd), "%s %s %s", script, e->dir, san);
        r = system(cmd);
        if (WIFEXITED(r) && WEXITSTATUS(r) == TEST_SKIP)
                exit(TEST_SKIP); /* no openssl */
        CHECK(r == 0);
}

void enter_netns(const char *ip)
{
        char cmd[200];

        if (unshare(CLONE_NEWNET) < 0) {
                perror("unshare(CLONE_NEWNET), skipping");
                exit(TEST_SKIP);
        }
        snprintf(cmd, sizeof(cmd), "ip link set lo up && ip addr add %s/32 dev lo", ip);
        if (system(cmd) != 0) {
                fprintf(stderr, "cannot set up lo in the namespace, skipping\n");
                exit(TEST_SKIP);
        }
}

int raw_connect(struct rigenv *e)
{
        return test_unix_connect(e->sock);
}

void sim_request(struct rigenv *e, const char *json_line)
{
        json_decref(sim_query(e, json_line));
}

json_t *sim_query(struct rigenv *e, const char *json_line)
{
        char path[400], reply[4096];
        json_t *r;
        int fd;
        ssize_t n;

        snprintf(path, sizeof(path), "%s/control.sock", e->simdir);
        fd = test_unix_connect(path);
        CHECK(fd >= 0);
        CHECK(write(fd, json_line, strlen(json_line)) == (ssize_t)strlen(json_line));
        n = read(fd, reply, sizeof(reply) - 1);
        CHECK(n > 0);
        reply[n] = 0;
        r = json_loads(reply, 0, NULL);
        if (!json_is_true(json_object_get(r, "ok")))
                fprintf(stderr, "gonio-sim answered %s to %s", reply, json_line);
        CHECK(json_is_true(json_object_get(r, "ok")));
        close(fd);
        return r;
}

double sim_axis_deg(struct rigenv *e, const char *role)
{
        json_t *sim = sim_query(e, "{\"cmd\":\"state\"}\n");
        double deg = json_number_value(json_object_get(json_object_get(sim, "state"), role));

        json_decref(sim);
        return deg;
}

json_t *wait_state(struct rigenv *e, const char *want, double timeout)
{
        double end = now_s() + timeout;

        for (;;) {
                json_t *st = ctl_ok(e, "status", NULL);
                const char *s = json_string_value(json_object_get(st, "state"));
                if (s && strcmp(s, want) == 0)
                        return st;
                json_decref(st);
                CHECK(now_s() < end);
                usleep(50000);
        }
}

static void wait_socket(struct rigenv *e, double timeout)
{
        double end = now_s() + timeout;

        for (;;) {
                int fd = raw_connect(e);
                if (fd >= 0) {
                        close(fd);
                        return;
                }
                CHECK(now_s() < end);
                CHECK(waitpid(e->daemon, NULL, WNOHANG) == 0); /* daemon still alive */
                usleep(50000);
        }
}

static void start_daemon(struct rigenv *e)
{
        char *argv[] = {(char *)e->goniod, "--rig",  e->rig,  "--socket",
                        e->sock,           "--data", e->data, NULL};
        int fd;

        e->daemon = spawn(argv, &fd, e->daemon_log[0] ? e->daemon_log : NULL);
        close(fd);
        wait_socket(e, 30);
}

/* Starts gonio-sim on e's rig and directories and waits for "ready". */
static void start_sim(struct rigenv *e)
{
        char log[320];
        int fd;

        snprintf(log, sizeof(log), "%s/render.log", e->dir);
        e->sim = spawn((char *[]){(char *)e->gonio_sim, "--rig", e->rig, "--dir", e->simdir,
                                  "--time-scale", e->time_scale, "--render-log", log, NULL},
                       &fd, NULL);
        CHECK(wait_word(fd, "ready", 30));
        close(fd);
}

/* Sets e up for a rig in a new temp dir: paths, rig file, environment. */
static void init(struct rigenv *e, char **argv, double time_scale, const char *rig_text)
{
        memset(e, 0, sizeof(*e));
        e->goniod = argv[1];
        e->gonioctl = argv[2];
        e->gonio_sim = argv[3];
        snprintf(e->dir, sizeof(e->dir), "/tmp/gonio-e2e-XXXXXX");
        CHECK(mkdtemp(e->dir));
        snprintf(e->simdir, sizeof(e->simdir), "%s/sim", e->dir);
        snprintf(e->rig, sizeof(e->rig), "%s/rig.yaml", e->dir);
        snprintf(e->sock, sizeof(e->sock), "%s/goniod.sock", e->dir);
        snprintf(e->data, sizeof(e->data), "%s/data", e->dir);
        write_file(e->rig, rig_text ? rig_text : test_rig);
        setenv("GONIO_SIM_DIR", e->simdir, 1);
        snprintf(e->time_scale, sizeof(e->time_scale), "%g", time_scale);
}

/* from with the skip bytes at at replaced by text (at must not be NULL), malloc'ed. */
static char *rig_splice(const char *from, const char *at, size_t skip, const char *text)
{
        char *out;

        CHECK(at);
        CHECK(asprintf(&out, "%.*s%s%s", (int)(at - from), from, text, at + skip) > 0);
        return out;
}

char *rig_insert(const char *rig, const char *after, const char *text)
{
        const char *from = rig ? rig : test_rig, *at = strstr(from, after);

        return rig_splice(from, at ? at + strlen(after) : NULL, 0, text);
}

char *rig_replace(const char *rig, const char *old, const char *text)
{
        const char *from = rig ? rig : test_rig;

        return rig_splice(from, strstr(from, old), strlen(old), text);
}

void rigenv_start_rig(struct rigenv *e, char **argv, double time_scale, const char *rig_text)
{
        init(e, argv, time_scale, rig_text);
        start_sim(e);
        start_daemon(e);
}

void rigenv_start_sim(struct rigenv *e, char **argv, double time_scale)
{
        rigenv_start_sim_rig(e, argv, time_scale, NULL);
}

void rigenv_start_sim_rig(struct rigenv *e, char **argv, double time_scale, const char *rig_text)
{
        init(e, argv, time_scale, rig_text);
        start_sim(e);
}

void rigenv_spawn_daemon(struct rigenv *e, const char *socket, void (*setup)(void *ud), void *ud)
{
        char log[320];
        pid_t pid;

        snprintf(log, sizeof(log), "%s/goniod.log", e->dir);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                int fd = open(log, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
                if (fd < 0 || dup2(fd, STDERR_FILENO) < 0)
                        _exit(127);
                setup(ud);
                execv(e->goniod, (char *[]){(char *)e->goniod, "--rig", e->rig, "--socket",
                                            (char *)socket, "--data", e->data, NULL});
                _exit(127);
        }
        remember_child(pid);
        e->daemon = pid;
}

void rigenv_start_logged(struct rigenv *e, char **argv, double time_scale)
{
        init(e, argv, time_scale, NULL);
        snprintf(e->daemon_log, sizeof(e->daemon_log), "%s/goniod.log", e->dir);
        start_sim(e);
        start_daemon(e);
}

void rigenv_start(struct rigenv *e, char **argv, double time_scale)
{
        rigenv_start_rig(e, argv, time_scale, NULL);
}

void rigenv_crash_daemon(struct rigenv *e)
{
        CHECK(kill(e->daemon, SIGKILL) == 0);
        CHECK(waitpid(e->daemon, NULL, 0) == e->daemon);
        start_daemon(e);
}

void rigenv_crash_sim(struct rigenv *e)
{
        CHECK(kill(e->sim, SIGKILL) == 0);
        CHECK(waitpid(e->sim, NULL, 0) == e->sim);
        start_sim(e);
}

/* SIGTERMs pid and checks it exits cleanly (under ASan a leak makes the status non-zero). */
static void stop_pid(pid_t pid, const char *what)
{
        int status;

        if (pid <= 0)
                return;
        kill(pid, SIGTERM);
        for (int i = 0; i < 200; i++) {
                if (waitpid(pid, &status, WNOHANG) == pid) {
                        if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
                                fprintf(stderr, "%s exited with status 0x%x\n", what, status);
                        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
                        return;
                }
                usleep(50000);
        }
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        CHECK(!"did not stop within 10 s of SIGTERM");
}

void rigenv_term_daemon(struct rigenv *e)
{
        stop_pid(e->daemon, "goniod");
        start_daemon(e);
}

void rigenv_term_starting(struct rigenv *e, int n, double step_s)
{
        char *argv[] = {(char *)e->goniod, "--rig",  e->rig,  "--socket",
                        e->sock,           "--data", e->data, NULL};
        int fd, status;

        stop_pid(e->daemon, "goniod");
        for (int i = 0; i < n; i++) {
                pid_t pid = spawn(argv, &fd, NULL);
                close(fd);
                usleep((useconds_t)(i * step_s * 1e6));
                CHECK(kill(pid, SIGTERM) == 0);
                CHECK(waitpid(pid, &status, 0) == pid);
                if ((WIFEXITED(status) && WEXITSTATUS(status) == 0) ||
                    (WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM))
                        continue;
                fprintf(stderr, "goniod SIGTERMed %.0f ms after its start: status 0x%x\n",
                        i * step_s * 1e3, status);
                CHECK(!"goniod ended its start with an error");
        }
        start_daemon(e);
}

void rigenv_stop(struct rigenv *e)
{
        char cmd[400];

        stop_pid(e->daemon, "goniod");
        stop_pid(e->sim, "gonio-sim");
        snprintf(cmd, sizeof(cmd), "rm -rf '%s'", e->dir);
        CHECK(system(cmd) == 0);
}

int run_capture(char *const argv[], char *out, size_t outlen, char *err, size_t errlen)
{
        int po[2], pe[2], status;
        pid_t pid;

        CHECK(pipe2(po, O_CLOEXEC) == 0 && pipe2(pe, O_CLOEXEC) == 0);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                dup2(po[1], STDOUT_FILENO);
                dup2(pe[1], STDERR_FILENO);
                execv(argv[0], argv);
                _exit(127);
        }
        close(po[1]);
        close(pe[1]);
        for (int k = 0; k < 2; k++) {
                int fd = k ? pe[0] : po[0];
                char *buf = k ? err : out;
                size_t cap = k ? errlen : outlen, len = 0;
                char sink[4096];
                ssize_t n;

                while ((n = read(fd, buf ? buf + len : sink, buf ? cap - 1 - len : sizeof(sink))) >
                       0)
                        if (buf)
                                len += n;
                if (buf)
                        buf[len] = 0;
                close(fd);
        }
        CHECK(waitpid(pid, &status, 0) == pid);
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

static int vctl(struct rigenv *e, json_t **out, va_list ap)
{
        char *argv[32] = {(char *)e->gonioctl, "--socket", e->sock, "--json"};
        static char buf[1 << 20];
        char err[4096];
        int n = 4, r;
        const char *a;

        while ((a = va_arg(ap, const char *)) && n < 31)
                argv[n++] = (char *)a;
        argv[n] = NULL;
        r = run_capture(argv, buf, sizeof(buf), err, sizeof(err));
        if (err[0])
                fprintf(stderr, "gonioctl %s: %s", argv[4], err);
        if (out)
                *out = json_loads(buf, JSON_DECODE_ANY, NULL);
        return r;
}

int ctl(struct rigenv *e, json_t **out, ...)
{
        va_list ap;
        int r;

        va_start(ap, out);
        r = vctl(e, out, ap);
        va_end(ap);
        return r;
}

json_t *ctl_ok(struct rigenv *e, ...)
{
        json_t *out = NULL;
        va_list ap;
        int r;

        va_start(ap, e);
        r = vctl(e, &out, ap);
        va_end(ap);
        CHECK_INT(r, 0);
        CHECK(out != NULL);
        return out;
}

static char seen[8192]; /* methods of the notifications raw_call skipped */

static void note_seen(const char *method)
{
        size_t len = strlen(seen);

        if (method && len + strlen(method) + 2 < sizeof(seen))
                snprintf(seen + len, sizeof(seen) - len, "%s ", method);
}

const char *raw_seen(void)
{
        return seen;
}

/* Lines read past the message raw_next returned stay for the next call on the same fd. */
static struct {
        char buf[1 << 20];
        size_t len;
        int fd;
} raw = {.fd = -1};

/* The next message on fd, waiting up to timeout_ms for it (the test fails after). */
static json_t *raw_next(int fd, int timeout_ms)
{
        if (fd != raw.fd)
                raw.len = 0, raw.buf[0] = 0, raw.fd = fd;
        for (;;) {
                char *nl = strchr(raw.buf, '\n');
                struct pollfd pfd = {.fd = fd, .events = POLLIN};
                json_t *msg;
                ssize_t n;

                if (nl) {
                        *nl = 0;
                        msg = json_loads(raw.buf, 0, NULL);
                        memmove(raw.buf, nl + 1, raw.len - (nl + 1 - raw.buf) + 1);
                        raw.len = strlen(raw.buf);
                        CHECK(msg);
                        return msg;
                }
                CHECK(poll(&pfd, 1, timeout_ms) == 1);
                n = read(fd, raw.buf + raw.len, sizeof(raw.buf) - 1 - raw.len);
                CHECK(n > 0);
                raw.len += n;
                raw.buf[raw.len] = 0;
        }
}

json_t *raw_call(int fd, const char *text)
{
        if (fd != raw.fd)
                raw.len = 0, raw.buf[0] = 0, raw.fd = fd;
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        for (;;) {
                json_t *msg = raw_next(fd, 20000);

                if (json_object_get(msg, "id"))
                        return msg;
                note_seen(json_string_value(json_object_get(msg, "method")));
                json_decref(msg); /* a notification */
        }
}

json_t *raw_wait_note(int fd, const char *method, const char *state, double timeout)
{
        double end = now_s() + timeout;

        for (;;) {
                json_t *msg = raw_next(fd, (int)fmax(1, (end - now_s()) * 1000));
                json_t *params = json_object_get(msg, "params");
                const char *m = json_string_value(json_object_get(msg, "method"));
                const char *st = json_string_value(json_object_get(params, "state"));

                if (m && strcmp(m, method) == 0 && (!state || (st && strcmp(st, state) == 0))) {
                        json_incref(params);
                        json_decref(msg);
                        return params;
                }
                json_decref(msg);
                CHECK(now_s() < end);
        }
}

/* ---- rows against the render log ---- */

/* gonio-sim's render log as an object: each line under its "timestamp_ns" (the first line
 * of a timestamp wins), read once so that a check of n rows is not n passes over the log. */
static json_t *render_log(struct rigenv *e)
{
        char path[400], line[8192], key[32];
        json_t *log = json_object();
        FILE *f;

        snprintf(path, sizeof(path), "%s/render.log", e->dir);
        f = fopen(path, "re");
        CHECK(f && log);
        while (fgets(line, sizeof(line), f)) {
                json_t *j = json_loads(line, 0, NULL);
                CHECK(j);
                snprintf(key, sizeof(key), "%" JSON_INTEGER_FORMAT,
                         json_integer_value(json_object_get(j, "timestamp_ns")));
                if (!json_object_get(log, key))
                        CHECK_INT(json_object_set(log, key, j), 0);
                json_decref(j);
        }
        fclose(f);
        return log;
}

/* The render-log line of the frame gonio-sim rendered at timestamp ns, or NULL. */
static json_t *rendered(json_t *log, uint64_t ns)
{
        char key[32];

        snprintf(key, sizeof(key), "%" PRIu64, ns);
        return json_object_get(log, key);
}

/* The pose gonio-sim reports in a render-log state object (lamps in rig-file order). */
static struct gn_pose sim_pose(json_t *st)
{
        struct gn_pose p = gn_pose_none();
        json_t *v;
        size_t i;

        for (int r = 0; r < GN_ROLE_COUNT; r++)
                if (json_is_number(json_object_get(st, gn_role_name(r))))
                        p.deg[r] = json_number_value(json_object_get(st, gn_role_name(r)));
        json_array_foreach(json_object_get(st, "lamps"), i, v) if (json_is_true(v)) p.lamps |=
                UINT32_C(1) << i;
        json_array_foreach(json_object_get(st, "lasers"), i, v) if (json_is_true(v)) p.lasers |=
                UINT32_C(1) << i;
        return p;
}

static void print_pose(const char *what, const struct gn_pose *p)
{
        fprintf(stderr, "%s: turntable %g light_arm %g camera_arm %g lamps 0x%x lasers 0x%x\n",
                what, p->deg[0], p->deg[1], p->deg[2], p->lamps, p->lasers);
}

struct rows {
        json_t *log;    /* render_log */
        unsigned roles; /* bit r: the rig has an axis of role r */
};

/* Angles the rig has no axis for are rendered at 0 and must be absent from the row. */
static bool same_pose(const struct gn_pose *row, struct gn_pose sim, unsigned roles)
{
        for (int r = 0; r < GN_ROLE_COUNT; r++)
                if (!(roles & (1u << r)))
                        sim.deg[r] = NAN;
        return gn_pose_equal(row, &sim, POSE_TOL_DEG);
}

static int check_row(const struct ds_capture *c, void *userdata)
{
        struct rows *rows = userdata;
        json_t *r = rendered(rows->log, c->t_exposure_ns);
        struct gn_pose start, end;

        if (!r)
                fprintf(stderr, "row %lld (%s): no frame rendered at %llu\n", (long long)c->id,
                        c->file, (unsigned long long)c->t_exposure_ns);
        CHECK(r);
        CHECK_STR(json_string_value(json_object_get(r, "camera")), c->camera);
        start = sim_pose(json_object_get(r, "state"));
        end = sim_pose(json_object_get(r, "state_end"));
        if (!same_pose(&c->pose, start, rows->roles) || !same_pose(&c->pose, end, rows->roles)) {
                fprintf(stderr, "row %lld (%s) does not describe its exposure\n", (long long)c->id,
                        c->file);
                print_pose("row", &c->pose);
                print_pose("rendered (start)", &start);
                print_pose("rendered (end)", &end);
        }
        CHECK(same_pose(&c->pose, start, rows->roles) && same_pose(&c->pose, end, rows->roles));
        return 0;
}

int64_t check_dataset_roles(struct rigenv *e, const char *name, unsigned roles)
{
        struct rows rows = {render_log(e), roles};
        char path[400];
        struct ds *d = NULL;
        int64_t n;

        snprintf(path, sizeof(path), "%s/%s", e->data, name);
        CHECK_INT(ds_open(path, &d), 0);
        n = ds_count(d);
        CHECK_INT(ds_rows(d, 0, -1, check_row, &rows), n);
        ds_close(d);
        json_decref(rows.log);
        return n;
}

/* ---- sessions ---- */

void print_json(const char *what, json_t *reply)
{
        char *text = json_dumps(reply, JSON_COMPACT);

        fprintf(stderr, "%s: %s\n", what, text ? text : "?");
        free(text);
}

const char *const e2e_session_text = "name: s1\n"
                                     "dataset: ds1\n"
                                     "sweep:\n"
                                     "  turntable: { from: 0, to: 270, step: 90 }\n"
                                     "  light_arm: [0, 120]\n"
                                     "cameras: [cam0, cam1]\n"
                                     "lamps: [lamp0, lamp1]\n"
                                     "laser: true\n"
                                     "dark_frames: 1\n"
                                     "flat_frames: 1\n"
                                     "skip_occluded: false\n"
                                     "skip_glare: false\n"
                                     "metadata: { object: sphere, operator: e2e }\n";

const char *sess_write(struct rigenv *e, const char *name, const char *text, char *path, size_t len)
{
        snprintf(path, len, "%s/%s", e->dir, name);
        write_file(path, text);
        return path;
}

int64_t sess_planned(struct rigenv *e, const char *file, double *estimate_s)
{
        json_t *plan = ctl_ok(e, "session", "plan", file, NULL);
        int64_t n = json_integer_value(json_object_get(plan, "captures"));

        CHECK(n > 0);
        if (estimate_s)
                *estimate_s = json_number_value(json_object_get(plan, "estimate_s"));
        json_decref(plan);
        return n;
}

int sess_send_run(struct rigenv *e, const char *file)
{
        char *text = NULL, *req;
        size_t len = 0;
        FILE *f = fopen(file, "re");
        json_t *p;
        int fd = raw_connect(e);

        CHECK(f && fd >= 0);
        CHECK(getdelim(&text, &len, 0, f) > 0);
        fclose(f);
        p = json_pack("{sssssss{ssss}}", "jsonrpc", "2.0", "method", "session.run", "id", "1",
                      "params", "file", file, "text", text);
        free(text);
        req = json_dumps(p, JSON_COMPACT);
        json_decref(p);
        CHECK(req);
        req = realloc(req, strlen(req) + 2);
        CHECK(req);
        strcat(req, "\n");
        CHECK(write(fd, req, strlen(req)) == (ssize_t)strlen(req));
        free(req);
        return fd;
}

int sess_start_raw(struct rigenv *e, const char *file)
{
        int fd = sess_send_run(e, file);
        json_t *r = raw_call(fd, "");

        if (!json_object_get(r, "result"))
                print_json("session.run", r);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        return fd;
}

int sess_start_default(struct rigenv *e, int64_t *planned)
{
        char file[400];

        sess_write(e, "s1.yaml", e2e_session_text, file, sizeof(file));
        if (planned)
                *planned = sess_planned(e, file, NULL);
        return sess_start_raw(e, file);
}

const char *sess_state(struct rigenv *e, char *buf, size_t len)
{
        json_t *st = ctl_ok(e, "session", "status", NULL);

        snprintf(buf, len, "%s", json_string_value(json_object_get(st, "state")));
        json_decref(st);
        return buf;
}

void sess_wait(struct rigenv *e, const char *want, double timeout)
{
        double end = now_s() + timeout;
        char state[32];

        while (strcmp(sess_state(e, state, sizeof(state)), want) != 0) {
                if (strcmp(state, "none") == 0 || now_s() > end) {
                        fprintf(stderr, "session state %s, expected %s\n", state, want);
                        CHECK(!"the session did not reach the expected state");
                }
                usleep(50000);
        }
}

static void print_problem(const char *problem, void *userdata)
{
        fprintf(stderr, "dataset check: %s\n", problem);
}

int sess_problems(struct rigenv *e, const char *dataset)
{
        char path[400];
        struct ds *d = NULL;
        int r;

        snprintf(path, sizeof(path), "%s/%s", e->data, dataset);
        CHECK_INT(ds_open(path, &d), 0);
        r = ds_check(d, print_problem, NULL);
        CHECK(r >= 0);
        ds_close(d);
        return r;
}

void sess_info(struct rigenv *e, const char *dataset, const char *session,
               struct ds_session_info *info)
{
        char path[400];
        struct ds *d = NULL;

        snprintf(path, sizeof(path), "%s/%s", e->data, dataset);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_session_get(d, session, info), 0);
        ds_close(d);
}

void sess_check_complete(struct rigenv *e, const char *dataset, const char *session, int64_t n)
{
        struct ds_session_info info = {0};

        CHECK_INT(sess_problems(e, dataset), 0);
        sess_info(e, dataset, session, &info);
        if (strcmp(info.state, "done") != 0)
                fprintf(stderr, "session %s: %s (%s)\n", session, info.state, info.reason);
        CHECK_STR(info.state, "done");
        /* darks found in the dark library are imported rather than planned */
        CHECK(info.planned <= n); /* and every row is there: n, below */
        CHECK_INT(info.captured, info.planned);
        ds_session_info_clear(&info);
        CHECK_INT(check_dataset_roles(e, dataset, (1u << GN_ROLE_COUNT) - 1), n);
}

/* Kills what who names, waits for the pause when goniod survived, and resumes the session
 * on a new connection, which it returns (fd, the old one, is closed). */
static int kill_and_resume(struct rigenv *e, int fd, const char *who)
{
        bool daemon = strchr(who, 'd');
        json_t *r;

        if (strchr(who, 's'))
                rigenv_crash_sim(e);
        if (daemon)
                rigenv_crash_daemon(e);
        if (!daemon)
                sess_wait(e, "paused", 30);
        close(fd);
        fd = raw_connect(e);
        r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"session.resume\"}\n");
        if (!json_object_get(r, "result"))
                print_json("resume after a kill", r);
        json_decref(r);
        return fd;
}

void sess_run_killing(struct rigenv *e, const char *file, const char *const who[], int kills)
{
        int fd = sess_start_raw(e, file);

        for (int k = 0; k < kills; k++) {
                usleep(100000 + rand() % 1200000);
                fd = kill_and_resume(e, fd, who[k]);
        }
        close(fd);
        /* the session ends, or pauses (a kill hit its end) */
        for (double end = now_s() + 60; now_s() < end; usleep(100000)) {
                char state[32];
                if (strcmp(sess_state(e, state, sizeof(state)), "none") == 0)
                        break;
                if (strcmp(state, "paused") == 0)
                        CHECK_INT(ctl(e, NULL, "session", "resume", NULL), 0);
        }
}
