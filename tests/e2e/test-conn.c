/* test-conn.c - goniod's control socket under contention, end to end on gonio-sim:
 * 300 connected clients that say and read nothing do not lock the operator out
 * (`stop` still stops a move at once); a second goniod on the same socket exits
 * with a clear message and leaves the first reachable; a stale socket left by a
 * killed goniod is replaced; a regular file at the socket path is never removed. */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "harness.h"
#include "tests/test.h"

#define N_RUDE 300

/* The first line fd received: the server's reason for dropping it. */
static void expect_evicted(int fd)
{
        struct pollfd pfd = {.fd = fd, .events = POLLIN};
        char buf[4096];
        ssize_t n;
        json_t *r;

        CHECK(poll(&pfd, 1, 5000) == 1);
        n = read(fd, buf, sizeof(buf) - 1);
        CHECK(n > 0);
        buf[n] = 0;
        CHECK(strchr(buf, '\n'));
        *strchr(buf, '\n') = 0;
        r = json_loads(buf, 0, NULL);
        CHECK_INT(json_integer_value(json_object_get(json_object_get(r, "error"), "code")), -32001);
        CHECK_STR_CONTAINS(
                json_string_value(json_object_get(json_object_get(r, "error"), "message")),
                "never said hello");
        json_decref(r);
}

static void test_rude_clients(struct rigenv *e)
{
        int rude[N_RUDE];
        json_t *st, *a;
        double t;
        size_t i;

        json_decref(ctl_ok(e, "move", "camera_arm", "160", "--no-wait", NULL));
        for (int k = 0; k < N_RUDE; k++)
                CHECK((rude[k] = raw_connect(e)) >= 0);
        t = now_s();
        json_decref(ctl_ok(e, "stop", NULL));
        CHECK(now_s() - t < 3);
        st = wait_state(e, "idle", 5);
        json_array_foreach(json_object_get(st, "axes"), i, a)
        {
                if (strcmp(json_string_value(json_object_get(a, "name")), "camera_arm") == 0)
                        CHECK(json_number_value(json_object_get(a, "position")) < 100);
        }
        json_decref(st);
        expect_evicted(rude[0]); /* the oldest made room first */
        for (int k = 0; k < N_RUDE; k++)
                close(rude[k]);
}

static void test_second_daemon(struct rigenv *e)
{
        char *argv[] = {(char *)e->goniod, "--rig",  e->rig,  "--socket",
                        e->sock,           "--data", e->data, NULL};
        char err[8192], want[400];

        CHECK(run_capture(argv, NULL, 0, err, sizeof(err)) != 0);
        snprintf(want, sizeof(want), "another goniod is serving %s (connect succeeded); stop it",
                 e->sock);
        CHECK_STR_CONTAINS(err, want);
        CHECK(waitpid(e->daemon, NULL, WNOHANG) == 0);
        json_decref(ctl_ok(e, "status", NULL)); /* the first is still reachable */
}

/* A killed goniod leaves its socket file behind: the next one replaces it. */
static void test_stale_socket(struct rigenv *e)
{
        rigenv_crash_daemon(e);
        json_decref(ctl_ok(e, "status", NULL));
}

static void test_regular_file(struct rigenv *e)
{
        char path[400], err[8192], buf[32] = "";
        char *argv[] = {(char *)e->goniod, "--rig", e->rig, "--socket", path,
                        "--data",          e->data, NULL};
        FILE *f;

        snprintf(path, sizeof(path), "%s/notes.txt", e->dir);
        CHECK((f = fopen(path, "we")) && fputs("precious", f) >= 0 && fclose(f) == 0);
        CHECK(run_capture(argv, NULL, 0, err, sizeof(err)) != 0);
        CHECK_STR_CONTAINS(err, "exists and is not a socket");
        CHECK((f = fopen(path, "re")) && fgets(buf, sizeof(buf), f) && fclose(f) == 0);
        CHECK_STR(buf, "precious");
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 4);
        signal(SIGPIPE, SIG_IGN);
        rigenv_start(&e, argv, 1);
        json_decref(ctl_ok(&e, "home", NULL));
        test_rude_clients(&e);
        test_second_daemon(&e);
        test_stale_socket(&e);
        test_regular_file(&e);
        rigenv_stop(&e);
        return 0;
}
