/* test-systemd.c - goniod under systemd's protocols, on gonio-sim, without systemd:
 *   activation  the test binds the operator and admin sockets, connects a client, then
 *               starts goniod with LISTEN_FDS/LISTEN_PID/LISTEN_FDNAMES as systemd would:
 *               the client connected before goniod started is served (it waited in the
 *               backlog), gonioctl works through the passed socket, goniod binds nothing
 *               itself, fault.override (admin) is refused on the operator socket and lifts a
 *               relay's fault on the admin one, and the sockets outlive goniod (systemd's);
 *   notify      NOTIFY_SOCKET on a datagram socket of the test: READY=1, STATUS= that
 *               follow the rig (idle, homing, fault), WATCHDOG=1 at WATCHDOG_USEC/2..3/4,
 *               STOPPING=1 at SIGTERM;
 *   run-user    goniod as a transient Type=notify unit of `systemd-run --user`, where a
 *               user manager runs (skipped, 77, where none does, as in a container). */
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "harness.h"
#include "tests/test.h"

#define WATCHDOG_USEC 500000

/* A socket of type bound at path (mode), listening when it is a stream socket. */
static int bound(const char *path, int type, mode_t mode)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        int fd = socket(AF_UNIX, type | SOCK_CLOEXEC, 0);

        CHECK(fd >= 0 && strlen(path) < sizeof(sa.sun_path));
        strcpy(sa.sun_path, path);
        CHECK(bind(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0 && chmod(path, mode) == 0);
        CHECK(type != SOCK_STREAM || listen(fd, 16) == 0);
        return fd;
}

static long error_code(json_t *reply)
{
        return json_integer_value(json_object_get(json_object_get(reply, "error"), "code"));
}

/* ---- activation ---- */

struct fds {
        int op, admin;
};

/* In goniod's child: the sockets at 3 and 4, named, for this pid (sd_listen_fds). */
static void pass_fds(void *ud)
{
        struct fds *f = ud;
        int op = fcntl(f->op, F_DUPFD, 10), admin = fcntl(f->admin, F_DUPFD, 10);
        char pid[32];

        if (op < 0 || admin < 0 || dup2(op, 3) != 3 || dup2(admin, 4) != 4)
                _exit(127);
        snprintf(pid, sizeof(pid), "%d", (int)getpid());
        setenv("LISTEN_FDS", "2", 1);
        setenv("LISTEN_PID", pid, 1);
        setenv("LISTEN_FDNAMES", "operator:admin", 1);
}

/* A relay that stops answering faults the rig; fault.clear cannot clear it; the admin's
 * fault.override lifts it, refused on the operator socket; the drives still move. */
static void check_override(struct rigenv *e, int op, int admin, const char *admin_path)
{
        char want[400];
        json_t *r;

        sim_request(e,
                    "{\"cmd\":\"inject\",\"bus\":\"relays\",\"unit\":10,\"fault\":\"timeout\"}\n");
        CHECK(ctl(e, NULL, "lamp", "lamp1", "on", NULL) != 0);
        json_decref(wait_state(e, "fault", 10));
        r = raw_call(op, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"fault.override\"}\n");
        snprintf(want, sizeof(want),
                 "method 'fault.override' is allowed only on the admin socket (%s)", admin_path);
        CHECK_INT(error_code(r), -32008);
        CHECK_STR(json_string_value(json_object_get(json_object_get(r, "error"), "message")), want);
        json_decref(r);
        json_decref(wait_state(e, "fault", 1)); /* refused: still latched */
        /* busy (-32001) until the safe state is reached */
        for (double end = now_s() + 5;; usleep(50000)) {
                r = raw_call(admin,
                             "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"fault.override\"}\n");
                if (json_object_get(r, "result"))
                        break;
                CHECK(error_code(r) == -32001 && now_s() < end);
                json_decref(r);
        }
        json_decref(r);
        json_decref(wait_state(e, "idle", 5));
        json_decref(ctl_ok(e, "home", "turntable", NULL));
        json_decref(ctl_ok(e, "move", "turntable", "20", NULL));
}

static void test_activation(struct rigenv *e)
{
        char admin_path[320], unused[320];
        struct fds f;
        json_t *r;
        int early, admin, status;

        snprintf(admin_path, sizeof(admin_path), "%s/admin.sock", e->dir);
        snprintf(unused, sizeof(unused), "%s/no-such-dir/goniod.sock", e->dir);
        f.op = bound(e->sock, SOCK_STREAM, 0660);
        f.admin = bound(admin_path, SOCK_STREAM, 0600);
        /* before goniod runs: the connection waits in the backlog, the request in its buffer */
        early = raw_connect(e);
        CHECK(early >= 0);
        rigenv_spawn_daemon(e, unused, pass_fds, &f);
        close(f.op);
        close(f.admin);
        r = raw_call(early, "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"hello\",\"params\":"
                            "{\"protocol\":1}}\n");
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        json_decref(ctl_ok(e, "status", NULL));
        CHECK(access(unused, F_OK) < 0 && errno == ENOENT); /* it bound nothing itself */
        admin = test_unix_connect(admin_path);
        CHECK(admin >= 0);
        check_override(e, early, admin, admin_path);
        close(admin);
        close(early);
        CHECK(kill(e->daemon, SIGTERM) == 0);
        CHECK(waitpid(e->daemon, &status, 0) == e->daemon);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
        e->daemon = 0;
        CHECK(access(e->sock, F_OK) == 0 && access(admin_path, F_OK) == 0);
}

/* ---- notify ---- */

/* In goniod's child: systemd's notification and watchdog variables for this pid. */
static void notify_env(void *ud)
{
        char pid[32], usec[32];

        snprintf(pid, sizeof(pid), "%d", (int)getpid());
        snprintf(usec, sizeof(usec), "%d", WATCHDOG_USEC);
        setenv("NOTIFY_SOCKET", ud, 1);
        setenv("WATCHDOG_PID", pid, 1);
        setenv("WATCHDOG_USEC", usec, 1);
}

/* What goniod sent to NOTIFY_SOCKET, read at once by a thread (as systemd does: goniod's
 * sd_notify blocks when the socket's queue is full). */
struct notes {
        int fd;
        pthread_mutex_t lock;
        char text[1 << 16]; /* the datagrams but WATCHDOG=1, each after a "|" */
        size_t len;
        int pings;        /* WATCHDOG=1 seen */
        double gap, last; /* the longest gap between two, the last one's time */
};

static void *read_notes(void *ud)
{
        struct notes *n = ud;
        char buf[4096];
        ssize_t len;

        while ((len = recv(n->fd, buf, sizeof(buf) - 1, 0)) > 0) {
                double t = now_s();
                buf[len] = 0;
                pthread_mutex_lock(&n->lock);
                if (strcmp(buf, "WATCHDOG=1") == 0) {
                        n->gap = n->last > 0 ? MAX(n->gap, t - n->last) : 0;
                        n->last = t;
                        n->pings++;
                } else if (n->len + len + 2 < sizeof(n->text)) {
                        fprintf(stderr, "notify: %s\n", buf);
                        n->len += snprintf(n->text + n->len, sizeof(n->text) - n->len, "|%s", buf);
                }
                pthread_mutex_unlock(&n->lock);
        }
        return NULL;
}

/* Waits until what goniod sent, from *from on, holds want (within timeout s); moves *from
 * past it. */
static void wait_note(struct notes *n, size_t *from, const char *want, double timeout)
{
        double end = now_s() + timeout;

        for (;;) {
                const char *at;
                pthread_mutex_lock(&n->lock);
                at = strstr(n->text + *from, want);
                if (at)
                        *from = at - n->text + strlen(want);
                pthread_mutex_unlock(&n->lock);
                if (at)
                        return;
                if (now_s() > end) {
                        fprintf(stderr, "no '%s' from goniod within %.1f s\n", want, timeout);
                        CHECK(!"notification missing");
                }
                usleep(10000);
        }
}

static void test_notify(struct rigenv *e)
{
        static struct notes n = {.lock = PTHREAD_MUTEX_INITIALIZER};
        char path[320];
        size_t from = 0;
        pthread_t reader;
        double t_ready;
        int status;

        snprintf(path, sizeof(path), "%s/notify.sock", e->dir);
        n.fd = bound(path, SOCK_DGRAM, 0600);
        CHECK(pthread_create(&reader, NULL, read_notes, &n) == 0);
        rigenv_spawn_daemon(e, e->sock, notify_env, path);
        wait_note(&n, &from, "|READY=1\nSTATUS=idle", 30);
        t_ready = now_s();
        pthread_mutex_lock(&n.lock);
        n.pings = 0;
        n.gap = n.last = 0;
        pthread_mutex_unlock(&n.lock);
        /* STATUS= follows the rig */
        json_decref(ctl_ok(e, "home", "turntable", NULL));
        wait_note(&n, &from, "|STATUS=homing", 5);
        wait_note(&n, &from, "|STATUS=idle", 10);
        sim_request(e,
                    "{\"cmd\":\"inject\",\"bus\":\"relays\",\"unit\":10,\"fault\":\"timeout\"}\n");
        CHECK(ctl(e, NULL, "lamp", "lamp1", "on", NULL) != 0);
        wait_note(&n, &from, "|STATUS=fault: ", 10);
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"relays\",\"unit\":10,\"fault\":\"none\"}\n");
        /* the watchdog, meanwhile: at WATCHDOG_USEC/2..3/4, so 3 pings at least in 1.5 s */
        usleep(MAX(0, (int)((t_ready + 1.5 - now_s()) * 1e6)));
        pthread_mutex_lock(&n.lock);
        fprintf(stderr, "%d pings in %.1f s, longest gap %.3f s\n", n.pings, now_s() - t_ready,
                n.gap);
        CHECK(n.pings >= 3 && n.gap <= WATCHDOG_USEC * 1e-6);
        pthread_mutex_unlock(&n.lock);
        CHECK(kill(e->daemon, SIGTERM) == 0);
        wait_note(&n, &from, "|STOPPING=1\nSTATUS=stopping", 10);
        CHECK(waitpid(e->daemon, &status, 0) == e->daemon);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
        e->daemon = 0;
}

/* ---- run-user ---- */

/* Runs cmd (a shell line) quietly; returns its exit status. */
static int sh(const char *cmd)
{
        int r = system(cmd);

        return WIFEXITED(r) ? WEXITSTATUS(r) : 128;
}

static void test_run_user(struct rigenv *e)
{
        char cmd[2048], unit[64];

        if (sh("timeout 10 systemd-run --user --quiet --wait true >/dev/null 2>&1") != 0) {
                fprintf(stderr, "no systemd user manager here: skipped\n");
                rigenv_stop(e);
                exit(TEST_SKIP);
        }
        snprintf(unit, sizeof(unit), "gonio-test-%d", (int)getpid());
        /* Type=notify: systemd-run returns once goniod sent READY=1 */
        snprintf(cmd, sizeof(cmd),
                 "timeout 60 systemd-run --user --quiet --unit=%s -p Type=notify "
                 "-p WatchdogSec=5 --setenv=GONIO_SIM_DIR=%s %s --rig %s --socket %s --data %s",
                 unit, e->simdir, e->goniod, e->rig, e->sock, e->data);
        CHECK_INT(sh(cmd), 0);
        json_decref(ctl_ok(e, "status", NULL));
        snprintf(cmd, sizeof(cmd), "systemctl --user is-active --quiet %s", unit);
        CHECK_INT(sh(cmd), 0);
        snprintf(cmd, sizeof(cmd), "systemctl --user stop %s", unit);
        CHECK_INT(sh(cmd), 0);
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 5);
        signal(SIGPIPE, SIG_IGN);
        rigenv_start_sim(&e, argv, 20);
        if (strcmp(argv[4], "activation") == 0)
                test_activation(&e);
        else if (strcmp(argv[4], "notify") == 0)
                test_notify(&e);
        else if (strcmp(argv[4], "run-user") == 0)
                test_run_user(&e);
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return 0;
}
