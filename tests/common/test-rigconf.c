/* test-rigconf.c - the rig file loader: the example rig loads with the values
 * written in it, and each kind of mistake is refused with file, line and key. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "common/rigconf.h"
#include "tests/test.h"

static void test_example_rig(const char *path)
{
        struct rig_config *rc = NULL;
        char err[512];
        int r;

        setenv("GONIO_SIM_DIR", "/tmp/simdir", 1);
        r = rigconf_load(path, &rc, err, sizeof(err));
        if (r < 0)
                fprintf(stderr, "%s\n", err);
        CHECK_INT(r, 0);
        CHECK_INT(rc->n_axes, 3);
        CHECK_INT(rc->n_lamps, 4);
        CHECK_INT(rc->n_cameras, 2);
        CHECK(rc->has_laser);
        CHECK(rc->axes[0].continuous);
        CHECK_NEAR(rc->axes[2].min_deg, -170, 0);
        CHECK_NEAR(rc->lamps[3].elevation_deg, 75, 0);
        CHECK_INT(rc->laser.coil, 7);
        CHECK(strcmp(rc->buses[0].port, "/tmp/simdir/drives") == 0);
        CHECK(rigconf_profile(rc, "gonio-default") != NULL);
        CHECK(rigconf_scene(rc) != NULL);
        CHECK_NEAR(rc->cameras[0].dist[0], -0.08, 1e-12);
        rigconf_free(rc);
}

/* Writes text to a temp file and expects the loader to fail with msg in the error. */
static void expect_error(const char *text, const char *msg)
{
        char path[] = "/tmp/gonio-rigconf-XXXXXX";
        struct rig_config *rc = NULL;
        char err[512] = "";
        int fd = mkstemp(path);
        int r;

        CHECK(fd >= 0);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        close(fd);
        r = rigconf_load(path, &rc, err, sizeof(err));
        unlink(path);
        if (r != -EINVAL || !strstr(err, msg))
                fprintf(stderr, "for:\n%s\ngot %d: %s\n", text, r, err);
        CHECK_INT(r, -EINVAL);
        CHECK_STR_CONTAINS(err, path);
        CHECK_STR_CONTAINS(err, msg);
        CHECK(rc == NULL);
}

#define BUS "rig: t\nbuses:\n  - { name: b, type: modbus-rtu, port: /dev/null }\n"

static void test_errors(void)
{
        expect_error("rig: [unclosed\n", "YAML syntax error");
        expect_error("rig: t\nfoo: 1\n", ":2: key 'foo': unknown key");
        expect_error("buses: []\n", "key 'rig': required key is missing");
        expect_error(BUS "axes:\n  - name: a\n    backend: modbus\n    bus: nope\n",
                     ":7: key 'bus': axes 'a': no bus named 'nope'");
        expect_error(BUS "axes:\n  - { name: a, backend: modbus, bus: b, max_speed: fast }\n",
                     ":5: key 'max_speed': 'fast' is not a number");
        expect_error(BUS "axes:\n  - { name: a, backend: modbus, bus: b, unit: 300 }\n",
                     "key 'unit': 300 is out of range");
        expect_error(BUS "axes:\n  - { name: a, backend: modbus, bus: b, limits: [10, -10] }\n",
                     "key 'limits': need min < max");
        expect_error(BUS "lamps:\n  - { name: a, backend: modbus-coil, bus: b, elevation: 1 }\n"
                         "  - { name: a, backend: modbus-coil, bus: b, elevation: 2 }\n",
                     "device name 'a' is used twice");
        expect_error("rig: t\nbuses:\n  - { name: b, type: can }\n", "'can' is not a bus type");
        expect_error(BUS "cameras:\n  - { name: c, backend: sim, bus: b }\n",
                     "bus 'b' is of the wrong type");
}

int main(int argc, char **argv)
{
        CHECK(argc == 2);
        test_example_rig(argv[1]);
        test_errors();
        return 0;
}
