/* scan.c - a 360 deg laser scan at 0.45 deg steps (800 angles) captured on gonio-sim at real
 * time (time scale 1) with the timing model of examples/rigs/sim.yaml (turntable 90 deg/s,
 * 180 deg/s^2, settle 50 ms; a Modbus RTU drive and relay; a camera at 30 frames/s, here
 * 320x240 so that rendering keeps up, 2 ms exposures, lamps off; its gem): the continuous
 * mode (goniod's scan.continuous) and the stop-and-go mode (a session: move, settle, one
 * laser frame per angle), both through gonioctl scan, against the camera bound (the frames
 * the scan needs, 800, divided by the frame rate). Rig time is wall time at time scale 1.
 * Stop-and-go takes minutes for 800 angles: it runs on the first PREFIX angles and is
 * extrapolated to 800 (said in the output), unless run with --full. --two-lasers: the rig
 * has a second laser (azimuth 60): continuous scans run one pass per laser, stop-and-go takes
 * each laser alone at every angle, and the camera bound is twice the frames. points: the
 * laser-line
 * points (calib/laserline, one frame: the room is dark) found in the continuous scan's
 * frames. Last line: {"bench":"scan","continuous_s":...,"stop_and_go_s":...,
 * "camera_bound_s":...,"points":...}. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "calib/laserline.h"
#include "dataset/ds.h"
#include "tests/test.h"

#define POSITIONS 800
#define STEP      "0.45"
#define FPS       30.0 /* the camera's frame_rate below */
#define PREFIX    100  /* stop-and-go angles measured without --full */
#define EXPOSURE  "2000"

/* examples/rigs/sim.yaml reduced to what a scan uses, its camera at half size. */
static const char *const bench_rig =
        "rig: bench-scan\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\", baud: 115200 }\n"
        "  - { name: relays, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/relays\", baud: 115200 }\n"
        "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true,\n"
        "      max_speed: 90, accel: 180, settle_ms: 50 }\n"
        "lasers:\n"
        "  - { name: laser, azimuth: 0, origin: [600, 0, 150], width: 1.0, power: 1.0e4,\n"
        "      channel: red, modbus-coil: { bus: relays, unit: 10, coil: 7 } }\n"
        "%s"
        "cameras:\n"
        "  - { name: cam0, sim: { bus: frames }, elevation: 15, distance: 600, azimuth: 30,\n"
        "      target: [0, 0, 40], width: 320, height: 240, fx: 550, fy: 550,\n"
        "      exposure_us: 2000, frame_rate: 30 }\n"
        "scene:\n"
        "  seed: 1\n"
        "  object:\n"
        "    shape: gem\n"
        "    size: 70\n"
        "    pose: { translate: [45, -20, 0], rotate_x: 12 }\n"
        "    material: { albedo: [0.7, 0.55, 0.35] }\n"
        "  turntable: { radius: 150, albedo: [0.2, 0.2, 0.2] }\n";

struct count {
        struct ds *d;
        struct laserline_opts o;
        long points, frames;
};

static int count_points(const struct ds_capture *c, void *userdata)
{
        struct count *k = userdata;
        struct gn_frame f = {0};
        static float centre[LASERLINE_MAX_LEN];
        struct laserline_result r = {.centre = centre, .n = LASERLINE_MAX_LEN};

        CHECK_INT(ds_load_image(k->d, c->file, &f), 0);
        CHECK(laserline_extract(&f, NULL, &k->o, &r) >= 0);
        k->points += r.points;
        k->frames++;
        gn_frame_free_data(&f);
        return 0;
}

/* The laser-line points found in the frames of dataset name. */
static long dataset_points(struct rigenv *e, const char *name)
{
        struct count k = {0};
        char path[400];

        snprintf(path, sizeof(path), "%s/%s", e->data, name);
        CHECK_INT(ds_open(path, &k.d), 0);
        laserline_opts_default(&k.o, 0);
        CHECK(ds_rows(k.d, 0, -1, count_points, &k) >= 0);
        ds_close(k.d);
        printf("dataset %s: %ld laser points in %ld frames\n", name, k.points, k.frames);
        return k.points;
}

/* Runs gonioctl scan with the angles to (exclusive on a full turn) and the mode; returns the
 * wall time in seconds. */
static double timed_scan(struct rigenv *e, const char *dataset, const char *mode, const char *to)
{
        double t0 = bench_now_ms();

        CHECK_INT(ctl(e, NULL, "--timeout", "3600", "scan", dataset, "--no-mesh", "--mode", mode,
                      "--start", "0", "--end", to, "--step", STEP, "--camera", "cam0", "--exposure",
                      EXPOSURE, NULL),
                  0);
        return (bench_now_ms() - t0) / 1e3;
}

/* The second laser of --two-lasers, 60 deg round from the first. */
static const char second_laser[] =
        "  - { name: laser2, azimuth: 60, origin: [300, 520, 150], width: 1.0, power: 1.0e4,\n"
        "      channel: red, modbus-coil: { bus: relays, unit: 10, coil: 8 } }\n";

int main(int argc, char **argv)
{
        bool full = false, two = false;
        int stop_n;
        char to[32], rig[4096];
        struct rigenv e;
        double cont, stop, bound;
        long points;

        for (int i = 1; i < argc; i++) {
                full = full || strcmp(argv[i], "--full") == 0;
                two = two || strcmp(argv[i], "--two-lasers") == 0;
        }
        stop_n = full ? POSITIONS : PREFIX;
        bound = POSITIONS * (two ? 2 : 1) / FPS;
        snprintf(rig, sizeof(rig), bench_rig, two ? second_laser : "");
        bench_start_rig(&e, 1, rig);
        json_decref(ctl_ok(&e, "home", NULL));
        cont = timed_scan(&e, "cont", "continuous", "360");
        points = dataset_points(&e, "cont");
        snprintf(to, sizeof(to), "%.2f", (stop_n - 1) * 0.45);
        stop = timed_scan(&e, "stop", "stop", to) * POSITIONS / stop_n;
        rigenv_stop(&e);
        printf("continuous: %.1f s for %d angles (%.2fx the camera bound of %.1f s)\n", cont,
               POSITIONS, cont / bound, bound);
        printf("stop-and-go: %.1f s for %d angles%s (%.1fx the continuous scan)\n", stop, POSITIONS,
               full ? "" : ", extrapolated from the first 100", stop / cont);
        printf("{\"bench\":\"scan\",\"continuous_s\":%.2f,\"stop_and_go_s\":%.2f,"
               "\"camera_bound_s\":%.2f,\"points\":%ld}\n",
               cont, stop, bound, points);
        return 0;
}
