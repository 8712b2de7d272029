/* v4l2-goniod.c - kernel lane end to end: goniod on a rig of two v4l2 cameras (vivid's two
 * nodes, one local bus each), driven by gonioctl as an operator would: a dataset created,
 * describe listing each camera's own ranges (vivid's gain 0..255, no exposure control), one
 * capture storing a frame of each camera, one of cam1 alone at a requested gain; then
 * the dataset read back: files match their rows (ds_verify), each row names its camera
 * with the size, format, gain and a timestamp within its gonioctl call, and the stored
 * images decode to vivid's colour bars. vivid stamps the start of each frame
 * (timestamp_source 1): its end-of-frame stamps are emulated ahead of delivery.
 *
 * Usage: kl-v4l2-goniod GONIOD GONIOCTL (as root in the guest). */
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>

#include <jansson.h>

#include "dataset/ds.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: klane-v4l2-goniod\n"
        "buses:\n"
        "  - { name: cams0, type: local }\n"
        "  - { name: cams1, type: local }\n"
        "cameras:\n"
        "  - { name: cam0, v4l2: { bus: cams0, bus_info: 'platform:vivid-000',\n"
        "            controls: { timestamp_source: 1 } },\n"
        "      elevation: 20, distance: 500, target: [0, 0, 0], width: 640, height: 480,\n"
        "      fx: 500, fy: 500, gain: 30 }\n"
        "  - { name: cam1, v4l2: { bus: cams1, bus_info: 'platform:vivid-001', format: UYVY,\n"
        "            controls: { timestamp_source: 1 } },\n"
        "      elevation: 20, distance: 500, target: [0, 0, 0], width: 320, height: 180,\n"
        "      fx: 250, fy: 250, gain: 50 }\n";

static char dir[] = "/tmp/kl-v4l2-goniod-XXXXXX";
static char sock[64], data[64];
static const char *gonioctl;

static int64_t realtime_ns(void)
{
        struct timespec t;

        clock_gettime(CLOCK_REALTIME, &t);
        return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

/* Runs gonioctl --socket SOCK ARGS; returns its exit status. */
static int ctl(const char *args)
{
        char cmd[512];
        int st;

        snprintf(cmd, sizeof(cmd), "%s --socket %s %s", gonioctl, sock, args);
        fprintf(stderr, "$ gonioctl %s\n", args);
        st = system(cmd);
        return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static pid_t start_goniod(const char *goniod)
{
        char rig[64];
        pid_t pid;
        int fd;

        snprintf(rig, sizeof(rig), "%s/rig.yaml", dir);
        fd = open(rig, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        CHECK(fd >= 0);
        CHECK(write(fd, rig_yaml, strlen(rig_yaml)) == (ssize_t)strlen(rig_yaml));
        close(fd);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                execl(goniod, goniod, "--rig", rig, "--socket", sock, "--data", data, NULL);
                _exit(127);
        }
        for (int i = 0; i < 100; i++) {
                int s = test_unix_connect(sock);

                if (s >= 0) {
                        close(s);
                        return pid;
                }
                usleep(100000);
        }
        CHECK(!"goniod's socket did not appear");
        return -1;
}

/* gonioctl --json describe: the cameras' options are the devices' (vivid: gain 0..255, no
 * exposure). */
static void check_describe(void)
{
        char cmd[512], out[8192] = "";
        json_error_t jerr;
        size_t n, i;
        json_t *dev;
        FILE *p;

        snprintf(cmd, sizeof(cmd), "%s --socket %s --json describe", gonioctl, sock);
        p = popen(cmd, "r");
        CHECK(p);
        n = fread(out, 1, sizeof(out) - 1, p);
        CHECK_INT(pclose(p), 0);
        out[n] = '\0';
        json_t *o = json_loads(out, 0, &jerr);
        CHECK(o);
        json_array_foreach(json_object_get(o, "devices"), i, dev)
        {
                json_t *opt;
                size_t k;
                bool gain = false;

                CHECK_STR(json_string_value(json_object_get(dev, "backend")), "v4l2");
                json_array_foreach(json_object_get(dev, "options"), k, opt)
                {
                        const char *name = json_string_value(json_object_get(opt, "name"));

                        CHECK(strcmp(name, "exposure") != 0);
                        if (strcmp(name, "gain") == 0)
                                gain = json_real_value(json_object_get(opt, "max")) == 255;
                }
                CHECK(gain);
        }
        CHECK_INT(i, 2);
        json_decref(o);
}

struct expect {
        int64_t t0[3], t1[3]; /* around the gonioctl call that stored row i + 1 */
        int rows;
};

/* One stored row: camera, shape, gain, timestamp and image as captured. */
static int check_row(const struct ds_capture *c, void *userdata)
{
        struct expect *x = userdata;
        const bool cam0 = strcmp(c->camera, "cam0") == 0;
        const int i = x->rows++;

        fprintf(stderr, "row %lld: %s %s %dx%d %s gain %g at %llu\n", (long long)c->id, c->camera,
                c->file, c->width, c->height, c->pixfmt, c->gain,
                (unsigned long long)c->t_exposure_ns);
        CHECK(i < 3);
        CHECK(cam0 || strcmp(c->camera, "cam1") == 0);
        CHECK_INT(c->width, cam0 ? 640 : 320);
        CHECK_INT(c->height, cam0 ? 480 : 180);
        CHECK_STR(c->pixfmt, "rgb8");
        CHECK_NEAR(c->gain, cam0 ? 30 : i == 2 ? 9 : 50, 0);
        CHECK((int64_t)c->t_exposure_ns >= x->t0[i] && (int64_t)c->t_exposure_ns <= x->t1[i]);
        return 0;
}

/* The stored image of cam0 shows vivid's 75% white and blue bars. */
static int check_image(const struct ds_capture *c, void *userdata)
{
        struct ds *d = userdata;
        struct gn_frame f = {0};

        if (strcmp(c->camera, "cam0") != 0)
                return 0;
        CHECK_INT(ds_load_image(d, c->file, &f), 0);
        CHECK_INT(f.width, 640);
        const uint8_t *w = f.data + f.stride * 240 + 3 * 40, *b = f.data + f.stride * 240 + 3 * 520;
        CHECK_NEAR(w[0], 191, 6);
        CHECK_NEAR(w[2], 191, 6);
        CHECK(b[2] > 180 && b[0] < 10 && b[1] < 10);
        gn_frame_free_data(&f);
        return 0;
}

int main(int argc, char **argv)
{
        struct expect x = {0};
        struct ds *d = NULL;
        char path[128];
        pid_t pid;
        int st;

        CHECK(argc == 3);
        gonioctl = argv[2];
        CHECK(mkdtemp(dir));
        snprintf(sock, sizeof(sock), "%s/goniod.sock", dir);
        snprintf(data, sizeof(data), "%s/data", dir);
        CHECK(mkdir(data, 0755) == 0);
        pid = start_goniod(argv[1]);

        check_describe();
        CHECK_INT(ctl("dataset create v"), 0);
        x.t0[0] = x.t0[1] = realtime_ns();
        CHECK_INT(ctl("capture"), 0);
        x.t1[0] = x.t1[1] = realtime_ns();
        x.t0[2] = realtime_ns();
        CHECK_INT(ctl("capture --camera cam1 --gain 9"), 0);
        x.t1[2] = realtime_ns();
        CHECK_INT(ctl("capture --camera cam1 --gain 900"), 6); /* vivid's gain ends at 255 */
        CHECK_INT(ctl("dataset close"), 0);
        CHECK_INT(kill(pid, SIGTERM), 0);
        CHECK_INT(waitpid(pid, &st, 0), pid);
        CHECK(WIFEXITED(st) && WEXITSTATUS(st) == 0);

        snprintf(path, sizeof(path), "%s/v", data);
        CHECK_INT(ds_open(path, &d), 0);
        CHECK_INT(ds_count(d), 3);
        CHECK_INT(ds_verify(d), 0);
        CHECK_INT(ds_rows(d, 0, -1, check_row, &x), 3);
        CHECK_INT(ds_rows(d, 0, -1, check_image, d), 3);
        ds_close(d);
        return 0;
}
