/* test-ciclop.c - the Ciclop rig of examples/rigs/ciclop.yaml end to end: gonio-sim emulates
 * its Horus G-code board (turntable + two lasers on one serial line) and renders its webcam;
 * goniod drives it through the gcode and gcode-laser backends; gonioctl homes, turns the
 * table, switches the lasers (both, or one by name: tool 2 is the right one) and captures; every
 * stored row matches what gonio-sim rendered (the render log), and the emulated table ends where
 * goniod says it is; a board that stops answering is a fault goniod clears once it answers again.
 */
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>
#include <string.h>

#include "common/fileio.h"
#include "common/pose.h"
#include "harness.h"
#include "tests/test.h"

/* Half a step of the board's 8.889 steps/deg: where a move can end. */
#define STEP_TOL_DEG 0.057

/* The board stops answering: goniod latches a fault naming a device of the board and the
 * cause, switches the laser off, refuses to clear while the board is silent, and clears
 * once it answers again. */
static void silent_board(struct rigenv *e)
{
        json_t *st, *fault;
        const char *device;
        char *text;

        json_decref(ctl_ok(e, "laser", "on", NULL));
        sim_request(e,
                    "{\"cmd\":\"inject\",\"bus\":\"ciclop\",\"unit\":0,\"fault\":\"timeout\"}\n");
        st = wait_state(e, "fault", 10);
        fault = json_object_get(st, "fault");
        device = json_string_value(json_object_get(fault, "device"));
        CHECK(device && (strcmp(device, "turntable") == 0 || strncmp(device, "laser_", 6) == 0));
        text = json_dumps(fault, JSON_COMPACT);
        CHECK_STR_CONTAINS(text, "within 300 ms");
        free(text);
        json_decref(st);
        CHECK(ctl(e, NULL, "fault", "clear", NULL) != 0);
        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"ciclop\",\"unit\":0,\"fault\":\"none\"}\n");
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        json_decref(wait_state(e, "idle", 5));
        st = sim_query(e, "{\"cmd\":\"state\"}\n"); /* the resync's reset put it off */
        CHECK(json_is_false(json_object_get(json_object_get(st, "state"), "laser")));
        json_decref(st);
}

/* The board's USB cable is pulled and put back: the board reboots and forgets its zero.
 * goniod faults, clears once the port is back, and then knows no turntable angle: rows
 * stored before homing again have none (never the stale one). */
static void unplugged_board(struct rigenv *e)
{
        json_t *st;

        sim_request(e, "{\"cmd\":\"unplug\",\"bus\":\"ciclop\",\"ms\":1500}\n");
        json_decref(wait_state(e, "fault", 10));
        usleep(1700 * 1000);
        json_decref(ctl_ok(e, "fault", "clear", NULL));
        st = ctl_ok(e, "status", NULL);
        CHECK(!json_is_true(
                json_object_get(json_array_get(json_object_get(st, "axes"), 0), "homed")));
        json_decref(st);
        json_decref(ctl_ok(e, "dataset", "create", "after", NULL));
        json_decref(ctl_ok(e, "capture", NULL));
        CHECK_INT(check_dataset_roles(e, "after", 0), 1); /* no angle */
}

/* gonio-sim's lasers (bit set) as its state says. */
static uint32_t sim_lasers(struct rigenv *e)
{
        json_t *sim = sim_query(e, "{\"cmd\":\"state\"}\n"), *v;
        uint32_t bits = 0;
        size_t i;

        json_array_foreach(json_object_get(json_object_get(sim, "state"), "lasers"), i, v) bits |=
                (uint32_t)json_is_true(v) << i;
        json_decref(sim);
        return bits;
}

/* One laser by name (the right one: tool 2, "M71 T2"), then both, then none. */
static void lasers_by_name(struct rigenv *e)
{
        json_decref(ctl_ok(e, "laser", "on", "laser_right", NULL));
        CHECK_INT(sim_lasers(e), 2);
        json_decref(ctl_ok(e, "laser", "on", NULL));
        CHECK_INT(sim_lasers(e), 3);
        json_decref(ctl_ok(e, "laser", "off", "laser_left", NULL));
        CHECK_INT(sim_lasers(e), 2);
        CHECK_INT(ctl(e, NULL, "laser", "on", "laser_middle", NULL), 6);
        json_decref(ctl_ok(e, "laser", "off", NULL));
        CHECK_INT(sim_lasers(e), 0);
}

static char *read_rig(const char *path)
{
        FILE *f = fopen(path, "re");
        char *text = calloc(1, 65536);

        CHECK(f && text);
        CHECK(fread(text, 1, 65535, f) > 0);
        fclose(f);
        return text;
}

/* The rig text with off_on_disconnect: false on both lasers (freed), so that `gonioctl laser
 * on` switches them on and returns rather than holding them on. */
static char *one_shot_lasers(char *rig)
{
        char *a = rig_insert(rig, "  - name: laser_left\n", "    off_on_disconnect: false\n");
        char *b = rig_insert(a, "  - name: laser_right\n", "    off_on_disconnect: false\n");

        free(rig);
        free(a);
        return b;
}

int main(int argc, char **argv)
{
        struct rigenv e;
        char *rig;

        if (argc < 5) {
                fprintf(stderr, "usage: %s GONIOD GONIOCTL GONIO_SIM CICLOP_YAML\n", argv[0]);
                return 2;
        }
        rig = one_shot_lasers(read_rig(argv[4]));
        rigenv_start_rig(&e, argv, 10.0, rig);
        json_decref(ctl_ok(&e, "home", NULL));
        json_decref(ctl_ok(&e, "dataset", "create", "scan", NULL));
        json_decref(ctl_ok(&e, "move", "turntable", "90", NULL));
        CHECK_NEAR(sim_axis_deg(&e, "turntable"), 90.0, STEP_TOL_DEG);
        json_decref(ctl_ok(&e, "laser", "on", NULL));
        json_decref(ctl_ok(&e, "capture", NULL));
        json_decref(ctl_ok(&e, "move", "turntable", "300", NULL)); /* back 150 deg */
        CHECK_NEAR(sim_axis_deg(&e, "turntable"), 300.0, STEP_TOL_DEG);
        json_decref(ctl_ok(&e, "capture", NULL));
        json_decref(ctl_ok(&e, "laser", "off", NULL));
        json_decref(ctl_ok(&e, "capture", NULL));
        CHECK_INT(check_dataset_roles(&e, "scan", 1u << GN_ROLE_TURNTABLE), 3);
        lasers_by_name(&e);
        silent_board(&e);
        json_decref(ctl_ok(&e, "move", "turntable", "45", NULL)); /* still homed */
        CHECK_NEAR(sim_axis_deg(&e, "turntable"), 45.0, STEP_TOL_DEG);
        json_decref(ctl_ok(&e, "capture", NULL));
        CHECK_INT(check_dataset_roles(&e, "scan", 1u << GN_ROLE_TURNTABLE), 4);
        unplugged_board(&e);
        rigenv_stop(&e);
        free(rig);
        return 0;
}
