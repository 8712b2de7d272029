/* test-safety.c - the laser and lamp safety rules of goniod (docs/goniod.md, "Safety"),
 * checked on gonio-sim's relay coils, not on goniod's word: a switch goes off after its
 * max_on_s, counted from when it went on; where the rig file says off_on_disconnect (a
 * laser's default), when the client that switched it on outside a session disconnects, while
 * what another client switched on stays on; `gonioctl laser on` holds the laser on while it
 * runs, and it goes off when gonioctl is killed, ends at SIGTERM, or after --for. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "harness.h"
#include "tests/test.h"

/* Whether gonio-sim has lamp i (or the laser, i < 0) on. */
static bool sim_on(struct rigenv *e, int i)
{
        json_t *r = sim_query(e, "{\"cmd\":\"state\"}\n"), *st = json_object_get(r, "state");
        bool on = json_is_true(json_array_get(json_object_get(st, i < 0 ? "lasers" : "lamps"),
                                              i < 0 ? 0 : (size_t)i));

        json_decref(r);
        return on;
}

/* Seconds until gonio-sim has switch i off, at most timeout (else the test fails). */
static double wait_off(struct rigenv *e, int i, double timeout)
{
        double t0 = now_s();

        while (sim_on(e, i)) {
                CHECK(now_s() - t0 < timeout);
                usleep(20000);
        }
        return now_s() - t0;
}

/* Switches lamp i (or the laser, i < 0) on over the raw connection fd, checked on the
 * coil. */
static void raw_on(struct rigenv *e, int fd, int i)
{
        char req[160];
        json_t *r;

        if (i < 0)
                snprintf(req, sizeof(req),
                         "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"laser.set\",\"params\":"
                         "{\"on\":true}}\n");
        else
                snprintf(req, sizeof(req),
                         "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"lamp.set\",\"params\":"
                         "{\"lamp\":%d,\"on\":true}}\n",
                         i);
        r = raw_call(fd, req);
        CHECK(json_object_get(r, "result") != NULL);
        json_decref(r);
        CHECK(sim_on(e, i));
}

/* The laser (max_on_s 1) and lamp0 (2) go off on their own, the connection kept open, at
 * their limits; lamp1 (the default: an hour) stays on. */
static void test_max_on(char **argv)
{
        char *a = rig_insert(NULL, "laser: { name: laser, ", "max_on_s: 1, ");
        char *rig = rig_insert(a, "name: lamp0, ", "max_on_s: 2, ");
        struct rigenv e;
        double t0, t_laser, t_lamp;
        int fd;

        rigenv_start_rig(&e, argv, 10, rig);
        fd = raw_connect(&e);
        t0 = now_s();
        raw_on(&e, fd, -1);
        raw_on(&e, fd, 0);
        raw_on(&e, fd, 1);
        t_laser = now_s() - t0 + wait_off(&e, -1, 5);
        t_lamp = now_s() - t0 + wait_off(&e, 0, 5);
        fprintf(stderr, "laser off after %.2f s (max_on_s 1), lamp0 after %.2f s (2)\n", t_laser,
                t_lamp);
        CHECK(t_laser >= 0.9 && t_lamp >= 1.9);
        CHECK(sim_on(&e, 1));
        close(fd);
        rigenv_stop(&e);
        free(rig);
        free(a);
}

/* The laser (off_on_disconnect by default) and lamp1 (set) go off when the client that
 * switched them on goes, not before; lamp0, switched on by a client still there, stays on,
 * and stays on after that client goes too (it has no off_on_disconnect). */
static void test_disconnect(char **argv)
{
        char *a = rig_replace(NULL, RIG_LASER_ONE_SHOT, "");
        char *rig = rig_insert(a, "name: lamp1, ", "off_on_disconnect: true, ");
        struct rigenv e;
        int one, two;

        rigenv_start_rig(&e, argv, 10, rig);
        one = raw_connect(&e);
        two = raw_connect(&e);
        raw_on(&e, one, -1);
        raw_on(&e, one, 1);
        raw_on(&e, two, 0);
        usleep(300 * 1000); /* nothing changes while both stay */
        CHECK(sim_on(&e, -1) && sim_on(&e, 1) && sim_on(&e, 0));
        close(one);
        fprintf(stderr, "after the client left: laser off in %.2f s, lamp1 in %.2f s\n",
                wait_off(&e, -1, 3), wait_off(&e, 1, 3));
        CHECK(sim_on(&e, 0));
        close(two); /* lamp0 has no off_on_disconnect: it stays on */
        usleep(300 * 1000);
        CHECK(sim_on(&e, 0));
        rigenv_stop(&e);
        free(rig);
        free(a);
}

/* Starts gonioctl laser on (in hold mode) with extra (NULL or an option) and waits until
 * gonio-sim has the laser on; returns gonioctl's pid. */
static pid_t hold_laser(struct rigenv *e, const char *extra)
{
        pid_t pid = fork();
        double t0 = now_s();

        CHECK(pid >= 0);
        if (pid == 0) {
                execl(e->gonioctl, e->gonioctl, "--socket", e->sock, "laser", "on", extra,
                      (char *)NULL);
                _exit(127);
        }
        while (!sim_on(e, -1)) {
                CHECK(now_s() - t0 < 5);
                usleep(20000);
        }
        return pid;
}

/* gonioctl's exit status after sig (0: none sent), or -1 when it died by a signal. */
static int reap(pid_t pid, int sig)
{
        int st = 0;

        if (sig)
                CHECK_INT(kill(pid, sig), 0);
        CHECK_INT(waitpid(pid, &st, 0), pid);
        return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Held on while gonioctl runs; off when it is killed outright (goniod sees the connection
 * close) and when SIGTERM ends it (it switches the laser off itself and exits 0). */
static void test_hold_kill(char **argv)
{
        char *rig = rig_replace(NULL, RIG_LASER_ONE_SHOT, "");
        struct rigenv e;
        pid_t pid;

        rigenv_start_rig(&e, argv, 10, rig);
        pid = hold_laser(&e, NULL);
        usleep(300 * 1000);
        CHECK(sim_on(&e, -1));
        CHECK_INT(reap(pid, SIGKILL), -1);
        fprintf(stderr, "gonioctl killed: laser off after %.2f s\n", wait_off(&e, -1, 3));
        pid = hold_laser(&e, NULL);
        CHECK_INT(reap(pid, SIGTERM), 0);
        CHECK(!sim_on(&e, -1)); /* off before gonioctl exited */
        rigenv_stop(&e);
        free(rig);
}

/* --for 1: on for about a second, then gonioctl switches it off and exits 0 (on the test rig,
 * whose laser has off_on_disconnect: false, so that the off is gonioctl's own, not goniod's
 * when gonioctl leaves). Held with --for and switched off by another client: gonioctl says
 * so and exits 10. */
static void test_hold_for(char **argv)
{
        struct rigenv e;
        double t0, t;
        pid_t pid;
        int fd;

        rigenv_start(&e, argv, 10);
        t0 = now_s();
        pid = hold_laser(&e, "--for=1");
        t = now_s() - t0 + wait_off(&e, -1, 4);
        fprintf(stderr, "laser on --for 1: off after %.2f s\n", t);
        CHECK(t >= 0.9 && t < 2.5);
        CHECK_INT(reap(pid, 0), 0);
        pid = hold_laser(&e, "--for=30");
        fd = raw_connect(&e);
        json_decref(raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"laser.set\","
                                 "\"params\":{\"on\":false}}\n"));
        CHECK_INT(reap(pid, 0), 10);
        close(fd);
        rigenv_stop(&e);
}

int main(int argc, char **argv)
{
        CHECK(argc == 5);
        if (!strcmp(argv[4], "max-on"))
                test_max_on(argv);
        else if (!strcmp(argv[4], "disconnect"))
                test_disconnect(argv);
        else if (!strcmp(argv[4], "hold-kill"))
                test_hold_kill(argv);
        else if (!strcmp(argv[4], "hold-for"))
                test_hold_for(argv);
        else
                CHECK(!"unknown case");
        return 0;
}
