/* test-wait.c - gonioctl wait against goniod on gonio-sim: returns at once in the state,
 * follows a move through moving to idle, ends with exit 10 at --timeout, exit 5 when a fault
 * latches while waiting for idle, and 0 waiting for that fault; goniod's errors under --json
 * as error objects with the JSON-RPC code; the bash completion's device names from goniod's
 * describe (issue 13).
 * Usage: test-e2e-wait GONIOD GONIOCTL GONIO_SIM COMPLETION */
#include <jansson.h>

#include "tests/e2e/harness.h"
#include "tests/test.h"

/* Runs gonioctl wait ARGS...: checks the exit code and, for exit 0, the state it printed. */
static void wait_for(struct rigenv *e, int want, const char *state, const char *timeout)
{
        json_t *out = NULL;
        int r = ctl(e, &out, "--timeout", timeout, "wait", "--state", state, NULL);

        if (r != want)
                fprintf(stderr, "wait --state %s --timeout %s: exit %d\n", state, timeout, r);
        CHECK_INT(r, want);
        if (want == 0)
                CHECK_STR(json_string_value(json_object_get(out, "state")), state);
        json_decref(out);
}

static double position(struct rigenv *e, const char *axis)
{
        json_t *st = ctl_ok(e, "status", NULL), *ax;
        double pos = NAN;
        size_t i;

        json_array_foreach(json_object_get(st, "axes"), i,
                           ax) if (strcmp(json_string_value(json_object_get(ax, "name")), axis) ==
                                   0) pos = json_number_value(json_object_get(ax, "position"));
        json_decref(st);
        return pos;
}

/* A move of the camera arm (30 deg/s, so about 1 s at time scale 5) followed by wait. */
static void test_move(struct rigenv *e)
{
        json_t *out = NULL, *err;
        double t0;

        json_decref(ctl_ok(e, "home", NULL));
        wait_for(e, 0, "idle", "5");
        json_decref(ctl_ok(e, "move", "camera_arm", "150", "--no-wait", NULL));
        wait_for(e, 0, "moving", "5");
        /* --timeout while it moves: exit 10, an error object that says so */
        CHECK_INT(ctl(e, &out, "--timeout", "0.3", "wait", NULL), 10);
        err = json_object_get(out, "error");
        CHECK_STR(json_string_value(json_object_get(err, "code")), "interrupted");
        CHECK_STR(json_string_value(json_object_get(err, "cause")), "timeout");
        CHECK_STR_CONTAINS(json_string_value(json_object_get(err, "message")), "timed out");
        json_decref(out);
        t0 = now_s();
        wait_for(e, 0, "idle", "30");
        CHECK(now_s() - t0 > 0.3); /* it did wait for the move */
        CHECK_NEAR(position(e, "camera_arm"), 150, 0.01);
}

/* An error goniod reports, as an error object with its JSON-RPC code. */
static void test_rpc_error(struct rigenv *e)
{
        json_t *out = NULL, *err;

        CHECK_INT(ctl(e, &out, "move", "camera_arm", "500", NULL), 6);
        err = json_object_get(out, "error");
        CHECK_STR(json_string_value(json_object_get(err, "code")), "invalid");
        CHECK_INT(json_integer_value(json_object_get(err, "exit")), 6);
        CHECK(json_integer_value(json_object_get(err, "rpc_code")) < -32000);
        CHECK_STR_CONTAINS(json_string_value(json_object_get(err, "message")), "move: ");
        json_decref(out);
}

/* A fault while waiting for idle ends the wait with exit 5; waiting for the fault ends. */
static void test_fault(struct rigenv *e)
{
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":1,\"fault\":\"stall\"}\n");
        CHECK_INT(ctl(e, NULL, "move", "turntable", "170", "--no-wait", NULL) == 0 ||
                          ctl(e, NULL, "move", "turntable", "170", NULL) == 5,
                  1);
        wait_for(e, 0, "fault", "20");
        wait_for(e, 5, "idle", "5");
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":1,\"fault\":\"none\"}\n");
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        wait_for(e, 0, "idle", "10");
}

/* What the bash completion (client/gonioctl.bash) offers after "gonioctl --socket S WORDS",
 * with the gonioctl under test first in PATH. Returns the words, malloc'ed. */
static char *complete(struct rigenv *e, const char *completion, const char *words)
{
        char cmd[2048], *out = calloc(1, 1024);
        const char *slash = strrchr(e->gonioctl, '/');
        FILE *p;

        CHECK(out && slash);
        snprintf(cmd, sizeof(cmd),
                 "PATH='%.*s':\"$PATH\" bash -c 'source %s; COMP_WORDS=(gonioctl --socket %s %s);"
                 " COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _gonioctl; echo \"${COMPREPLY[*]}\"'",
                 (int)(slash - e->gonioctl), e->gonioctl, completion, e->sock, words);
        p = popen(cmd, "r");
        CHECK(p);
        CHECK(fgets(out, 1024, p));
        CHECK_INT(pclose(p), 0);
        return out;
}

/* The completion's device names come from goniod: axes after move, lamps after lamp, the
 * settings of a device after set. */
static void test_completion(struct rigenv *e, const char *completion)
{
        char *axes = complete(e, completion, "move \"\""),
             *lamps = complete(e, completion, "lamp l");
        char *cams = complete(e, completion, "capture --camera \"\"");
        char *settings = complete(e, completion, "set turntable.");

        CHECK_STR(axes, "turntable light_arm camera_arm\n");
        CHECK_STR_CONTAINS(lamps, "lamp0");
        CHECK(!strstr(lamps, "laser") && !strstr(lamps, "turntable"));
        CHECK_STR_CONTAINS(cams, "cam");
        CHECK_STR(settings, "turntable.speed turntable.accel\n");
        free(settings);
        free(axes);
        free(lamps);
        free(cams);
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 5);
        rigenv_start(&e, argv, 5);
        test_completion(&e, argv[4]);
        test_move(&e);
        test_rpc_error(&e);
        test_fault(&e);
        rigenv_stop(&e);
        return 0;
}
