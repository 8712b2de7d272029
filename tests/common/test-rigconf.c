/* test-rigconf.c - the rig file loader: the example rig loads with the values written in
 * it, and each kind of mistake is refused with file, line and key: unknown keys in every
 * kind of entry and in every backend's map, backend maps missing, doubled, misplaced or
 * naming an unknown profile, two devices on one Modbus address, two buses on one port,
 * unset environment variables, duplicate names, axis roles, camera control ranges; a
 * `lasers:` list (the one `laser:` mapping is its shorthand) and its mistakes; the limits of
 * the device settings (max_accel, max_exposure_us, max_gain) and off_on_disconnect's
 * defaults.
 * Usage: test-rigconf EXAMPLE-RIG CASE; an unknown CASE fails. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "common/rigconf.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/camera/sim/api.h"
#include "drivers/registry.h"
#include "drivers/switch/modbus/proto.h"
#include "tests/test.h"

static const char *example_path;
/* The backend table loads use: gonio's, unless a case swaps in its own. */
static const struct rig_backend *const *backends = registry_backends;

/* Loads text from a temporary file; *path gets the file's name (already removed). */
static int load_text(const char *text, struct rig_config **rc, char *err, size_t errlen,
                     char path[static 32])
{
        int fd, r;

        snprintf(path, 32, "/tmp/gonio-rigconf-XXXXXX");
        fd = mkstemp(path);
        CHECK(fd >= 0);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        close(fd);
        err[0] = 0;
        r = rigconf_load(path, backends, rc, err, errlen);
        unlink(path);
        return r;
}

/* Loads text and expects success. Free the result with rigconf_free. */
static struct rig_config *expect_ok(const char *text)
{
        struct rig_config *rc = NULL;
        char err[512], path[32];
        int r = load_text(text, &rc, err, sizeof(err), path);

        if (r < 0)
                fprintf(stderr, "for:\n%s\ngot %d: %s\n", text, r, err);
        CHECK_INT(r, 0);
        return rc;
}

/* Expects the load to fail with "FILE:LINE: key 'KEY': " followed by text containing msg. */
static void expect_at(const char *text, int line, const char *key, const char *msg)
{
        struct rig_config *rc = NULL;
        char err[512], path[32], want[128];
        int r = load_text(text, &rc, err, sizeof(err), path);

        snprintf(want, sizeof(want), "%s:%d: key '%s': ", path, line, key);
        if (r != -EINVAL || strncmp(err, want, strlen(want)) != 0 || !strstr(err, msg))
                fprintf(stderr, "for:\n%s\nwant %s...%s\ngot %d: %s\n", text, want, msg, r, err);
        CHECK_INT(r, -EINVAL);
        CHECK(strncmp(err, want, strlen(want)) == 0);
        CHECK_STR_CONTAINS(err, msg);
        CHECK(rc == NULL);
}

/* Lines 1-3: a rig with one RTU bus 'b' and one sim bus 'f'. */
#define BUS                                                                                        \
        "rig: t\nbuses:\n  - { name: b, type: modbus-rtu, port: /dev/null }\n"                     \
        "  - { name: f, type: sim, port: /tmp/f.sock }\n"
#define AXIS(name, unit) "  - { name: " name ", modbus: { bus: b, unit: " unit " } }\n"
#define LAMP(name, unit, coil)                                                                     \
        "  - { name: " name ", elevation: 1, modbus-coil: { bus: b, unit: " unit ", coil: " coil   \
        " } }\n"

static void case_example(void)
{
        struct rig_config *rc = NULL;
        char err[512];
        int r;

        setenv("GONIO_SIM_DIR", "/tmp/simdir", 1);
        r = rigconf_load(example_path, registry_backends, &rc, err, sizeof(err));
        if (r < 0)
                fprintf(stderr, "%s\n", err);
        CHECK_INT(r, 0);
        CHECK_INT(rc->n_axes, 3);
        CHECK_INT(rc->n_lamps, 4);
        CHECK_INT(rc->n_cameras, 2);
        CHECK(rc->n_lasers);
        CHECK(rc->axes[0].continuous);
        CHECK_NEAR(rc->axes[2].min_deg, -170, 0);
        CHECK_NEAR(rc->lamps[3].elevation_deg, 75, 0);
        CHECK_STR(rc->lasers[0].backend.name, "modbus-coil");
        CHECK_INT(((const struct mbsw_conf *)rc->lasers[0].backend.conf)->coil, 7);
        CHECK_INT(((const struct mbsw_conf *)rc->lasers[0].backend.conf)->unit, 10);
        CHECK_STR(rc->axes[1].backend.name, "modbus");
        CHECK_STR(rc->axes[1].bus, "drives");
        CHECK_INT(((const struct mbax_conf *)rc->axes[1].backend.conf)->unit, 2);
        CHECK(((const struct mbax_conf *)rc->axes[1].backend.conf)->profile ==
              rigconf_profile(rc, "gonio-default"));
        CHECK_STR(rc->cameras[1].backend.name, "sim");
        CHECK_STR(rc->cameras[1].bus, "frames");
        CHECK_STR(rc->buses[0].port, "/tmp/simdir/drives");
        CHECK(rigconf_profile(rc, "gonio-default") != NULL);
        CHECK(rigconf_scene(rc) != NULL);
        CHECK_NEAR(rc->cameras[0].dist[0], -0.08, 1e-12);
        for (int i = 0; i < GN_ROLE_COUNT; i++)
                CHECK_INT(rigconf_axis_of_role(rc, i), i);
        rigconf_free(rc);
}

static void case_errors(void)
{
        struct rig_config *rc = NULL;
        char err[512], path[32];

        CHECK_INT(load_text("rig: [unclosed\n", &rc, err, sizeof(err), path), -EINVAL);
        CHECK_STR_CONTAINS(err, "YAML syntax error");
        expect_at("buses: []\n", 1, "rig", "required key is missing");
        expect_at(BUS "axes:\n  - name: a\n    modbus:\n      bus: nope\n", 8, "bus",
                  "axes 'a': no bus named 'nope'");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, max_speed: fast }\n", 6,
                  "max_speed", "'fast' is not a number");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b, unit: 300 } }\n", 6, "unit",
                  "300 is out of range");
        expect_at(BUS "lamps:\n  - { name: l, elevation: 1, modbus-coil: { bus: b, coil: -1 } }\n",
                  6, "coil", "-1 is out of range");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, limits: [10, -10] }\n", 6,
                  "limits", "need min < max");
        rc = expect_ok("rig: t\nbuses:\n  - { name: l, type: local }\n"); /* no port */
        CHECK(rc->buses[0].type == RIG_BUS_LOCAL);
        CHECK_STR(rigconf_bus_type_name(rc->buses[0].type), "local");
        rigconf_free(rc);
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, move_retries: 2 }\n", 6,
                  "move_retries", "retries need a deadband > 0");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, backlash: 45 }\n", 6, "backlash",
                  "");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, continuous: true,\n"
                      "      direction: sideways }\n",
                  7, "direction", "'sideways': shortest, positive or negative");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, direction: positive }\n", 6,
                  "direction", "only a continuous axis");
        expect_at("rig: t\nbuses:\n  - { name: b, type: can }\n", 3, "type",
                  "'can' is not a bus type");
        expect_at(BUS "cameras:\n  - { name: c, sim: { bus: b } }\n", 6, "bus",
                  "bus 'b' is of the wrong type (modbus-rtu; backend 'sim' does not run on it)");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: f } }\n", 6, "bus",
                  "bus 'f' is of the wrong type (sim; backend 'modbus' does not run on it)");
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b, profile: nope } }\n", 6, "profile",
                  "no register profile named 'nope'");
}

/* A misspelt key in each kind of entry, in block and flow style. */
static const struct {
        const char *kind, *text;
        int line;
        const char *key;
} unknown_keys[] = {
        {"root", "rig: t\nrig_name: x\n", 2, "rig_name"},
        {"profiles", "rig: t\nprofiles:\n  - name: p\n    postion: 3\n", 4, "postion"},
        {"buses", "rig: t\nbuses:\n  - name: b\n    type: modbus-rtu\n    baudrate: 9600\n", 5,
         "baudrate"},
        {"buses", "rig: t\nbuses:\n  - { name: b, type: modbus-tcp, tcp-port: 502 }\n", 3,
         "tcp-port"},
        {"axes", BUS "axes:\n  - name: a\n    modbus: { bus: b }\n    limts: [-9, 9]\n", 8,
         "limts"},
        {"axes", BUS "axes:\n  - { name: a, modbus: { bus: b }, max_sped: 5 }\n", 6, "max_sped"},
        {"lamps", BUS "lamps:\n  - name: l\n    elevaton: 10\n", 7, "elevaton"},
        {"laser", BUS "laser:\n  name: x\n  orgin: [0, 0, 0]\n", 7, "orgin"},
        {"lasers", BUS "lasers:\n  - name: x\n    modbus-coil: { bus: b }\n    azimth: 3\n", 8,
         "azimth"},
        {"cameras", BUS "cameras:\n  - name: c\n    sim: { bus: f }\n    exposure: 100\n", 8,
         "exposure"},
        {"cameras", BUS "cameras:\n  - { name: c, sim: { bus: f }, distorsion: [0, 0] }\n", 6,
         "distorsion"},
        /* inside each backend's map */
        {"modbus", BUS "axes:\n  - name: a\n    modbus:\n      bus: b\n      unti: 2\n", 9, "unti"},
        {"modbus", BUS "axes:\n  - { name: a, modbus: { bus: b, profil: p } }\n", 6, "profil"},
        {"modbus-coil",
         BUS "lamps:\n  - { name: l, elevation: 1, modbus-coil: { bus: b, col: 3 } }\n", 6, "col"},
        {"modbus-coil", BUS "laser:\n  name: x\n  modbus-coil:\n    bus: b\n    cooil: 7\n", 9,
         "cooil"},
        {"sim", BUS "cameras:\n  - name: c\n    sim:\n      bus: f\n      port: /x\n", 9, "port"},
        {"gpio-stepper",
         "rig: t\nbuses: [{ name: g, type: local }]\naxes:\n"
         "  - { name: a, gpio-stepper: { bus: g, chip: c, step: 0, dir: 1, stpe: 2 } }\n",
         4, "stpe"},
        {"gpio",
         "rig: t\nbuses: [{ name: g, type: local }]\nlamps:\n"
         "  - { name: l, elevation: 1, gpio: { bus: g, chip: c, lien: 3 } }\n",
         4, "lien"},
        {"libcamera",
         "rig: t\nbuses: [{ name: u, type: local }]\ncameras:\n"
         "  - { name: c, libcamera: { bus: u, idd: x } }\n",
         4, "idd"},
        {"usbrelay",
         "rig: t\nbuses: [{ name: u, type: local }]\nlamps:\n"
         "  - { name: l, elevation: 1, usbrelay: { bus: u, rely: 2 } }\n",
         4, "rely"},
        {"gcode",
         "rig: t\nbuses:\n  - { name: s, type: serial, port: /dev/null }\n"
         "axes:\n  - { name: a, gcode: { bus: s, axs: Y } }\n",
         5, "axs"},
        {"gcode-laser",
         "rig: t\nbuses:\n  - { name: s, type: serial, port: /dev/null }\n"
         "laser:\n  name: x\n  gcode-laser: { bus: s, tol: 2 }\n",
         6, "tol"},
        {"v4l2",
         "rig: t\nbuses:\n  - { name: l, type: local }\ncameras:\n  - name: c\n    v4l2:\n"
         "      bus: l\n      devce: /dev/video0\n",
         8, "devce"},
};

/* Whether kind names a backend this build has not (one on an optional library). */
static bool optional_and_absent(const char *kind)
{
        static const char *const optional[] = {"gpio-stepper", "gpio", "libcamera", "usbrelay",
                                               "v4l2"};

        for (size_t i = 0; i < ELEMENTSOF(optional); i++)
                if (strcmp(kind, optional[i]) == 0) {
                        for (const struct rig_backend *const *b = registry_backends; *b; b++)
                                if (strcmp((*b)->name, kind) == 0)
                                        return false;
                        return true;
                }
        return false;
}

/* Whether unknown_keys has a row of kind. */
static bool covered(const char *kind)
{
        for (size_t i = 0; i < ELEMENTSOF(unknown_keys); i++)
                if (strcmp(unknown_keys[i].kind, kind) == 0)
                        return true;
        fprintf(stderr, "no unknown-key row for '%s'\n", kind);
        return false;
}

static void case_unknown_keys(void)
{
        static const char *const kinds[] = {"root",  "profiles", "buses",  "axes",
                                            "lamps", "laser",    "lasers", "cameras"};

        for (size_t k = 0; k < ELEMENTSOF(kinds); k++)
                CHECK(covered(kinds[k]));
        for (const struct rig_backend *const *b = registry_backends; *b; b++)
                CHECK(covered((*b)->name)); /* every backend's map, new ones too */
        for (size_t i = 0; i < ELEMENTSOF(unknown_keys); i++)
                if (!optional_and_absent(unknown_keys[i].kind))
                        expect_at(unknown_keys[i].text, unknown_keys[i].line, unknown_keys[i].key,
                                  "unknown key");
        /* a list key given as a mapping is not silently ignored either */
        expect_at(BUS "axes:\n  - name: a\n    modbus: { bus: b }\n"
                      "    limits: { min: -9, max: 9 }\n",
                  8, "limits", "expected a list");
}

static void case_addresses(void)
{
        expect_at(BUS "axes:\n" AXIS("t", "1") AXIS("l", "2") AXIS("c", "1"), 8, "unit",
                  "axis 't' and axis 'c' are both on unit 1 on bus 'b'");
        expect_at(BUS "axes:\n  - { name: t, modbus: { bus: b } }\n" AXIS("c", "1"), 7, "unit",
                  "axis 't' and axis 'c' are both on unit 1"); /* unit 1 by default */
        expect_at(BUS "lamps:\n" LAMP("l0", "10", "0") LAMP("l1", "10", "1") LAMP("l2", "10", "1"),
                  8, "coil", "lamp 'l1' and lamp 'l2' are both on coil 1 of unit 10 on bus 'b'");
        expect_at(BUS "lamps:\n" LAMP("l0", "10", "7") "laser:\n  name: x\n  modbus-coil:\n"
                                                       "    bus: b\n    unit: 10\n    coil: 7\n",
                  12, "coil", "lamp 'l0' and laser 'x' are both on coil 7 of unit 10");
        expect_at(BUS "axes:\n" AXIS("t", "3") "lamps:\n" LAMP("l0", "3", "0"), 8, "unit",
                  "axis 't' and lamp 'l0' are both on unit 3 on bus 'b'");
        expect_at("rig: t\nbuses:\n  - { name: a, type: modbus-rtu, port: /dev/ttyS0 }\n"
                  "  - { name: c, type: modbus-rtu, port: /dev/ttyS1 }\n"
                  "  - { name: b, type: modbus-rtu, port: /dev/ttyS0 }\n",
                  5, "port", "buses 'a' and 'b' both use port '/dev/ttyS0'");
        expect_at("rig: t\nbuses:\n  - { name: a, type: modbus-tcp, host: h, tcp_port: 502 }\n"
                  "  - { name: b, type: modbus-tcp, host: h, tcp_port: 502 }\n",
                  4, "tcp_port", "buses 'a' and 'b' both use h:502");
        /* distinct addresses: same unit and other coils, other units, other buses, other TCP
         * ports, a sim bus and an RTU bus on different paths */
        rigconf_free(expect_ok(
                BUS "  - { name: b2, type: modbus-rtu, port: /dev/zero }\n"
                    "  - { name: t1, type: modbus-tcp, host: h, tcp_port: 502 }\n"
                    "  - { name: t2, type: modbus-tcp, host: h, tcp_port: 503 }\n"
                    "axes:\n" AXIS("t", "1")
                            AXIS("l", "2") "  - { name: c, modbus: { bus: b2, unit: 1 } }\n"
                                           "lamps:\n" LAMP("l0", "10", "0")
                                                   LAMP("l1", "10",
                                                        "1") "laser: { name: x, modbus-coil: { "
                                                             "bus: b, unit: 10, coil: 2 } }\n"));
}

/* A dataset's stored rig file read offline: unset and empty variables stay as written. */
static void case_env_stored(void)
{
        const char *text =
                "rig: \"a${GONIO_TEST_EMPTY}\"\nbuses:\n"
                "  - { name: b, type: modbus-rtu, port: \"${GONIO_TEST_UNSET}/drives\" }\n";
        struct rig_config *rc = NULL;
        char err[512] = "", path[] = "/tmp/gonio-rigconf-XXXXXX";
        int fd = mkstemp(path);

        CHECK(fd >= 0);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        close(fd);
        if (rigconf_load_stored(path, backends, &rc, err, sizeof(err)) < 0)
                fprintf(stderr, "%s\n", err);
        CHECK(rc);
        unlink(path);
        CHECK_STR(rc->name, "a${GONIO_TEST_EMPTY}");
        CHECK_STR(rc->buses[0].port, "${GONIO_TEST_UNSET}/drives");
        rigconf_free(rc);
}

static void case_env(void)
{
        struct rig_config *rc;

        unsetenv("GONIO_TEST_UNSET");
        setenv("GONIO_TEST_EMPTY", "", 1);
        setenv("GONIO_TEST_DIR", "/tmp/d", 1);
        expect_at("rig: t\nbuses:\n  - name: b\n    type: modbus-rtu\n"
                  "    port: ${GONIO_TEST_UNSET}/drives\n",
                  5, "port",
                  "environment variable GONIO_TEST_UNSET is not set (write "
                  "${GONIO_TEST_UNSET:-default} for a default)");
        expect_at("rig: \"a${GONIO_TEST_EMPTY}\"\n", 1, "rig",
                  "environment variable GONIO_TEST_EMPTY is empty");
        expect_at("rig: \"${}\"\n", 1, "rig", "bad variable reference");
        rc = expect_ok("rig: \"${GONIO_TEST_UNSET:-x}${GONIO_TEST_EMPTY:-y}${GONIO_TEST_UNSET:-}"
                       "-${GONIO_TEST_DIR}-${GONIO_TEST_DIR:-z}$HOME{}\"\nbuses:\n"
                       "  - { name: b, type: sim, port: \"${GONIO_TEST_DIR:-/run}/f.sock\" }\n");
        CHECK_STR(rc->name, "xy-/tmp/d-/tmp/d$HOME{}");
        CHECK_STR(rc->buses[0].port, "/tmp/d/f.sock");
        rigconf_free(rc);
        case_env_stored();
}

static void case_duplicates(void)
{
        expect_at(BUS "lamps:\n" LAMP("a", "1", "0") LAMP("z", "1", "1") LAMP("a", "1", "2"), 8,
                  "name", "device name 'a' is used twice (first at line 6)");
        expect_at(BUS "axes:\n" AXIS("a", "1") "cameras:\n  - name: c\n    sim: { bus: f }\n"
                                               "  - sim:\n      bus: f\n    name: a\n",
                  12, "name", "device name 'a' is used twice (first at line 6)");
        expect_at(BUS "laser:\n  modbus-coil: { bus: b }\n  name: a\nlamps:\n" LAMP("a", "1", "1"),
                  9, "name", "device name 'a' is used twice (first at line 7)");
        expect_at("rig: t\nbuses:\n  - { name: b, type: sim, port: /x }\n"
                  "  - { name: b, type: sim, port: /y }\n",
                  4, "name", "bus name 'b' is used twice (first at line 3)");
        expect_at("rig: t\nprofiles:\n  - { name: p }\n  - { name: p, scale: 2 }\n", 4, "name",
                  "profile name 'p' is used twice");
        expect_at("rig: t\nprofiles:\n  - name: gonio-default\n", 3, "name",
                  "profile 'gonio-default' is built in");
}

static void case_roles(void)
{
        struct rig_config *rc =
                expect_ok(BUS "axes:\n" AXIS("turntable", "1") AXIS("light_arm", "2")
                                  AXIS("spare", "3") "  - { name: arm2, modbus: { bus: b, "
                                                     "unit: 4 }, role: camera_arm }\n"
                                                     "  - { name: camera_arm, modbus: { "
                                                     "bus: b, unit: 5 }, role: none }\n");

        CHECK_INT(rc->axes[0].role, GN_ROLE_TURNTABLE);
        CHECK_INT(rc->axes[1].role, GN_ROLE_LIGHT_ARM);
        CHECK_INT(rc->axes[2].role, -1);
        CHECK_INT(rc->axes[3].role, GN_ROLE_CAMERA_ARM);
        CHECK_INT(rc->axes[4].role, -1);
        CHECK_INT(rigconf_axis_of_role(rc, GN_ROLE_CAMERA_ARM), 3);
        rigconf_free(rc);
        rc = expect_ok(BUS "axes:\n  - { name: tt, modbus: { bus: b }, role: turntable }\n");
        CHECK_INT(rigconf_axis_of_role(rc, GN_ROLE_TURNTABLE), 0);
        CHECK_INT(rigconf_axis_of_role(rc, GN_ROLE_LIGHT_ARM), -ENOENT);
        CHECK_INT(rigconf_axis_of_role(rc, GN_ROLE_CAMERA_ARM), -ENOENT);
        rigconf_free(rc);
        rc = expect_ok("rig: bare\n");
        CHECK_INT(rigconf_axis_of_role(rc, GN_ROLE_TURNTABLE), -ENOENT);
        rigconf_free(rc);
        expect_at(BUS "axes:\n  - name: a\n    modbus: { bus: b }\n    role: turntabel\n", 8,
                  "role", "unknown role 'turntabel' (turntable, light_arm, camera_arm or none)");
        expect_at(BUS "axes:\n" AXIS("turntable", "1") "  - { name: t2, modbus: { bus: b, "
                                                       "unit: 2 }, role: turntable }\n",
                  7, "role", "axes 'turntable' and 't2' both have role 'turntable'");
        expect_at(BUS "axes:\n  - { name: x, modbus: { bus: b, unit: 2 }, role: light_arm }\n"
                      "  - name: light_arm\n    modbus: { bus: b }\n",
                  7, "role", "axes 'x' and 'light_arm' both have role 'light_arm'");
}

/* The rig file's default exposure and gain ranges are the named constants. */
static void case_camera_ranges(void)
{
        char text[512];
        struct {
                const char *key;
                double v;
                bool ok;
        } rows[] = {
                {"exposure_us", RIG_EXPOSURE_US_MIN, true},
                {"exposure_us", RIG_EXPOSURE_US_MAX, true},
                {"exposure_us", RIG_EXPOSURE_US_MIN - 1, false},
                {"exposure_us", RIG_EXPOSURE_US_MAX + 1, false},
                {"gain", RIG_GAIN_MIN, true},
                {"gain", RIG_GAIN_MAX, true},
                {"gain", RIG_GAIN_MIN * 0.99, false},
                {"gain", RIG_GAIN_MAX * 1.01, false},
                {"readout_ms", 0, true},
                {"readout_ms", 10000, true},
                {"readout_ms", -1, false},
                {"frame_rate", 0.1, true},
                {"frame_rate", 1000, true},
                {"frame_rate", 0, false},
                {"frame_rate", 1001, false},
                {"occlusion_deg", 90, true},
                {"occlusion_deg", 91, false},
        };
        struct rig_config *rc;

        for (size_t i = 0; i < ELEMENTSOF(rows); i++) {
                snprintf(text, sizeof(text),
                         BUS "cameras:\n  - { name: c, sim: { bus: f }, %s: %.17g }\n", rows[i].key,
                         rows[i].v);
                if (rows[i].ok)
                        rigconf_free(expect_ok(text));
                else
                        expect_at(text, 6, rows[i].key, "is out of range");
        }
        /* the planner's timing keys and their defaults */
        rc = expect_ok(BUS "cameras:\n  - { name: c, sim: { bus: f } }\n"
                           "axes:\n  - { name: a, modbus: { bus: b } }\n");
        CHECK_INT(rc->cameras[0].readout_ms, 30);
        CHECK_NEAR(rc->cameras[0].frame_rate, 30, 0);
        CHECK_NEAR(rc->cameras[0].occlusion_deg, 5, 0);
        CHECK_INT(rc->axes[0].move_overhead_ms, 35);
        rigconf_free(rc);
        rc = expect_ok(BUS "axes:\n  - { name: a, modbus: { bus: b }, move_overhead_ms: 0 }\n");
        CHECK_INT(rc->axes[0].move_overhead_ms, 0);
        rigconf_free(rc);
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b }, move_overhead_ms: -5 }\n", 6,
                  "move_overhead_ms", "is out of range");
}

/* A second axis backend, for the rule of one backend map per device (gonio has one). */
static int spare_parse(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                       struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", NULL};

        return yconf_check_keys(yc, m, keys);
}

static const struct rig_backend spare_axis = {
        .name = "spare",
        .cls = RIG_CLASS_AXIS,
        .bus_types = 1u << RIG_BUS_MODBUS_RTU,
        .parse_conf = spare_parse,
};

/* Backend maps: exactly one per device, of its class, a mapping with a bus; its keys are the
 * backend's; profiles resolve when the file loads. */
static void case_backend_maps(void)
{
        static const struct rig_backend *const with_spare[] = {&mbax_backend, &mbsw_backend,
                                                               &cam_sim_backend, &spare_axis, NULL};
        struct rig_config *rc;

        expect_at(BUS
                  "axes:\n  - name: a\n    modbus:\n      bus: b\n      profile: gonio-defualt\n",
                  9, "profile", "no register profile named 'gonio-defualt'");
        rc = expect_ok("rig: t\nprofiles:\n  - { name: p, scale: 2 }\nbuses:\n"
                       "  - { name: b, type: modbus-tcp, tcp_port: 502 }\n"
                       "axes:\n  - { name: a, modbus: { bus: b, profile: p } }\n");
        CHECK(((const struct mbax_conf *)rc->axes[0].backend.conf)->profile == &rc->profiles[1]);
        CHECK_NEAR(((const struct mbax_conf *)rc->axes[0].backend.conf)->profile->scale, 2, 0);
        rigconf_free(rc);
        expect_at(BUS "axes:\n  - { name: a, backend: modbus, bus: b }\n", 6, "backend",
                  "go in one map named after the backend (modbus");
        expect_at(BUS "cameras:\n  - { name: c, bus: f }\n", 6, "bus",
                  "go in one map named after the backend (sim");
        expect_at(BUS "axes:\n  - { name: a, modbus: b }\n", 6, "modbus",
                  "expected the backend's settings as a mapping");
        expect_at(BUS "axes:\n  - { name: a, modbus: { unit: 2 } }\n", 6, "bus",
                  "required key is missing");
        backends = with_spare; /* messages listing the backends: a fixed table */
        expect_at(BUS "laser:\n  name: x\n  power: 1\n", 6, "modbus-coil",
                  "no backend map in this entry (one of: modbus-coil)");
        expect_at(BUS "lamps:\n  - { name: l, elevation: 1, modbus: { bus: b } }\n", 6, "modbus",
                  "'modbus' is a backend for axes, not for lamps and lasers (modbus-coil)");
        expect_at(BUS "axes:\n  - name: a\n    modbus: { bus: b }\n    spare: { bus: b }\n", 8,
                  "spare", "a second backend map (after 'modbus'): a device has exactly one");
        expect_at(BUS "axes:\n  - { name: a }\n", 6, "modbus, spare",
                  "no backend map in this entry (one of: modbus, spare)");
        rc = expect_ok(BUS "axes:\n  - { name: a, spare: { bus: b } }\n" AXIS("m", "1"));
        CHECK_STR(rc->axes[0].backend.name, "spare");
        CHECK(rc->axes[0].backend.conf == NULL);
        rigconf_free(rc);
        backends = registry_backends;
}

/* Lines 5-: two Modbus-coil lasers, x on coil 7 and y on coil 8 of unit 10. */
#define LASER(name, coil, az)                                                                      \
        "  - { name: " name ", azimuth: " az ", channel: green, modbus-coil: { bus: b, unit: 10, " \
        "coil: " coil " } }\n"

/* A `lasers:` list: each entry parsed like the one `laser:` mapping, in file order; the
 * shorthand loads as a list of one; and the mistakes of lists refused with file and line. */
static void case_lasers(void)
{
        struct rig_config *rc =
                expect_ok(BUS "lasers:\n" LASER("x", "7", "30") LASER("y", "8", "-30"));

        CHECK_INT(rc->n_lasers, 2);
        CHECK_STR(rc->lasers[1].name, "y");
        CHECK(rc->lasers[1].kind == RIG_SWITCH_LASER);
        CHECK_NEAR(rc->lasers[1].laser_azimuth_deg, -30, 0);
        CHECK_INT(rc->lasers[1].laser_channel, 1);
        CHECK_INT(((const struct mbsw_conf *)rc->lasers[1].backend.conf)->coil, 8);
        CHECK_INT(rigconf_laser(rc, "y"), 1);
        CHECK_INT(rigconf_laser(rc, "z"), -ENOENT);
        CHECK_INT(rigconf_all_lasers(rc), 3);
        rigconf_free(rc);
        rc = expect_ok(BUS "laser: { name: x, azimuth: 12, modbus-coil: { bus: b } }\n");
        CHECK_INT(rc->n_lasers, 1);
        CHECK_NEAR(rc->lasers[0].laser_azimuth_deg, 12, 0);
        rigconf_free(rc);
        expect_at(BUS "lasers:\n" LASER("x", "7", "0") LASER("x", "8", "0"), 7, "name",
                  "device name 'x' is used twice (first at line 6)");
        expect_at(BUS "lamps:\n" LAMP("x", "3", "1") "lasers:\n" LASER("x", "8", "0"), 8, "name",
                  "device name 'x' is used twice (first at line 6)");
        expect_at(BUS "lasers:\n" LASER("x", "7", "0") LASER("y", "7", "0"), 7, "coil",
                  "laser 'x' and laser 'y' are both on coil 7 of unit 10");
        expect_at(BUS "laser: { name: x }\nlasers:\n" LASER("y", "8", "0"), 7, "lasers",
                  "either 'laser' (one mapping) or 'lasers' (a list), not both");
        expect_at(BUS "lasers:\n" LASER("x", "7", "0") "laser: { name: y }\n", 7, "laser",
                  "not both");
        expect_at(BUS "lasers: { name: x }\n", 5, "lasers", "expected a list");
        expect_at(BUS "laser:\n" LASER("x", "7", "0"), 6, "laser",
                  "expected a mapping (several lasers: a list 'lasers')");
        expect_at(BUS "lasers:\n  - x\n", 6, "lasers", "entry 0 is not a mapping");
        expect_at(BUS "lasers:\n  - { azimuth: 3, modbus-coil: { bus: b } }\n", 6, "name",
                  "required key is missing");
        expect_at(BUS "lasers:\n" LASER("a", "1", "0") LASER("b", "2", "0") LASER("c", "3", "0")
                          LASER("d", "4", "0") LASER("e", "5", "0") LASER("f", "6", "0")
                                  LASER("g", "7", "0") LASER("h", "8", "0") LASER("i", "9", "0"),
                  6, "lasers", "at most 8 entries");
}

/* Text the YAML parser must not see: an empty file (getdelim leaves its buffer unwritten),
 * bytes that are not UTF-8 (libfyaml 0.7 loops for ever on "%\x83") and a tab outside quotes
 * and comments (libfyaml 0.7.12 crashes on "? a:\t? b"), refused at their line; UTF-8 text and
 * tabs in quotes and comments load. */
static void case_text(void)
{
        struct rig_config *rc = NULL;
        char err[512], path[32], want[96];

        CHECK_INT(load_text("", &rc, err, sizeof(err), path), -EINVAL);
        CHECK(rc == NULL);
        CHECK_INT(load_text("rig: t\n%\x83\n", &rc, err, sizeof(err), path), -EINVAL);
        snprintf(want, sizeof(want), "%s:2: not UTF-8 text (byte 0x83)", path);
        CHECK_STR(err, want);
        CHECK_INT(load_text("rig: \xc3(\n", &rc, err, sizeof(err), path), -EINVAL);
        snprintf(want, sizeof(want), "%s:1: not UTF-8 text (byte 0xc3)", path);
        CHECK_STR(err, want);
        CHECK_INT(load_text("rig: \xed\xa0\x80\n", &rc, err, sizeof(err), path), -EINVAL);
        CHECK(rc == NULL);
        rc = expect_ok("rig: t\xc3\xa9\xe2\x82\xac\xf0\x9f\x98\x80\n");
        CHECK_STR(rc->name, "t\xc3\xa9\xe2\x82\xac\xf0\x9f\x98\x80");
        rigconf_free(rc);
        CHECK_INT(load_text("rig: t\n? a:\t? I\n", &rc, err, sizeof(err), path), -EINVAL);
        snprintf(want, sizeof(want), "%s:2: a tab: gonio's YAML files take spaces only", path);
        CHECK_STR_CONTAINS(err, want);
        rc = expect_ok("rig: \"t\\\"\tu\" # a\ttab\n# it's\t'\n");
        CHECK_STR(rc->name, "t\"\tu");
        rigconf_free(rc);
}

/* The limits of the settings: max_accel defaults to accel, the camera's to none (0), each at
 * least the value it bounds; a laser goes off when its client goes unless the rig file says
 * otherwise, a lamp only when it says so. */
static void case_limits(void)
{
        struct rig_config *rc = expect_ok(
                BUS "axes:\n  - { name: a, modbus: { bus: b, unit: 1 }, accel: 50 }\n"
                    "  - { name: c, modbus: { bus: b, unit: 2 }, accel: 50, max_accel: 80 }\n"
                    "lamps:\n" LAMP(
                            "l", "9",
                            "0") "laser: { name: x, modbus-coil: { bus: b, "
                                 "unit: 9, coil: 1 } }\ncameras:\n  - { name: k, sim: { bus: f }, "
                                 "max_exposure_us: 50000, max_gain: 8 }\n");

        CHECK(rc->axes[0].max_accel == 50 && rc->axes[1].max_accel == 80);
        CHECK(rc->cameras[0].max_exposure_us == 50000 && rc->cameras[0].max_gain == 8);
        CHECK(rc->lasers[0].off_on_disconnect && !rc->lamps[0].off_on_disconnect);
        rigconf_free(rc);
        rc = expect_ok(BUS "cameras:\n  - { name: k, sim: { bus: f } }\n");
        CHECK(rc->cameras[0].max_exposure_us == 0 && rc->cameras[0].max_gain == 0);
        rigconf_free(rc);
        expect_at(BUS "axes:\n  - { name: a, modbus: { bus: b, unit: 1 }, accel: 50, "
                      "max_accel: 40 }\n",
                  6, "max_accel", "must be at least accel (50)");
        expect_at(BUS "cameras:\n  - { name: k, sim: { bus: f }, max_exposure_us: 500 }\n", 6,
                  "max_exposure_us", "must be at least exposure_us (10000)");
        expect_at(BUS "cameras:\n  - { name: k, sim: { bus: f }, gain: 2, max_gain: 1 }\n", 6,
                  "max_gain", "must be at least gain (2)");
}

static const struct {
        const char *name;
        void (*fn)(void);
} cases[] = {
        {"limits", case_limits},
        {"example", case_example},
        {"errors", case_errors},
        {"unknown-keys", case_unknown_keys},
        {"addresses", case_addresses},
        {"env", case_env},
        {"duplicates", case_duplicates},
        {"roles", case_roles},
        {"camera-ranges", case_camera_ranges},
        {"backend-maps", case_backend_maps},
        {"lasers", case_lasers},
        {"text", case_text},
};

int main(int argc, char **argv)
{
        CHECK(argc == 3);
        example_path = argv[1];
        for (size_t i = 0; i < ELEMENTSOF(cases); i++)
                if (strcmp(cases[i].name, argv[2]) == 0) {
                        cases[i].fn();
                        return 0;
                }
        fprintf(stderr, "test-rigconf: unknown case '%s'\n", argv[2]);
        return 1;
}
