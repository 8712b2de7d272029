/* move.c - how long goniod takes for a move compared with the physical limit: the
 * trapezoidal motion time of the drive (axis_move_time) plus the axis's settle time.
 * Runs gonio-sim and goniod at real time (time scale 1) on the e2e test rig and moves
 * the camera arm back and forth by several distances through the control socket.
 * Last line: {"bench":"move","moves":N,"physical_s":...,"measured_s":...,
 * "overhead_ms_per_move":...,"ratio":measured/physical}. */
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "common/clock.h"
#include "drivers/axis/axis.h"
#include "tests/test.h"

/* camera_arm of the e2e rig: 30 deg/s, 60 deg/s^2, settle 20 ms */
#define SPEED  30.0
#define ACCEL  60.0
#define SETTLE 0.020

int main(void)
{
        static const double targets[] = {5, -5, 30, -30, 90, 0, 1, 0, 10, -10};
        char req[256];
        double physical = 0, measured = 0, pos = 0;
        struct rigenv e;
        int fd, n = 0;

        bench_start(&e, 1, false);
        json_decref(ctl_ok(&e, "home", NULL));
        fd = raw_connect(&e);
        for (size_t i = 0; i < sizeof(targets) / sizeof(targets[0]); i++, n++) {
                double t0 = gn_monotonic_ns() * 1e-9;

                snprintf(req, sizeof(req),
                         "{\"jsonrpc\":\"2.0\",\"id\":%zu,\"method\":\"move\",\"params\":"
                         "{\"axis\":\"camera_arm\",\"position\":%g}}\n",
                         i + 1, targets[i]);
                json_t *r = raw_call(fd, req);
                CHECK(json_object_get(r, "result"));
                json_decref(r);
                measured += gn_monotonic_ns() * 1e-9 - t0;
                physical += axis_move_time(targets[i] - pos, SPEED, ACCEL) + SETTLE;
                pos = targets[i];
        }
        close(fd);
        rigenv_stop(&e);
        printf("%d moves of the camera arm: %.3f s measured, %.3f s physical limit\n", n, measured,
               physical);
        printf("{\"bench\":\"move\",\"moves\":%d,\"physical_s\":%.3f,\"measured_s\":%.3f,"
               "\"overhead_ms_per_move\":%.1f,\"ratio\":%.3f}\n",
               n, physical, measured, (measured - physical) * 1e3 / n, measured / physical);
        return 0;
}
