/* test-gonio-sim.c - the gonio-sim program (path in argv[1]): started on the test rig
 * with a fresh --dir it prints its ports and "ready", writes the ports file and the
 * symlinks and opens its render log; SIGTERM makes it exit 0 and remove them. A bad rig file is
 * refused with a message naming the file. */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <jansson.h>

#include "tests/sim/simtest.h"

struct child {
        pid_t pid;
        int out, err; /* read ends of its stdout and stderr */
};

/* Runs prog on rig with --dir dir and --ports-file ports; its render log goes to
 * ports's directory, render.log. */
static struct child spawn(const char *prog, const char *rig, const char *dir, const char *ports)
{
        char log[256];
        int out[2], err[2];
        struct child c;

        snprintf(log, sizeof log, "%.*s/render.log", (int)(strrchr(ports, '/') - ports), ports);
        CHECK(pipe(out) == 0 && pipe(err) == 0);
        c.pid = fork();
        CHECK(c.pid >= 0);
        if (c.pid == 0) {
                dup2(out[1], STDOUT_FILENO);
                dup2(err[1], STDERR_FILENO);
                execl(prog, prog, "--rig", rig, "--dir", dir, "--time-scale", "10", "--ports-file",
                      ports, "--render-log", log, (char *)NULL);
                _exit(127);
        }
        close(out[1]);
        close(err[1]);
        c.out = out[0];
        c.err = err[0];
        return c;
}

/* Reads fd until it contains want or closes; returns what was read (static-size buffer). */
static void read_until(int fd, const char *want, char *buf, size_t len, double limit_s)
{
        size_t n = 0;
        double t0 = simtest_now();

        buf[0] = '\0';
        while (!strstr(buf, want) && n + 1 < len) {
                struct pollfd p = {.fd = fd, .events = POLLIN};
                CHECK(simtest_now() - t0 < limit_s);
                if (poll(&p, 1, 100) <= 0)
                        continue;
                ssize_t k = read(fd, buf + n, len - n - 1);
                if (k <= 0)
                        break;
                n += (size_t)k;
                buf[n] = '\0';
        }
}

static int wait_exit(pid_t pid, double limit_s)
{
        double t0 = simtest_now();
        int status;

        while (waitpid(pid, &status, WNOHANG) == 0) {
                CHECK(simtest_now() - t0 < limit_s);
                usleep(10000);
        }
        CHECK(WIFEXITED(status));
        return WEXITSTATUS(status);
}

static void check_link(const char *path, const char *target)
{
        char buf[256];
        ssize_t n = readlink(path, buf, sizeof buf - 1);

        CHECK(n > 0);
        buf[n] = '\0';
        CHECK(strcmp(buf, target) == 0);
}

/* The control socket answers control requests and renders nothing. */
static void check_control(const char *path)
{
        static const char req[] = "{\"cmd\":\"state\"}\n{\"cmd\":\"render\",\"camera\":\"cam0\"}\n";
        char reply[4096] = "";
        size_t len = 0;
        int fd = test_unix_connect(path);

        CHECK(fd >= 0);
        CHECK(write(fd, req, strlen(req)) == (ssize_t)strlen(req));
        while (len < sizeof(reply) - 1 && !strstr(reply, "renders nothing")) {
                ssize_t n = read(fd, reply + len, sizeof(reply) - 1 - len);
                CHECK(n > 0);
                len += n;
                reply[len] = 0;
        }
        CHECK(strstr(reply, "\"state\""));
        close(fd);
}

static void test_run(const char *prog)
{
        char dir[64], rig[128], run[128], ports[128], path[256], out[8192];
        struct stat st;
        json_error_t jerr;

        simtest_write_rig(dir, false);
        snprintf(rig, sizeof rig, "%s/rig.yaml", dir);
        snprintf(run, sizeof run, "%s/run/sub", dir); /* created by gonio-sim */
        snprintf(ports, sizeof ports, "%s/ports.json", dir);
        struct child c = spawn(prog, rig, run, ports);
        read_until(c.out, "ready\n", out, sizeof out, 15.0);
        CHECK(strstr(out, "ready\n"));
        CHECK(strstr(out, "\"drives\""));

        json_t *o = json_load_file(ports, 0, &jerr);
        CHECK(o);
        json_t *buses = json_object_get(o, "buses");
        const char *drives_pty =
                json_string_value(json_object_get(json_object_get(buses, "drives"), "pty"));
        const char *relays_pty =
                json_string_value(json_object_get(json_object_get(buses, "relays"), "pty"));
        const char *sock =
                json_string_value(json_object_get(json_object_get(buses, "frames"), "path"));
        CHECK(drives_pty && relays_pty && sock);
        snprintf(path, sizeof path, "%s/drives", run);
        check_link(path, drives_pty);
        snprintf(path, sizeof path, "%s/relays", run);
        check_link(path, relays_pty);
        snprintf(path, sizeof path, "%s/frames.sock", run);
        CHECK(strcmp(sock, path) == 0);
        CHECK(stat(sock, &st) == 0 && S_ISSOCK(st.st_mode));
        snprintf(path, sizeof path, "%s/control.sock", run); /* --dir gives a control socket */
        CHECK(stat(path, &st) == 0 && S_ISSOCK(st.st_mode));
        check_control(path);
        snprintf(path, sizeof path, "%s/render.log", dir);
        CHECK(stat(path, &st) == 0 && st.st_size == 0); /* opened, no frame yet */

        /* The drives answer on the pty. */
        modbus_t *mb = simtest_modbus(run, "drives");
        CHECK(simtest_reg(mb, 3, SIMTEST_R_SPEED) == 300);
        modbus_close(mb);
        modbus_free(mb);

        CHECK(kill(c.pid, SIGTERM) == 0);
        CHECK(wait_exit(c.pid, 10.0) == 0);
        CHECK(lstat(sock, &st) < 0 && errno == ENOENT);
        snprintf(path, sizeof path, "%s/control.sock", run);
        CHECK(lstat(path, &st) < 0 && errno == ENOENT);
        snprintf(path, sizeof path, "%s/drives", run);
        CHECK(lstat(path, &st) < 0 && errno == ENOENT);
        snprintf(path, sizeof path, "%s/relays", run);
        CHECK(lstat(path, &st) < 0 && errno == ENOENT);
        CHECK(access(ports, F_OK) < 0);
        json_decref(o);
        close(c.out);
        close(c.err);
        CHECK(rmdir(run) == 0);
        snprintf(path, sizeof path, "%s/run", dir);
        CHECK(rmdir(path) == 0);
        simtest_rmdir(dir);
}

static void test_bad_rig(const char *prog)
{
        char dir[64], rig[128], ports[128], err[4096];

        simtest_write_rig(dir, false);
        snprintf(rig, sizeof rig, "%s/rig.yaml", dir);
        FILE *f = fopen(rig, "a");
        CHECK(f && fputs("bogus_key: 1\n", f) >= 0 && fclose(f) == 0);
        snprintf(ports, sizeof ports, "%s/ports.json", dir);
        struct child c = spawn(prog, rig, dir, ports);
        read_until(c.err, "\n", err, sizeof err, 15.0);
        CHECK(wait_exit(c.pid, 10.0) == 1);
        CHECK(strstr(err, "rig.yaml") && strstr(err, "bogus_key"));
        CHECK(access(ports, F_OK) < 0);
        close(c.out);
        close(c.err);
        simtest_rmdir(dir);
}

int main(int argc, char **argv)
{
        CHECK(argc == 2);
        test_run(argv[1]);
        test_bad_rig(argv[1]);
        return 0;
}
