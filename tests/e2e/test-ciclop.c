/* test-ciclop.c - the Ciclop rig of examples/rigs/ciclop.yaml end to end: gonio-sim emulates
 * its Horus G-code board (turntable + laser on one serial line) and renders its webcam;
 * goniod drives it through the gcode and gcode-laser backends; gonioctl homes, turns the
 * table, switches the laser and captures; every stored row matches what gonio-sim
 * rendered (the render log), and the emulated table ends where goniod says it is. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"
#include "common/pose.h"
#include "harness.h"
#include "tests/test.h"

/* Half a step of the board's 8.889 steps/deg: where a move can end. */
#define STEP_TOL_DEG 0.057

static double sim_turntable(struct rigenv *e)
{
        json_t *sim = sim_query(e, "{\"cmd\":\"state\"}\n");
        double deg = json_number_value(json_object_get(json_object_get(sim, "state"), "turntable"));

        json_decref(sim);
        return deg;
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

int main(int argc, char **argv)
{
        struct rigenv e;
        char *rig;

        if (argc < 5) {
                fprintf(stderr, "usage: %s GONIOD GONIOCTL GONIO_SIM CICLOP_YAML\n", argv[0]);
                return 2;
        }
        rig = read_rig(argv[4]);
        rigenv_start_rig(&e, argv, 10.0, rig);
        json_decref(ctl_ok(&e, "home", NULL));
        json_decref(ctl_ok(&e, "dataset", "create", "scan", NULL));
        json_decref(ctl_ok(&e, "move", "turntable", "90", NULL));
        CHECK_NEAR(sim_turntable(&e), 90.0, STEP_TOL_DEG);
        json_decref(ctl_ok(&e, "laser", "on", NULL));
        json_decref(ctl_ok(&e, "capture", NULL));
        json_decref(ctl_ok(&e, "move", "turntable", "300", NULL)); /* back 150 deg */
        CHECK_NEAR(sim_turntable(&e), 300.0, STEP_TOL_DEG);
        json_decref(ctl_ok(&e, "capture", NULL));
        json_decref(ctl_ok(&e, "laser", "off", NULL));
        json_decref(ctl_ok(&e, "capture", NULL));
        CHECK_INT(check_dataset_roles(&e, "scan", 1u << GN_ROLE_TURNTABLE), 3);
        rigenv_stop(&e);
        free(rig);
        return 0;
}
