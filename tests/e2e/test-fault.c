/* test-fault.c - device faults through the whole stack: a drive that stalls and a
 * relay module that stops answering, injected into gonio-sim. goniod must report
 * the fault, bring the rig to its safe state (motion stopped, lamps and laser off),
 * refuse to move until the fault is cleared, and then work again. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "dataset/ds.h"
#include "harness.h"
#include "tests/test.h"

static bool switch_on(json_t *st, const char *name)
{
        json_t *l;
        size_t i;

        if (strcmp(name, "laser") == 0)
                return json_is_true(json_object_get(json_object_get(st, "laser"), "on"));
        json_array_foreach(json_object_get(st, "lamps"), i,
                           l) if (strcmp(json_string_value(json_object_get(l, "name")), name) ==
                                  0) return json_is_true(json_object_get(l, "on"));
        return false;
}

/* Waits until every lamp and the laser report off. */
static void wait_all_off(struct rigenv *e)
{
        for (double end = now_s() + 10; now_s() < end; usleep(50000)) {
                json_t *st = ctl_ok(e, "status", NULL);
                bool any =
                        switch_on(st, "lamp0") || switch_on(st, "lamp1") || switch_on(st, "laser");
                json_decref(st);
                if (!any)
                        return;
        }
        CHECK(!"lamps and laser did not go off after the fault");
}

static void test_stall(struct rigenv *e)
{
        json_t *st;

        json_decref(ctl_ok(e, "lamp", "lamp0", "on", NULL));
        json_decref(ctl_ok(e, "laser", "on", NULL));
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":1,\"fault\":\"stall\"}\n");
        CHECK_INT(ctl(e, NULL, "move", "turntable", "170", NULL), 5); /* device fault */
        st = wait_state(e, "fault", 10);
        CHECK_STR(json_string_value(json_object_get(json_object_get(st, "fault"), "device")),
                  "turntable");
        json_decref(st);
        wait_all_off(e);
        CHECK_INT(ctl(e, NULL, "move", "camera_arm", "10", NULL), 9); /* refused while faulted */
        CHECK_INT(ctl(e, NULL, "lamp", "lamp0", "on", NULL), 9);
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":1,\"fault\":\"none\"}\n");
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        json_decref(wait_state(e, "idle", 5));
        json_decref(ctl_ok(e, "move", "turntable", "30", NULL));
}

static void test_relay_timeout(struct rigenv *e)
{
        json_t *st;
        char *text;

        sim_request(e,
                    "{\"cmd\":\"inject\",\"bus\":\"relays\",\"unit\":10,\"fault\":\"timeout\"}\n");
        CHECK_INT(ctl(e, NULL, "lamp", "lamp1", "on", NULL), 5);
        st = wait_state(e, "fault", 10);
        CHECK_STR(json_string_value(json_object_get(json_object_get(st, "fault"), "device")),
                  "lamp1");
        json_decref(st);
        CHECK_INT(ctl(e, &st, "doctor", NULL), 5); /* gonioctl doctor names the fault */
        text = json_dumps(st, 0);
        CHECK_STR_CONTAINS(text, "fault on lamp1");
        free(text);
        json_decref(st);
        /* the fault persists while the module is silent; only the admin socket can lift it
         * (gonioctl fault override finds it beside the control socket) */
        CHECK(ctl(e, NULL, "fault", "clear", NULL) != 0);
        setenv("GONIO_ADMIN_SOCKET", e->sock, 1); /* the operator socket: refused */
        CHECK_INT(ctl(e, NULL, "fault", "override", NULL), 9);
        unsetenv("GONIO_ADMIN_SOCKET");
        json_decref(ctl_ok(e, "fault", "override", NULL));
        json_decref(wait_state(e, "idle", 5));
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"relays\",\"unit\":10,\"fault\":\"none\"}\n");
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        json_decref(ctl_ok(e, "lamp", "lamp1", "on", NULL));
        st = ctl_ok(e, "status", NULL);
        CHECK(switch_on(st, "lamp1"));
        json_decref(st);
}

/* A full disk: the capture fails with a storage error, the rig goes to its safe state,
 * nothing torn is left, and after space is freed the dataset goes on. Needs root for a
 * small tmpfs: returns TEST_SKIP without one, else 0. */
static int test_full_disk(struct rigenv *e)
{
        char path[400], cmd[600];
        struct ds *d = NULL;
        json_t *st;
        int r = 0, i;

        snprintf(cmd, sizeof(cmd), "mkdir -p %s && mount -t tmpfs -o size=600k tmpfs %s", e->data,
                 e->data);
        if (system(cmd) != 0) {
                fprintf(stderr, "full-disk case skipped: cannot mount a tmpfs\n");
                return TEST_SKIP;
        }
        json_decref(ctl_ok(e, "dataset", "create", "full", NULL));
        json_decref(ctl_ok(e, "lamp", "lamp0", "on", NULL));
        for (i = 0; i < 200 && (r = ctl(e, NULL, "capture", NULL)) == 0; i++)
                ;
        CHECK_INT(r, 7); /* storage error */
        st = wait_state(e, "fault", 10);
        CHECK_STR(json_string_value(json_object_get(json_object_get(st, "fault"), "device")),
                  "dataset");
        json_decref(st);
        wait_all_off(e);
        snprintf(path, sizeof(path), "%s/full", e->data);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK(ds_count(d) > 0);
        CHECK_INT(ds_verify(d), 0); /* every row has its whole file */
        ds_close(d);
        snprintf(cmd, sizeof(cmd), "mount -o remount,size=8m %s", e->data);
        CHECK(system(cmd) == 0);
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        json_decref(ctl_ok(e, "capture", NULL));
        json_decref(ctl_ok(e, "dataset", "close", NULL));
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_verify(d), 0);
        ds_close(d);
        snprintf(cmd, sizeof(cmd), "umount %s", e->data);
        CHECK(system(cmd) == 0);
        return 0;
}

/* The drives' RS-485 adapter is pulled out during a move and put back: goniod faults
 * naming the line, stops nothing it cannot reach but marks the drives closed, refuses to
 * clear while the port is gone, and reopens the new port once it is back. */
static void test_unplug(struct rigenv *e)
{
        json_t *st;

        json_decref(ctl_ok(e, "move", "--no-wait", "turntable", "170", NULL));
        sim_request(e, "{\"cmd\":\"unplug\",\"bus\":\"drives\",\"ms\":1500}\n");
        st = wait_state(e, "fault", 10);
        CHECK(!json_is_true(
                json_object_get(json_array_get(json_object_get(st, "axes"), 0), "open")));
        json_decref(st);
        CHECK(ctl(e, NULL, "fault", "clear", NULL) != 0); /* the port is still gone */
        usleep(1600 * 1000);
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        st = wait_state(e, "idle", 5);
        CHECK(json_is_true(
                json_object_get(json_array_get(json_object_get(st, "axes"), 0), "open")));
        json_decref(st);
        json_decref(ctl_ok(e, "move", "turntable", "20", NULL));
}

int main(int argc, char **argv)
{
        struct rigenv e;

        int r = 0;

        /* goniod gonioctl gonio-sim [full-disk]: the full-disk case is its own meson test,
         * so that it can be reported as skipped */
        CHECK(argc == 4 || (argc == 5 && strcmp(argv[4], "full-disk") == 0));
        rigenv_start(&e, argv, 10);
        json_decref(ctl_ok(&e, "home", NULL));
        if (argc == 5) {
                r = test_full_disk(&e);
        } else {
                test_stall(&e);
                test_relay_timeout(&e);
                test_unplug(&e);
        }
        rigenv_stop(&e);
        return r;
}
