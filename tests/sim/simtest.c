/* simtest.c - helpers shared by the tests of sim/ (see simtest.h). */
#include <dirent.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <math.h>

#include "common/clock.h"
#include "common/cleanup.h"
#include "drivers/registry.h"
#include "tests/sim/simtest.h"

static const char rig_head[] =
        "rig: test\n"
        "buses:\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\" }\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n";
static const char rig_drives_rtu[] =
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\" }\n";
static const char rig_drives_tcp[] =
        "  - { name: drives, type: modbus-tcp, host: 127.0.0.1, tcp_port: 0 }\n";
static const char rig_body[] =
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      max_speed: 90, accel: 180, settle_ms: 50 }\n"
        "  - { name: light_arm, modbus: { bus: drives, unit: 2 }, continuous: true,\n"
        "      max_speed: 45, accel: 90, settle_ms: 80 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3 }, limits: [-170, 170],\n"
        "      max_speed: 30, accel: 60, settle_ms: 100 }\n"
        "lamps:\n"
        "  - { name: lamp0, modbus-coil: { bus: relays, unit: 10, coil: 0 },\n"
        "      elevation: 30, radius: 450, intensity: 4.0e5 }\n"
        "  - { name: lamp1, modbus-coil: { bus: relays, unit: 10, coil: 1 },\n"
        "      elevation: 60, radius: 450, intensity: 4.0e5 }\n"
        "laser: { name: laser, modbus-coil: { bus: relays, unit: 10, coil: 7 },\n"
        "         azimuth: 0, origin: [600, 0, 150], width: 0.6, power: 2.0e3 }\n"
        "cameras:\n"
        "  - { name: cam0, sim: { bus: frames }, elevation: 20, distance: 500,\n"
        "      azimuth: 30, target: [0, 0, 30], width: 160, height: 120, fx: 240, fy: 240,\n"
        "      cx: 79.5, cy: 59.5, exposure_us: 20000, gain: 1.0, bits: 8 }\n"
        "scene:\n"
        "  seed: 1\n"
        "  object: { shape: sphere, size: 60, pose: { translate: [50, 0, 0] },\n"
        "            material: { albedo: [0.7, 0.6, 0.5] } }\n"
        "  turntable: { radius: 150, albedo: [0.2, 0.2, 0.2] }\n";

/* Makes the temporary directory and writes the concatenated parts (NULL-terminated) into
 * dir/rig.yaml. */
static void write_rig_parts(char *dir, const char *const *parts)
{
        char path[256];

        strcpy(dir, "/tmp/gonio-simtest-XXXXXX");
        CHECK(mkdtemp(dir));
        snprintf(path, sizeof path, "%s/rig.yaml", dir);
        FILE *f = fopen(path, "w");
        CHECK(f);
        for (; *parts; parts++)
                CHECK(fputs(*parts, f) >= 0);
        CHECK(fclose(f) == 0);
}

void simtest_write_rig(char *dir, bool drives_tcp)
{
        const char *const parts[] = {rig_head, drives_tcp ? rig_drives_tcp : rig_drives_rtu,
                                     rig_body, NULL};

        write_rig_parts(dir, parts);
}

struct rig_config *simtest_rig(char *dir, bool drives_tcp)
{
        simtest_write_rig(dir, drives_tcp);
        return simtest_load(dir);
}

struct rig_config *simtest_rig_text(char *dir, const char *text)
{
        const char *const parts[] = {text, NULL};

        write_rig_parts(dir, parts);
        return simtest_load(dir);
}

struct rig_config *simtest_load(const char *dir)
{
        char path[256], err[512] = "";
        struct rig_config *rc = NULL;

        snprintf(path, sizeof path, "%s/rig.yaml", dir);
        CHECK(setenv("GONIO_SIM_DIR", dir, 1) == 0);
        int r = rigconf_load(path, registry_backends, &rc, err, sizeof err);
        if (r < 0)
                fprintf(stderr, "rigconf_load: %s\n", err);
        CHECK(r >= 0);
        return rc;
}

void simtest_rmdir(const char *dir)
{
        char path[512];
        DIR *d = opendir(dir);
        struct dirent *de;

        if (!d)
                return;
        while ((de = readdir(d)))
                if (strcmp(de->d_name, ".") != 0 && strcmp(de->d_name, "..") != 0) {
                        snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
                        (void)unlink(path);
                }
        closedir(d);
        (void)rmdir(dir);
}

double simtest_now(void)
{
        return (double)gn_monotonic_ns() * 1e-9;
}

modbus_t *simtest_modbus(const char *dir, const char *bus)
{
        char path[256];

        snprintf(path, sizeof path, "%s/%s", dir, bus);
        modbus_t *mb = modbus_new_rtu(path, 115200, 'N', 8, 1);
        CHECK(mb);
        CHECK(modbus_connect(mb) == 0);
        CHECK(modbus_set_response_timeout(mb, 0, 300000) == 0);
        return mb;
}

uint16_t simtest_reg(modbus_t *mb, int unit, int addr)
{
        uint16_t v = 0;

        CHECK(modbus_set_slave(mb, unit) == 0);
        CHECK(modbus_read_registers(mb, addr, 1, &v) == 1);
        return v;
}

int simtest_command(modbus_t *mb, int unit, double target_deg, uint16_t cmd)
{
        uint32_t t = (uint32_t)(int32_t)lround(target_deg * 1000.0);
        uint16_t v[SIMTEST_R_COMMAND - SIMTEST_R_TARGET + 1] = {(uint16_t)(t >> 16), (uint16_t)t};

        CHECK(modbus_set_slave(mb, unit) == 0);
        CHECK(modbus_read_registers(mb, SIMTEST_R_SPEED, 2, v + 2) == 2);
        v[ELEMENTSOF(v) - 1] = cmd;
        int r = modbus_write_registers(mb, SIMTEST_R_TARGET, ELEMENTSOF(v), v);
        return r == (int)ELEMENTSOF(v) ? 1 : -1;
}

double simtest_wait_status(modbus_t *mb, int unit, uint16_t mask, uint16_t want, double limit_s)
{
        double t0 = simtest_now();

        while ((simtest_reg(mb, unit, SIMTEST_R_STATUS) & mask) != want) {
                CHECK(simtest_now() - t0 < limit_s);
                usleep(2000);
        }
        return simtest_now() - t0;
}
