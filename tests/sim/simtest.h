/* simtest.h - helpers shared by the tests of sim/: a temporary directory holding a small
 * test rig, and a monotonic clock (checks are tests/test.h's). */
#pragma once

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <modbus/modbus.h>

#include "common/rigconf.h"
#include "tests/test.h"

/* Makes a temporary directory (path into dir, at least 64 bytes) and writes the test rig
 * into dir/rig.yaml: three Modbus axes on bus 'drives' (units 1..3), two lamps and the
 * laser on bus 'relays' (unit 10, coils 0, 1, 7), one 160x120 camera 'cam0' on bus
 * 'frames'. Ports live under ${GONIO_SIM_DIR}. With drives_tcp the drives bus is
 * modbus-tcp on a free port. Aborts on failure. */
void simtest_write_rig(char *dir, bool drives_tcp);

/* simtest_write_rig(), then sets GONIO_SIM_DIR to dir and loads the rig. */
struct rig_config *simtest_rig(char *dir, bool drives_tcp);

/* Makes a temporary directory as simtest_write_rig(), writes text into dir/rig.yaml, then
 * loads it as simtest_load(). */
struct rig_config *simtest_rig_text(char *dir, const char *text);

/* Sets GONIO_SIM_DIR to dir and loads dir/rig.yaml; aborts on failure. */
struct rig_config *simtest_load(const char *dir);

/* Removes dir and the files in it. */
void simtest_rmdir(const char *dir);

/* CLOCK_MONOTONIC in seconds. */
double simtest_now(void);

/* Registers, status bits and commands of the gonio-default profile (docs/modbus-profile.md). */
enum {
        SIMTEST_R_STATUS = 0x00,
        SIMTEST_R_FAULT = 0x01,
        SIMTEST_R_POS = 0x02,
        SIMTEST_R_TARGET = 0x10,
        SIMTEST_R_SPEED = 0x12,
        SIMTEST_R_COMMAND = 0x20
};
enum {
        SIMTEST_ST_HOMED = 1 << 1,
        SIMTEST_ST_MOVING = 1 << 2,
        SIMTEST_ST_INPOS = 1 << 3,
        SIMTEST_ST_FAULT = 1 << 4
};
enum { SIMTEST_CMD_MOVE = 1, SIMTEST_CMD_HOME = 2, SIMTEST_CMD_STOP = 3, SIMTEST_CMD_RESET = 4 };

/* A connected libmodbus RTU client on dir/bus with a 300 ms response timeout. */
modbus_t *simtest_modbus(const char *dir, const char *bus);

/* Reads one holding register of unit; aborts on error. */
uint16_t simtest_reg(modbus_t *mb, int unit, int addr);

/* Writes target, speed and accel (unchanged) and command in one request (function 0x10,
 * registers 0x10..0x20). Returns 1, or -1 with errno set by libmodbus. */
int simtest_command(modbus_t *mb, int unit, double target_deg, uint16_t cmd);

/* Polls the status of unit until (status & mask) == want; aborts after limit_s. Returns
 * the real time it took. */
double simtest_wait_status(modbus_t *mb, int unit, uint16_t mask, uint16_t want, double limit_s);
