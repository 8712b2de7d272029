/* libcamera-capture.c - kernel lane test of the "libcamera" camera backend on vimc, through
 * the camera class as goniod drives it (rig file, local bus, cam_* wrappers): captures at the
 * rig file's size in rgb8 with the colour bars of vimc's test pattern in order, timestamps
 * on the wall clock and increasing, streaming through the eventfd, controls vimc lacks
 * refused by the option table, and clear errors for a wrong id, a wrong index, a size vimc
 * does not offer and a camera already in use. Then the faults vimc's injector
 * (tests/kernel/vimc-faults.patch) gives on command: frames dropped mid-stream, frames late,
 * and frames later than the capture's bound.
 *
 * Usage: kl-libcamera-capture (in the guest; writes libcamera-rig.yaml in the current
 * directory). */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>

#include "common/clock.h"
#include "common/rigconf.h"
#include "drivers/bus/bus.h"
#include "drivers/camera/camera.h"
#include "drivers/camera/libcamera/api.h"
#include "drivers/registry.h"
#include "tests/test.h"

#define VIMC_ID "platform/vimc.0 Sensor B"
/* How the first camera's errors begin (bus_log_dev) */
#define BY_ID "camera 'by-id' [libcamera@cams]: Failed to "

static const char rig_yaml[] =
        "rig: libcamera-vimc\n"
        "buses:\n"
        "  - { name: cams, type: local }\n"
        "cameras:\n"
        "  - { name: by-id, libcamera: { bus: cams, id: '" VIMC_ID
        "' }, width: 480, height: 360 }\n"
        "  - { name: by-model, libcamera: { bus: cams, model: Sensor B }, width: 240, height: 180 "
        "}\n"
        "  - { name: wrong-id, libcamera: { bus: cams, id: platform/vimc.0 Sensor X } }\n"
        "  - { name: wrong-index, libcamera: { bus: cams, model: Sensor B, index: 1 } }\n"
        "  - { name: tiny, libcamera: { bus: cams, index: 0 }, width: 32, height: 32 }\n";

struct fixture {
        struct rig_config *rc;
        struct bus *bus;
};

static struct cam *new_cam(struct fixture *f, size_t i)
{
        struct cam *c;

        CHECK_INT(cam_new(&f->rc->cameras[i], f->bus, &c), 0);
        return c;
}

/* The mean of channel ch over a 5x5 patch around (x, y). */
static int patch(const struct gn_frame *fr, int x, int y, int ch)
{
        int sum = 0;

        for (int dy = -2; dy <= 2; dy++)
                for (int dx = -2; dx <= 2; dx++)
                        sum += fr->data[(size_t)(y + dy) * fr->stride + (size_t)(x + dx) * 3 + ch];
        return sum / 25;
}

/* vimc's 75% colour bars: white, yellow, cyan, green, magenta, red, blue, black (its text
 * overlay covers the middle rows, so near the top). Checks that red, green and blue land in
 * the right channels (yellow lacks blue, blue has only blue). */
static void check_bars(const struct gn_frame *fr)
{
        int y = 10, yellow = fr->width * 3 / 16, blue = fr->width * 13 / 16;

        CHECK(patch(fr, yellow, y, 0) > patch(fr, yellow, y, 2) + 60);
        CHECK(patch(fr, yellow, y, 1) > patch(fr, yellow, y, 2) + 60);
        CHECK(patch(fr, blue, y, 2) > patch(fr, blue, y, 0) + 60);
        CHECK(patch(fr, blue, y, 2) > patch(fr, blue, y, 1) + 60);
}

static void check_frame(const struct gn_frame *fr, int width, int height)
{
        uint64_t now = gn_realtime_ns();

        CHECK_INT(fr->width, width);
        CHECK_INT(fr->height, height);
        CHECK_STR(gn_frame_format(fr), "rgb8");
        CHECK(fr->timestamp_ns <= now && fr->timestamp_ns > now - 5000000000ull);
        CHECK_INT(fr->exposure_us, 0); /* vimc reports no exposure */
}

static void test_capture(struct cam *c)
{
        struct gn_frame fr[2] = {};

        for (int i = 0; i < 2; i++) {
                CHECK_INT(cam_capture(c, NULL, &fr[i]), 0);
                check_frame(&fr[i], 480, 360);
        }
        check_bars(&fr[0]);
        CHECK(fr[1].timestamp_ns > fr[0].timestamp_ns);
        gn_frame_free_data(&fr[0]);
        gn_frame_free_data(&fr[1]);
}

/* Waits (5 s at most) for the stream's next frame and dequeues it: 0 or the dequeue's error. */
static int next_frame(struct cam *c, struct gn_frame *fr)
{
        struct pollfd p = {.fd = cam_stream_fd(c), .events = POLLIN};

        CHECK(p.fd >= 0);
        CHECK_INT(poll(&p, 1, 5000), 1);
        return cam_stream_dequeue(c, fr);
}

static void test_stream(struct cam *c)
{
        struct gn_frame fr[8] = {}; /* more than the camera's buffers: each is requeued */
        int r;

        CHECK_INT(cam_stream_fd(c), -ENOTCONN);
        CHECK_INT(cam_stream_start(c, NULL), 0);
        CHECK_INT(cam_stream_start(c, NULL), -EBUSY);
        CHECK_INT(cam_capture(c, NULL, &fr[0]), -EBUSY);
        for (int i = 0; i < 8; i++) {
                CHECK_INT(next_frame(c, &fr[i]), 0);
                check_frame(&fr[i], 480, 360);
                if (i > 0) {
                        CHECK(fr[i].seq > fr[i - 1].seq);
                        CHECK(fr[i].timestamp_ns > fr[i - 1].timestamp_ns);
                }
        }
        gn_frame_free_data(&fr[0]);
        while ((r = cam_stream_dequeue(c, &fr[0])) == 0) /* drain what is ready */
                gn_frame_free_data(&fr[0]);
        CHECK_INT(r, -EAGAIN);
        cam_stream_stop(c);
        CHECK_INT(cam_stream_fd(c), -ENOTCONN);
        for (int i = 1; i < 8; i++)
                gn_frame_free_data(&fr[i]);
}

/* vimc has neither ExposureTime nor AnalogueGain: the option table says so once open. */
static void test_controls(struct cam *c)
{
        struct gn_frame fr = {};
        char msg[128];

        CHECK_INT(
                cam_check_request(c, &(struct cam_request){.exposure_us = 1000}, msg, sizeof(msg)),
                -EOPNOTSUPP);
        CHECK_STR(msg, "cannot set exposure");
        CHECK_INT(cam_check_request(c, &(struct cam_request){.gain = 2}, msg, sizeof(msg)),
                  -EOPNOTSUPP);
        CHECK_INT(cam_capture(c, &(struct cam_request){.exposure_us = 1000}, &fr), -EOPNOTSUPP);
        CHECK_STR_CONTAINS(c->last_error, "cannot set exposure");
        CHECK_INT(cam_capture(c, &(struct cam_request){.bits = 16}, &fr), -EOPNOTSUPP);
        CHECK_STR_CONTAINS(c->last_error, "16-bit samples");
}

/* Sets vimc's fault injector parameter name (tests/kernel/vimc-faults.patch) to v. */
static void set_vimc(const char *name, unsigned v)
{
        char path[128];
        FILE *f;

        snprintf(path, sizeof(path), "/sys/module/vimc/parameters/%s", name);
        f = fopen(path, "w");
        CHECK(f && fprintf(f, "%u\n", v) > 0 && fclose(f) == 0);
}

/* Streams n frames in sequence (the last one's seq in *seq) and stops. */
static void stream_ok(struct cam *c, int n, uint64_t *seq)
{
        struct gn_frame fr = {};

        CHECK_INT(cam_stream_start(c, NULL), 0);
        for (int i = 0; i < n; i++) {
                CHECK_INT(next_frame(c, &fr), 0);
                CHECK(i == 0 || fr.seq == *seq + 1);
                *seq = fr.seq;
                gn_frame_free_data(&fr);
        }
        cam_stream_stop(c);
}

/* Two frames dropped by vimc mid-stream: the dequeue at the gap fails with -EIO naming the
 * camera and exactly the frames lost; the count goes on after it; the stream, ended as a
 * fault, starts again and runs without a gap. */
static void test_drops(struct cam *c)
{
        unsigned long long at, after;
        uint64_t seq = 0;
        struct gn_frame fr = {};
        int r, n = 0;

        stream_ok(c, 3, &seq);
        CHECK_INT(cam_stream_start(c, NULL), 0);
        CHECK_INT(next_frame(c, &fr), 0);
        seq = fr.seq;
        gn_frame_free_data(&fr);
        set_vimc("drop_frames", 2);
        while ((r = next_frame(c, &fr)) == 0 && n++ < 8) { /* the frames filled already */
                seq = fr.seq;
                gn_frame_free_data(&fr);
        }
        CHECK_INT(r, -EIO);
        CHECK_STR_CONTAINS(c->last_error, BY_ID "dequeue a frame: 2 frames dropped (sequence ");
        CHECK(sscanf(strstr(c->last_error, "(sequence "), "(sequence %llu after %llu)", &at,
                     &after) == 2);
        CHECK_INT(after, seq);
        CHECK_INT(at, seq + 3);
        CHECK_INT(next_frame(c, &fr), 0);
        CHECK_INT(fr.seq, at + 1);
        gn_frame_free_data(&fr);
        cam_stream_stop(c);
        stream_ok(c, 4, &seq);
}

/* vimc holding each frame: for 1 s, the capture waits for it and its timestamp is that late,
 * and a stream's cam_stream_next() gives up at its bound, then gets the frame with a longer
 * one; past LCCAM_TIMEOUT_MS, the capture gives up at the bound with -ETIMEDOUT naming the
 * camera; without the delay, captures are quick again. */
static void test_delay(struct cam *c)
{
        uint64_t t0 = gn_realtime_ns(), m0;
        struct gn_frame fr = {};

        set_vimc("delay_ms", 1000);
        CHECK_INT(cam_capture(c, NULL, &fr), 0);
        CHECK(fr.timestamp_ns > t0 + 1000000000ull);
        gn_frame_free_data(&fr);
        CHECK_INT(cam_stream_start(c, NULL), 0);
        CHECK_INT(cam_stream_next(c, 300, &fr), -ETIMEDOUT);
        CHECK_STR_CONTAINS(c->last_error, BY_ID "dequeue a frame: no frame within 300 ms");
        CHECK_INT(cam_stream_next(c, 3000, &fr), 0);
        gn_frame_free_data(&fr);
        cam_stream_stop(c);
        set_vimc("delay_ms", LCCAM_TIMEOUT_MS + 2000);
        m0 = gn_monotonic_ns();
        CHECK_INT(cam_capture(c, NULL, &fr), -ETIMEDOUT);
        CHECK(gn_monotonic_ns() - m0 >= LCCAM_TIMEOUT_MS * 1000000ull);
        CHECK(gn_monotonic_ns() - m0 < (LCCAM_TIMEOUT_MS + 1000) * 1000000ull); /* stopped */
        CHECK_STR_CONTAINS(c->last_error, BY_ID "capture: no frame within 5000 ms");
        set_vimc("delay_ms", 0);
        t0 = gn_realtime_ns();
        CHECK_INT(cam_capture(c, NULL, &fr), 0);
        CHECK(fr.timestamp_ns < t0 + 1000000000ull);
        gn_frame_free_data(&fr);
}

/* Opening camera i fails with err and a last_error holding what. */
static void check_open_fails(struct fixture *f, size_t i, int err, const char *what)
{
        struct cam *c = new_cam(f, i);

        CHECK_INT(cam_open(c), err);
        CHECK_STR_CONTAINS(c->last_error, what);
        cam_free(c);
}

int main(void)
{
        struct fixture f = {};
        struct cam *c, *other;
        struct gn_frame fr = {};
        char err[512] = "";
        FILE *file = fopen("libcamera-rig.yaml", "w");

        CHECK(file && fputs(rig_yaml, file) >= 0 && fclose(file) == 0);
        CHECK_INT(rigconf_load("libcamera-rig.yaml", registry_backends, &f.rc, err, sizeof(err)),
                  0);
        CHECK_INT(bus_new_sync(&f.rc->buses[0], &f.bus), 0);

        c = new_cam(&f, 0);
        CHECK_INT(cam_open(c), 0);
        test_capture(c);
        test_stream(c);
        test_controls(c);
        test_drops(c);
        test_delay(c);
        check_open_fails(&f, 1, -EBUSY, "cannot acquire " VIMC_ID);
        c = cam_free(c);

        other = new_cam(&f, 1); /* by model, once the camera is free again */
        CHECK_INT(cam_open(other), 0);
        CHECK_INT(cam_capture(other, NULL, &fr), 0);
        check_frame(&fr, 240, 180);
        gn_frame_free_data(&fr);
        cam_free(other);

        check_open_fails(&f, 2, -ENODEV,
                         "no camera 'platform/vimc.0 Sensor X' (cameras: " VIMC_ID ")");
        check_open_fails(&f, 3, -ENODEV, "no camera of model 'Sensor B' at index 1");
        check_open_fails(&f, 4, -EINVAL, "cannot give 32x32-BGR888");
        bus_free(f.bus);
        rigconf_free(f.rc);
        return 0;
}
