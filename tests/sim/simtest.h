/* simtest.h - helpers shared by the tests of sim/: checks that abort with the
 * location, a temporary directory holding a small test rig, and a monotonic clock. */
#pragma once

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

#include "common/rigconf.h"

#define CHECK(cond)                                                                                \
        do {                                                                                       \
                if (!(cond)) {                                                                     \
                        fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);   \
                        abort();                                                                   \
                }                                                                                  \
        } while (0)

#define CHECK_NEAR(a, b, tol)                                                                      \
        do {                                                                                       \
                double _a = (a), _b = (b);                                                         \
                if (!(_a >= _b - (tol) && _a <= _b + (tol))) {                                     \
                        fprintf(stderr, "%s:%d: %s = %g, expected %s = %g +- %g\n", __FILE__,      \
                                __LINE__, #a, _a, #b, _b, (double)(tol));                          \
                        abort();                                                                   \
                }                                                                                  \
        } while (0)

/* Makes a temporary directory (path into dir, at least 64 bytes) and writes the test rig
 * into dir/rig.yaml: three Modbus axes on bus 'drives' (units 1..3), two lamps and the
 * laser on bus 'relays' (unit 10, coils 0, 1, 7), one 160x120 camera 'cam0' on bus
 * 'frames'. Ports live under ${GONIO_SIM_DIR}. With drives_tcp the drives bus is
 * modbus-tcp on a free port. Aborts on failure. */
void simtest_write_rig(char *dir, bool drives_tcp);

/* simtest_write_rig(), then sets GONIO_SIM_DIR to dir and loads the rig. */
struct rig_config *simtest_rig(char *dir, bool drives_tcp);

/* Removes dir and the files in it. */
void simtest_rmdir(const char *dir);

/* CLOCK_MONOTONIC in seconds. */
double simtest_now(void);
