/* test-server.c - goniod's control server (daemon/server.c) in process, on a real
 * sd-event loop in a child process, driven through its socket:
 *   socket  one server per path: a live socket or a held lock is refused with
 *           -EADDRINUSE, a stale socket is replaced, a regular file is kept, and the
 *           path is unlinked on exit only while it is still the server's socket;
 *   churn   clients connecting and leaving at once leave no client behind;
 *   noread  a client that never reads its replies is dropped, others keep being served;
 *   evict   with the table full, the oldest client without hello goes first, then the
 *           one idle longest (not one with a request pending); when nobody qualifies
 *           the new connection gets one error line;
 *   nofd    out of descriptors, a connection still gets its error line, and the
 *           server accepts again once a client leaves;
 *   roles   an admin method is refused (-EPERM, naming the admin socket) on an operator
 *           socket and served on an admin socket taken as a descriptor (as from systemd),
 *           which must be a listening AF_UNIX stream socket and is never unlinked. */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <systemd/sd-event.h>
#include <time.h>
#include <unistd.h>

#include "daemon/server.h"
#include "tests/test.h"

#define EVICT_MAX     4
#define EVICT_IDLE_US 300000ULL

struct child {
        sd_event *event;
        struct server *server;
        struct srv_req *held;
};

static int m_ok(struct srv_req *req, json_t *params, void *userdata)
{
        srv_reply(req, NULL);
        return 0;
}

static int m_blob(struct srv_req *req, json_t *params, void *userdata)
{
        static char blob[60000];

        memset(blob, 'x', sizeof(blob) - 1);
        srv_reply(req, json_pack("{ss}", "blob", blob));
        return 0;
}

static int m_clients(struct srv_req *req, json_t *params, void *userdata)
{
        struct child *ch = userdata;

        srv_reply(req, json_pack("{si}", "n", (int)server_clients(ch->server)));
        return 0;
}

static int m_hold(struct srv_req *req, json_t *params, void *userdata)
{
        ((struct child *)userdata)->held = req; /* answered by release */
        return 0;
}

static int m_release(struct srv_req *req, json_t *params, void *userdata)
{
        struct child *ch = userdata;

        if (ch->held)
                srv_reply(ch->held, NULL);
        ch->held = NULL;
        srv_reply(req, NULL);
        return 0;
}

static int m_quit(struct srv_req *req, json_t *params, void *userdata)
{
        sd_event_exit(((struct child *)userdata)->event, 0);
        srv_reply(req, NULL);
        return 0;
}

static const struct srv_method methods[] = {
        {"hello", m_ok},  {"status", m_ok},       {"blob", m_blob}, {"clients", m_clients},
        {"hold", m_hold}, {"release", m_release}, {"quit", m_quit}, {"secret", m_ok, .admin = true},
        {NULL, NULL},
};

static pid_t server_pid; /* killed if a check fails */

static void kill_server(void)
{
        kill_own_child(server_pid);
}

/* Leaves the calling process exactly n free descriptors (holes filled, limit lowered). */
static void leave_fds(unsigned n)
{
        struct rlimit rl;
        int top = 0, fd;

        for (int i = 0; i < 1024; i++)
                if (fcntl(i, F_GETFD) >= 0)
                        top = i;
        while ((fd = open("/dev/null", O_RDONLY | O_CLOEXEC)) < top)
                CHECK(fd >= 0); /* kept open: fills a hole */
        close(fd);
        CHECK(getrlimit(RLIMIT_NOFILE, &rl) == 0);
        rl.rlim_cur = top + 1 + n;
        CHECK(setrlimit(RLIMIT_NOFILE, &rl) == 0);
}

/* A server of methods listening on path (operator): 0, or the -errno of server_listen. */
static int server_at(sd_event *ev, const char *path, void *userdata, struct server **ret)
{
        int r = server_new(ev, methods, userdata, ret);

        if (r >= 0 && (r = server_listen(*ret, path, SRV_OPERATOR)) < 0)
                *ret = server_free(*ret);
        return r;
}

/* Forks a server on path with the given limits (free_fds: descriptors left to the
 * server after start, 0 for no limit; admin_fd: a listening socket it serves as admin,
 * or -1); returns its pid once it listens. */
static pid_t serve(const char *path, unsigned max_clients, uint64_t idle_usec, unsigned free_fds,
                   int admin_fd)
{
        struct child ch = {0};
        int p[2];
        char c;
        pid_t pid;

        CHECK(pipe(p) == 0);
        pid = fork();
        CHECK(pid >= 0);
        if (pid > 0) {
                close(p[1]);
                if (admin_fd >= 0)
                        close(admin_fd);
                server_pid = pid;
                atexit(kill_server);
                CHECK(read(p[0], &c, 1) == 1);
                close(p[0]);
                return pid;
        }
        close(p[0]);
        CHECK(sd_event_new(&ch.event) >= 0);
        CHECK_INT(server_at(ch.event, path, &ch, &ch.server), 0);
        if (admin_fd >= 0)
                CHECK_INT(server_listen_fd(ch.server, admin_fd, SRV_ADMIN), 0);
        server_set_limits(ch.server, max_clients, idle_usec);
        CHECK_INT(server_start(ch.server), 0);
        if (free_fds)
                leave_fds(free_fds);
        CHECK(write(p[1], "r", 1) == 1);
        CHECK(sd_event_loop(ch.event) >= 0);
        server_free(ch.server);
        sd_event_unref(ch.event);
        _exit(0);
}

static double now_s(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Reads one line (without '\n') within 5 s. Returns its length, 0 at EOF, or -errno. */
static int read_line(int fd, char *buf, size_t size)
{
        size_t len = 0;

        while (len + 1 < size) {
                struct pollfd pfd = {.fd = fd, .events = POLLIN};
                ssize_t n;

                CHECK(poll(&pfd, 1, 5000) == 1);
                n = read(fd, buf + len, 1);
                if (n <= 0)
                        return n < 0 ? -errno : 0;
                if (buf[len] == '\n')
                        break;
                len++;
        }
        buf[len] = 0;
        return len;
}

static void send_req(int fd, const char *method)
{
        char line[200];
        int n = snprintf(line, sizeof(line), "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"%s\"}\n",
                         method);

        CHECK(send(fd, line, n, MSG_NOSIGNAL) == n);
}

/* Calls method on fd and returns the reply. */
static json_t *call(int fd, const char *method)
{
        char buf[1 << 17];
        json_t *r;

        send_req(fd, method);
        CHECK(read_line(fd, buf, sizeof(buf)) > 0);
        r = json_loads(buf, 0, NULL);
        CHECK(r);
        return r;
}

/* The next line on fd is a successful reply. */
static void expect_result(int fd)
{
        char buf[1 << 17];
        json_t *r;

        CHECK(read_line(fd, buf, sizeof(buf)) > 0);
        r = json_loads(buf, 0, NULL);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
}

static void call_ok(int fd, const char *method)
{
        send_req(fd, method);
        expect_result(fd);
}

/* Polls the server's client count until it is want (within 5 s). */
static void wait_clients(int fd, int want)
{
        double end = now_s() + 5;

        for (;;) {
                json_t *r = call(fd, "clients");
                int n = json_integer_value(json_object_get(json_object_get(r, "result"), "n"));

                json_decref(r);
                if (n == want)
                        return;
                if (now_s() > end)
                        CHECK_INT(n, want);
                usleep(20000);
        }
}

/* The next line on fd is an error for EUSERS whose message has part; then the server
 * closes the connection. */
static void expect_dropped(int fd, const char *part)
{
        char buf[4096];
        json_t *r, *err;

        CHECK(read_line(fd, buf, sizeof(buf)) > 0);
        r = json_loads(buf, 0, NULL);
        err = json_object_get(r, "error");
        CHECK(json_is_null(json_object_get(r, "id")));
        CHECK_INT(json_integer_value(json_object_get(err, "code")), -32001);
        CHECK_STR(json_string_value(json_object_get(json_object_get(err, "data"), "errno")),
                  "EUSERS");
        CHECK_STR_CONTAINS(json_string_value(json_object_get(err, "message")), part);
        json_decref(r);
        CHECK(read_line(fd, buf, sizeof(buf)) <= 0);
        close(fd);
}

static void stop(pid_t pid, int fd)
{
        int status;

        call_ok(fd, "quit");
        close(fd);
        CHECK(waitpid(pid, &status, 0) == pid);
        server_pid = 0;
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

static void make_stale_socket(const char *path)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        int fd = socket(AF_UNIX, SOCK_STREAM, 0);

        snprintf(sa.sun_path, sizeof(sa.sun_path), "%s", path);
        CHECK(bind(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0);
        close(fd); /* the file stays, nothing listens */
}

static void test_socket(const char *dir)
{
        char path[300], lock[310], moved[310], buf[16] = "";
        struct server *a = NULL, *b = NULL;
        sd_event *ev;
        FILE *f;
        int fd;

        snprintf(path, sizeof(path), "%s/s.sock", dir);
        snprintf(lock, sizeof(lock), "%s.lock", path);
        snprintf(moved, sizeof(moved), "%s.moved", path);
        CHECK(sd_event_new(&ev) >= 0);
        /* live: refused, the first keeps its socket */
        CHECK_INT(server_at(ev, path, NULL, &a), 0);
        CHECK_INT(server_at(ev, path, NULL, &b), -EADDRINUSE);
        CHECK((fd = test_unix_connect(path)) >= 0);
        close(fd);
        /* on exit the path is unlinked only while it is still our socket */
        CHECK(rename(path, moved) == 0);
        make_stale_socket(path);
        a = server_free(a);
        CHECK(access(path, F_OK) == 0);
        /* stale: replaced, and unlinked on exit */
        CHECK_INT(server_at(ev, path, NULL, &a), 0);
        CHECK((fd = test_unix_connect(path)) >= 0);
        close(fd);
        a = server_free(a);
        CHECK(access(path, F_OK) < 0 && errno == ENOENT);
        /* a lock held by someone else (a daemon starting): refused, path untouched */
        CHECK((fd = open(lock, O_RDWR | O_CLOEXEC)) >= 0);
        CHECK(flock(fd, LOCK_EX | LOCK_NB) == 0);
        CHECK_INT(server_at(ev, path, NULL, &a), -EADDRINUSE);
        CHECK(access(path, F_OK) < 0);
        close(fd);
        /* a regular file: refused and kept */
        CHECK((f = fopen(path, "we")) && fputs("keep", f) >= 0 && fclose(f) == 0);
        CHECK_INT(server_at(ev, path, NULL, &a), -EEXIST);
        CHECK((f = fopen(path, "re")) && fgets(buf, sizeof(buf), f) && fclose(f) == 0);
        CHECK_STR(buf, "keep");
        sd_event_unref(ev);
}

static void test_churn(const char *path)
{
        pid_t pid = serve(path, SRV_MAX_CLIENTS, SRV_IDLE_TIMEOUT_USEC, 0, -1);
        int watch = test_unix_connect(path);

        CHECK(watch >= 0);
        call_ok(watch, "hello"); /* not evicted when leavers fill the table */
        for (int i = 0; i < 3000; i++) {
                int fd = test_unix_connect(path);

                CHECK(fd >= 0);
                if (i % 2)
                        send_req(fd, i % 4 == 1 ? "status" : "blob"); /* gone before the reply */
                close(fd);
        }
        wait_clients(watch, 1);
        stop(pid, watch);
}

static void test_noread(const char *path)
{
        pid_t pid = serve(path, SRV_MAX_CLIENTS, SRV_IDLE_TIMEOUT_USEC, 0, -1);
        int watch = test_unix_connect(path), rude = test_unix_connect(path), sent = 0;
        double end = now_s() + 30;

        CHECK(watch >= 0 && rude >= 0);
        for (;;) {
                struct pollfd pfd = {.fd = rude, .events = POLLOUT};
                static const char req[] = "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"blob\"}\n";
                ssize_t n = send(rude, req, sizeof(req) - 1, MSG_NOSIGNAL | MSG_DONTWAIT);

                if (n < 0 && (errno == EPIPE || errno == ECONNRESET))
                        break; /* dropped */
                CHECK(n == (ssize_t)sizeof(req) - 1 || (n < 0 && errno == EAGAIN));
                if (n < 0)
                        poll(&pfd, 1, 100);
                if (n > 0 && ++sent % 50 == 0) {
                        double t = now_s();
                        call_ok(watch, "status");
                        CHECK(now_s() - t < 1.0); /* the others are served meanwhile */
                }
                CHECK(now_s() < end);
        }
        /* dropped for its backlog (1 MiB of 60 kB replies beyond the socket buffers), not
         * at once */
        CHECK(sent > 16);
        close(rude);
        wait_clients(watch, 1);
        stop(pid, watch);
}

static void test_evict(const char *path)
{
        pid_t pid = serve(path, EVICT_MAX, EVICT_IDLE_US, 0, -1);
        int a = test_unix_connect(path), b = test_unix_connect(path), c = test_unix_connect(path),
            d = test_unix_connect(path), e, f, g, h;

        call_ok(a, "hello");
        send_req(a, "hold"); /* a is idle longest, but awaits a reply */
        usleep(10000);
        call_ok(b, "hello");
        call_ok(c, "status"); /* a request is not a hello */
        /* full: the oldest without hello goes (c, then d) */
        e = test_unix_connect(path);
        expect_dropped(c, "never said hello");
        f = test_unix_connect(path);
        expect_dropped(d, "never said hello");
        call_ok(e, "hello");
        call_ok(f, "hello");
        /* full of fresh clients that said hello: refused with one line */
        g = test_unix_connect(path);
        expect_dropped(g, "too many clients (4)");
        /* past the idle timeout: the one idle longest goes, not one awaiting a reply */
        usleep(EVICT_IDLE_US + 100000);
        call_ok(e, "status");
        h = test_unix_connect(path);
        expect_dropped(b, "was idle for");
        call_ok(h, "hello");
        call_ok(f, "release");
        expect_result(a); /* the held request's reply */
        wait_clients(a, 4);
        close(e);
        close(f);
        close(h);
        stop(pid, a);
}

static void test_nofd(const char *path)
{
        pid_t pid = serve(path, SRV_MAX_CLIENTS, SRV_IDLE_TIMEOUT_USEC, 2, -1);
        int a = test_unix_connect(path), b = test_unix_connect(path), c;

        call_ok(a, "hello");
        call_ok(b, "hello");
        c = test_unix_connect(path);
        expect_dropped(c, "out of file descriptors");
        c = test_unix_connect(path); /* the spare descriptor is back: the same again */
        expect_dropped(c, "out of file descriptors");
        close(b);
        wait_clients(a, 1);
        c = test_unix_connect(path);
        call_ok(c, "hello");
        wait_clients(a, 2);
        close(c);
        stop(pid, a);
}

/* A socket bound at path, listening (or not). Returns the fd. */
static int bound_socket(const char *path, bool listening)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

        snprintf(sa.sun_path, sizeof(sa.sun_path), "%s", path);
        CHECK(fd >= 0 && bind(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0);
        CHECK(!listening || listen(fd, 16) == 0);
        return fd;
}

static void test_roles(const char *dir, const char *path)
{
        char admin[300], other[300], want[400];
        struct server *s = NULL;
        sd_event *ev;
        json_t *r;
        pid_t pid;
        int a, op;

        snprintf(admin, sizeof(admin), "%s/admin.sock", dir);
        snprintf(other, sizeof(other), "%s/other.sock", dir);
        /* what a descriptor must be: not a datagram socket, not a socket that does not listen */
        CHECK(sd_event_new(&ev) >= 0);
        CHECK_INT(server_new(ev, methods, NULL, &s), 0);
        CHECK_INT(server_listen_fd(s, socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0), SRV_ADMIN),
                  -ENOTSOCK);
        CHECK_INT(server_listen_fd(s, bound_socket(other, false), SRV_ADMIN), -ENOTSOCK);
        s = server_free(s);
        sd_event_unref(ev);
        pid = serve(path, SRV_MAX_CLIENTS, SRV_IDLE_TIMEOUT_USEC, 0, bound_socket(admin, true));
        op = test_unix_connect(path);
        a = test_unix_connect(admin);
        CHECK(op >= 0 && a >= 0);
        r = call(op, "secret");
        snprintf(want, sizeof(want), "method 'secret' is allowed only on the admin socket (%s)",
                 admin);
        CHECK_INT(json_integer_value(json_object_get(json_object_get(r, "error"), "code")), -32008);
        CHECK_STR(json_string_value(json_object_get(json_object_get(r, "error"), "message")), want);
        CHECK_STR(json_string_value(json_object_get(
                          json_object_get(json_object_get(r, "error"), "data"), "errno")),
                  "EPERM");
        json_decref(r);
        call_ok(a, "secret");
        call_ok(a, "status");
        call_ok(op, "status");
        close(op);
        stop(pid, a);
        CHECK(access(admin, F_OK) == 0); /* its owner's, not the server's */
}

int main(int argc, char **argv)
{
        char dir[] = "/tmp/gonio-server-XXXXXX", path[300], cmd[400];

        CHECK(argc == 2);
        CHECK(mkdtemp(dir));
        snprintf(path, sizeof(path), "%s/goniod.sock", dir);
        signal(SIGPIPE, SIG_IGN);
        if (strcmp(argv[1], "socket") == 0)
                test_socket(dir);
        else if (strcmp(argv[1], "churn") == 0)
                test_churn(path);
        else if (strcmp(argv[1], "noread") == 0)
                test_noread(path);
        else if (strcmp(argv[1], "evict") == 0)
                test_evict(path);
        else if (strcmp(argv[1], "nofd") == 0)
                test_nofd(path);
        else if (strcmp(argv[1], "roles") == 0)
                test_roles(dir, path);
        else
                CHECK(!"unknown case");
        snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
        CHECK(system(cmd) == 0);
        return 0;
}
