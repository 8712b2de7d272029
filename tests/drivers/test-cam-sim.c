/* test-cam-sim.c - the camera class's streaming shape through the "sim" backend against
 * gonio-sim's frame server (in process, on a Unix socket in a temp dir): start, poll the
 * stream fd, dequeue frames in order, an injected dropped frame, stop; and capture()
 * refused while streaming, working again after stop. */
#include <errno.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "drivers/camera/camera.h"
#include "sim/frame_server.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-camera\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: '@DIR@/drives' }\n"
        "  - { name: relays, type: modbus-rtu, port: '@DIR@/relays' }\n"
        "  - { name: frames, type: sim, port: '@DIR@/frames.sock' }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true }\n"
        "lamps:\n"
        "  - { name: lamp0, modbus-coil: { bus: relays, unit: 10, coil: 0 },\n"
        "      elevation: 30, radius: 450, intensity: 4.0e5 }\n"
        "cameras:\n"
        "  - { name: cam0, sim: { bus: frames }, elevation: 20, distance: 500,\n"
        "      azimuth: 30, target: [0, 0, 30], width: 64, height: 48, fx: 96, fy: 96,\n"
        "      cx: 31.5, cy: 23.5, exposure_us: 20000, gain: 1.0, bits: 8 }\n"
        "scene:\n"
        "  seed: 1\n"
        "  object: { shape: sphere, size: 60 }\n";

struct fixture {
        struct testrig rig;
        struct sim_scene *scene;
        struct sim_frame_server *fs;
        struct bus *bus;
        struct cam *cam;
};

/* Sends one control line to the frame server on a connection of its own. */
static void inject_drop(struct fixture *f)
{
        static const char line[] = "{\"cmd\":\"inject\",\"camera\":\"cam0\",\"fault\":\"drop\"}\n";
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        char reply[256];
        ssize_t n;
        int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

        CHECK(fd >= 0);
        snprintf(sa.sun_path, sizeof(sa.sun_path), "%s/frames.sock", f->rig.dir);
        CHECK(connect(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0);
        CHECK(write(fd, line, strlen(line)) == (ssize_t)strlen(line));
        n = read(fd, reply, sizeof(reply) - 1);
        CHECK(n > 0);
        reply[n] = '\0';
        CHECK(strstr(reply, "\"ok\": true") || strstr(reply, "\"ok\":true"));
        close(fd);
}

/* Waits until the stream fd is readable, as the daemon's event loop would. */
static void wait_readable(struct cam *c)
{
        struct pollfd p = {.fd = cam_stream_fd(c), .events = POLLIN};

        CHECK(p.fd >= 0);
        CHECK_INT(poll(&p, 1, 5000), 1);
}

static void test_stream(struct fixture *f)
{
        struct gn_frame fr[3] = {};
        int r;

        CHECK_INT(cam_stream_fd(f->cam), -ENOTCONN); /* not started */
        CHECK_INT(cam_stream_dequeue(f->cam, &fr[0]), -ENOTCONN);
        CHECK_INT(cam_stream_start(f->cam, &(struct cam_request){.exposure_us = 5000}), 0);
        CHECK_INT(cam_stream_start(f->cam, NULL), -EBUSY);
        CHECK_INT(cam_capture(f->cam, NULL, &fr[0]), -EBUSY);
        for (int i = 0; i < 3; i++) {
                wait_readable(f->cam);
                CHECK_INT(cam_stream_dequeue(f->cam, &fr[i]), 0);
                CHECK_INT(fr[i].width, 64);
                CHECK_INT(fr[i].height, 48);
                CHECK_INT(fr[i].exposure_us, 5000);
                if (i > 0)
                        CHECK_INT(fr[i].seq, fr[i - 1].seq + 1);
        }
        for (int i = 0; i < 3; i++)
                gn_frame_free_data(&fr[i]);

        /* the frame in flight may have been rendered before the fault arrived */
        inject_drop(f);
        r = cam_stream_dequeue(f->cam, &fr[0]);
        if (r == 0) {
                gn_frame_free_data(&fr[0]);
                r = cam_stream_dequeue(f->cam, &fr[0]);
        }
        CHECK_INT(r, -ETIMEDOUT);
        CHECK_STR_CONTAINS(f->cam->last_error, "Failed to dequeue a frame: gonio-sim:");
        CHECK_INT(cam_stream_dequeue(f->cam, &fr[0]), 0); /* asks again */
        gn_frame_free_data(&fr[0]);

        cam_stream_stop(f->cam);
        CHECK_INT(cam_stream_fd(f->cam), -ENOTCONN);
        CHECK_INT(cam_capture(f->cam, NULL, &fr[0]), 0); /* the dropped reply is not read */
        CHECK_INT(fr[0].exposure_us, 20000);
        gn_frame_free_data(&fr[0]);
}

int main(void)
{
        struct fixture f = {};
        char err[512] = "";

        testrig_start(&f.rig, rig_yaml);
        CHECK_INT(sim_scene_new(f.rig.rc, &f.scene, err, sizeof(err)), 0);
        CHECK_INT(sim_frame_server_new(f.rig.rc, f.scene, f.rig.emu, NULL, &f.fs), 0);
        CHECK_INT(bus_new_sync(testrig_bus(&f.rig, "frames"), &f.bus), 0);
        CHECK_INT(cam_new(&f.rig.rc->cameras[0], f.bus, &f.cam), 0);
        CHECK_INT(cam_open(f.cam), 0);

        test_stream(&f);

        f.cam = cam_free(f.cam);
        f.bus = bus_free(f.bus);
        sim_frame_server_free(f.fs);
        sim_scene_free(f.scene);
        testrig_stop(&f.rig);
        return 0;
}
