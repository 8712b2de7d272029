/* test-azd.c - goniod end to end on a sim rig whose turntable is an Oriental Motor AZ drive
 * (the built-in "azd" register profile, docs/modbus-profile.md) beside a gonio-default
 * camera arm on the same RS-485 line: home, moves, a capture whose row matches what gonio-sim
 * rendered, then a stall (alarm 0x10) that goniod reports as a fault of the turntable, brings
 * the rig to its safe state and clears with "fault clear" (ALM-RST), after which the
 * turntable moves again. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "common/pose.h"
#include "harness.h"
#include "tests/test.h"

static const char *const azd_rig =
        "rig: azd\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\", timeout_ms: 300 "
        "}\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\" }\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1, profile: azd, scale: 1000 },\n"
        "      continuous: true, max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3 }, limits: [-170, 170],\n"
        "      max_speed: 30, accel: 60, settle_ms: 20 }\n"
        "lamps:\n"
        "  - { name: top, modbus-coil: { bus: relays, unit: 10, coil: 0 }, elevation: 60,\n"
        "      radius: 450, intensity: 2.0e6 }\n"
        "cameras:\n"
        "  - { name: cam, sim: { bus: frames }, elevation: 20, distance: 500,\n"
        "      target: [0, 0, 30], width: 96, height: 64, fx: 200, fy: 200 }\n"
        "scene:\n"
        "  object: { shape: sphere, size: 60, pose: { translate: [40, 0, 30] } }\n";

static void test_capture(struct rigenv *e)
{
        json_decref(ctl_ok(e, "home", NULL));
        json_decref(ctl_ok(e, "move", "turntable", "270", NULL)); /* the short way: -90 */
        json_decref(ctl_ok(e, "move", "camera_arm", "20", NULL));
        CHECK(fabs(sim_axis_deg(e, "turntable") - 270.0) <= POSE_TOL_DEG);
        json_decref(ctl_ok(e, "lamp", "top", "on", NULL));
        json_decref(ctl_ok(e, "dataset", "create", "azd", NULL));
        json_decref(ctl_ok(e, "capture", NULL));
        CHECK_INT(check_dataset_roles(e, "azd", 1u << GN_ROLE_TURNTABLE | 1u << GN_ROLE_CAMERA_ARM),
                  1);
}

static void test_stall(struct rigenv *e)
{
        json_t *st, *fault;
        double at;

        sim_request(e, "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":1,\"fault\":\"stall\"}\n");
        CHECK_INT(ctl(e, NULL, "move", "turntable", "100", NULL), 5); /* device fault */
        st = wait_state(e, "fault", 10);
        fault = json_object_get(st, "fault");
        print_json("fault", fault);
        CHECK_STR(json_string_value(json_object_get(fault, "device")), "turntable");
        CHECK_STR_CONTAINS(json_string_value(json_object_get(fault, "message")),
                           "fault code 16"); /* alarm 0x10, excessive position deviation */
        json_decref(st);
        CHECK_INT(ctl(e, NULL, "lamp", "top", "on", NULL), 9); /* refused while faulted */
        at = sim_axis_deg(e, "turntable");
        CHECK(at > 101.0 && at < 269.0); /* stopped on the way back from 270 to 100 */

        json_decref(ctl_ok(e, "fault", "clear", NULL)); /* ALM-RST */
        json_decref(wait_state(e, "idle", 5));
        json_decref(ctl_ok(e, "move", "turntable", "30", NULL));
        CHECK(fabs(sim_axis_deg(e, "turntable") - 30.0) <= POSE_TOL_DEG);
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 4);
        rigenv_start_rig(&e, argv, 10, azd_rig);
        test_capture(&e);
        test_stall(&e);
        rigenv_stop(&e);
        return 0;
}
