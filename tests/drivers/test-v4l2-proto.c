/* test-v4l2-proto.c - the pure part of the "v4l2" camera backend (drivers/camera/v4l2/
 * proto.c) on the host: YUYV/UYVY to RGB against BT.601's published colour-bar values,
 * buffer conversion with padded rows and short buffers, Y16 byte order, v4l2-ctl's control
 * names and the older spellings, exposure units, buffer timestamps to CLOCK_REALTIME, and
 * the rig-file map (through rigconf_load, with file:line:key errors).
 * Usage: test-v4l2-proto [CASE]. */
#include <linux/videodev2.h>

#include "common/cleanup.h"
#include "drivers/camera/camera.h"
#include "drivers/camera/v4l2/proto.h"
#include "drivers/registry.h"
#include "tests/test.h"

static void check_px(const uint8_t *p, int r, int g, int b, int tol)
{
        CHECK_NEAR(p[0], r, tol);
        CHECK_NEAR(p[1], g, tol);
        CHECK_NEAR(p[2], b, tol);
}

/* 75% colour bars in 8-bit BT.601 limited range (ITU-R BT.801): Y'CbCr -> R'G'B' 191/0. */
static void t_yuyv(void)
{
        static const uint8_t bars[][3] = {
                {180, 128, 128}, {162, 44, 142}, {131, 156, 44}, {112, 72, 58},
                {84, 184, 198},  {65, 100, 212}, {35, 212, 114}, {16, 128, 128},
        };
        static const int rgb[][3] = {{191, 191, 191}, {191, 191, 0}, {0, 191, 191}, {0, 191, 0},
                                     {191, 0, 191},   {191, 0, 0},   {0, 0, 191},   {0, 0, 0}};

        for (size_t i = 0; i < ELEMENTSOF(bars); i++) {
                const uint8_t y = bars[i][0], u = bars[i][1], v = bars[i][2];
                const uint8_t yuyv[4] = {y, u, y, v}, uyvy[4] = {u, y, v, y};
                uint8_t out[6], out2[6];

                cam_yuv422_row_to_rgb8(yuyv, out, 2, 0);
                cam_yuv422_row_to_rgb8(uyvy, out2, 2, 1);
                check_px(out, rgb[i][0], rgb[i][1], rgb[i][2], 2);
                check_px(out + 3, rgb[i][0], rgb[i][1], rgb[i][2], 2);
                CHECK(memcmp(out, out2, 6) == 0);
        }
        /* nominal white and black, and clipping beyond them */
        uint8_t w[6], k[6];
        cam_yuv422_row_to_rgb8((const uint8_t[]){235, 128, 255, 128}, w, 2, 0);
        check_px(w, 255, 255, 255, 0);
        check_px(w + 3, 255, 255, 255, 0);
        cam_yuv422_row_to_rgb8((const uint8_t[]){16, 128, 0, 128}, k, 2, 0);
        check_px(k, 0, 0, 0, 0);
        check_px(k + 3, 0, 0, 0, 0);
        /* each pixel of a pair keeps its own luma; an odd width converts the last one */
        uint8_t three[9] = {0};
        cam_yuv422_row_to_rgb8((const uint8_t[]){16, 128, 235, 128, 126, 128, 0, 128}, three, 3, 0);
        check_px(three, 0, 0, 0, 0);
        check_px(three + 3, 255, 255, 255, 0);
        check_px(three + 6, 128, 128, 128, 1);
}

/* Whole buffers: padded rows skipped, a short buffer refused, Y16 little-endian to host. */
static void t_convert(void)
{
        const struct v4l2p_format *yuyv = v4l2p_format_find(V4L2_PIX_FMT_YUYV);
        const struct v4l2p_format *y16 = v4l2p_format_find(V4L2_PIX_FMT_Y16);
        uint8_t buf[2 * 12];
        struct gn_frame f = {0};

        CHECK(yuyv && y16 && !v4l2p_format_find(V4L2_PIX_FMT_MJPEG));
        CHECK_INT(yuyv->channels, 3);
        CHECK_INT(y16->bits, 16);
        memset(buf, 0xee, sizeof(buf)); /* padding: would convert to a colour */
        memcpy(buf, (const uint8_t[]){235, 128, 235, 128}, 4);
        memcpy(buf + 12, (const uint8_t[]){16, 128, 16, 128}, 4);
        CHECK_INT(gn_frame_alloc(&f, 2, 2, 3, 8), 0);
        CHECK_INT(v4l2p_convert(yuyv, buf, 12 + 4, 12, &f), 0);
        check_px(f.data, 255, 255, 255, 0);
        check_px(f.data + f.stride, 0, 0, 0, 0);
        CHECK_INT(v4l2p_convert(yuyv, buf, 12 + 3, 12, &f), -EBADMSG);
        CHECK_INT(v4l2p_convert(yuyv, buf, sizeof(buf), 3, &f), -EBADMSG); /* stride < row */
        gn_frame_free_data(&f);

        CHECK_INT(gn_frame_alloc(&f, 2, 1, 1, 16), 0);
        CHECK_INT(v4l2p_convert(y16, (const uint8_t[]){0x34, 0x12, 0xff, 0x00}, 4, 4, &f), 0);
        CHECK_INT(((uint16_t *)f.data)[0], 0x1234);
        CHECK_INT(((uint16_t *)f.data)[1], 0x00ff);
        gn_frame_free_data(&f);
}

static void t_fourcc(void)
{
        uint32_t fc = 0;
        char s[5];

        CHECK_INT(v4l2p_fourcc_parse("YUYV", &fc), 0);
        CHECK_INT(fc, V4L2_PIX_FMT_YUYV);
        CHECK_INT(v4l2p_fourcc_parse("Y16", &fc), 0);
        CHECK_INT(fc, V4L2_PIX_FMT_Y16);
        CHECK_STR(v4l2p_fourcc_str(fc, s), "Y16 ");
        CHECK_INT(v4l2p_fourcc_parse("YUYV2", &fc), -EINVAL);
        CHECK_INT(v4l2p_fourcc_parse("", &fc), -EINVAL);
}

/* Control names as v4l2-ctl prints them, and the older spellings mapped to the current. */
static void t_ctrl_names(void)
{
        static const char *const cases[][2] = {
                {"Exposure Time, Absolute", "exposure_time_absolute"},
                {"Gain, Automatic", "gain_automatic"},
                {"  White Balance  Temperature ", "white_balance_temperature"},
                {"Brightness", "brightness"},
                {"Integer 32 Bits", "integer_32_bits"},
                {"Power Line Frequency", "power_line_frequency"},
        };
        char out[V4L2P_CTRL_NAME], tiny[6];

        for (size_t i = 0; i < ELEMENTSOF(cases); i++) {
                v4l2p_ctrl_name(cases[i][0], out, sizeof(out));
                CHECK_STR(out, cases[i][1]);
        }
        v4l2p_ctrl_name("Gain, Automatic", tiny, sizeof(tiny));
        CHECK_STR(tiny, "gain");
        CHECK_STR(v4l2p_ctrl_canonical("exposure_absolute"), "exposure_time_absolute");
        CHECK_STR(v4l2p_ctrl_canonical("exposure_auto"), "auto_exposure");
        CHECK_STR(v4l2p_ctrl_canonical("gain"), "gain");
}

/* The class's exposure in us against V4L2_CID_EXPOSURE_ABSOLUTE's 100 us units. */
static void t_exposure(void)
{
        CHECK_INT(v4l2p_exposure_to_dev(10000), 100);
        CHECK_INT(v4l2p_exposure_to_dev(149), 1);
        CHECK_INT(v4l2p_exposure_to_dev(150), 2);
        CHECK_INT(v4l2p_exposure_to_dev(30), 1); /* never 0: the shortest the unit allows */
        CHECK_INT(v4l2p_exposure_from_dev(3), 300);
        CHECK_INT(v4l2p_exposure_from_dev(v4l2p_exposure_to_dev(20000)), 20000);
}

/* Frame rates as VIDIOC_S_PARM's intervals and back. */
static void t_fps(void)
{
        struct v4l2_fract f = v4l2p_interval(12.5);

        CHECK_INT(f.numerator, 1000);
        CHECK_INT(f.denominator, 12500);
        CHECK_NEAR(v4l2p_fps(&f), 12.5, 1e-12);
        CHECK_NEAR(v4l2p_fps(&(struct v4l2_fract){1, 30}), 30, 1e-12);
        CHECK_NEAR(v4l2p_fps(&(struct v4l2_fract){0, 30}), 0, 0);
}

/* Monotonic buffer stamps to CLOCK_REALTIME at exposure start; other clocks unknown. */
static void t_timestamp(void)
{
        const struct timeval tv = {.tv_sec = 100, .tv_usec = 250};
        const int64_t off = 1700000000LL * 1000000000LL;
        const uint32_t mono = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;

        CHECK_INT(v4l2p_timestamp_ns(&tv, mono | V4L2_BUF_FLAG_TSTAMP_SRC_SOE, off, 5000),
                  off + 100000250000LL);
        CHECK_INT(v4l2p_timestamp_ns(&tv, mono | V4L2_BUF_FLAG_TSTAMP_SRC_EOF, off, 5000),
                  off + 100000250000LL - 5000000);
        CHECK_INT(v4l2p_timestamp_ns(&tv, mono, off, 0), off + 100000250000LL);
        CHECK_INT(v4l2p_timestamp_ns(&tv, V4L2_BUF_FLAG_TIMESTAMP_COPY, off, 0), 0);
        CHECK_INT(v4l2p_timestamp_ns(&tv, V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN, off, 0), 0);
}

static const char rig_head[] = "rig: t\n"
                               "buses:\n"
                               "  - { name: cams, type: local }\n"
                               "  - { name: cams2, type: local }\n"
                               "cameras:\n"
                               "  - name: c\n"
                               "    width: 640\n"
                               "    height: 480\n"
                               "    fx: 500\n"
                               "    fy: 500\n";

/* Loads rig_head plus the camera's v4l2 map (line 11); returns rigconf_load's result. */
static int load(const char *map, struct rig_config **rc, char *err, size_t len)
{
        char path[] = "/tmp/test-v4l2-XXXXXX", text[1024];
        int fd = mkstemp(path), r;

        CHECK(fd >= 0);
        snprintf(text, sizeof(text), "%s    v4l2: %s\n", rig_head, map);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        close(fd);
        err[0] = '\0';
        r = rigconf_load(path, registry_backends, rc, err, len);
        unlink(path);
        return r;
}

static void expect_error(const char *map, const char *msg)
{
        struct rig_config *rc = NULL;
        char err[512];

        CHECK_INT(load(map, &rc, err, sizeof(err)), -EINVAL);
        fprintf(stderr, "%s\n", err);
        CHECK_STR_CONTAINS(err, ":11: ");
        CHECK_STR_CONTAINS(err, msg);
}

/* The rig-file map: every key read, controls by canonical name, mistakes refused. */
static void t_conf(void)
{
        struct rig_config *rc = NULL;
        char err[512];

        CHECK_INT(load("{ bus: cams, bus_info: 'usb-0000:00:14.0-1', format: UYVY, fps: 12.5, "
                       "buffers: 6, "
                       "skip: 3, "
                       "controls: { exposure_absolute: 250, brightness: -3, auto_exposure: 1 } }",
                       &rc, err, sizeof(err)),
                  0);
        const struct cam_v4l2_conf *c = rc->cameras[0].backend.conf;
        CHECK_STR(c->bus_info, "usb-0000:00:14.0-1");
        CHECK_INT(c->fourcc, V4L2_PIX_FMT_UYVY);
        CHECK_NEAR(c->fps, 12.5, 0);
        CHECK_INT(c->buffers, 6);
        CHECK_INT(c->skip, 3);
        CHECK_INT(c->n_ctrls, 3);
        CHECK_STR(c->ctrls[0].name, "exposure_time_absolute");
        CHECK_INT(c->ctrls[0].value, 250);
        CHECK_INT(c->ctrls[1].value, -3);
        rigconf_free(rc);
        CHECK_INT(load("{ bus: cams, device: /dev/video0 }", &rc, err, sizeof(err)), 0);
        c = rc->cameras[0].backend.conf;
        CHECK_STR(c->device, "/dev/video0");
        CHECK_INT(c->fourcc, 0);
        CHECK_INT(c->buffers, V4L2P_BUFFERS_DEF);
        rigconf_free(rc);

        expect_error("{ bus: cams }", "name the node by exactly one of device, card, bus_info");
        expect_error("{ bus: cams, device: /dev/video0, card: Cam }", "exactly one of");
        expect_error("{ bus: cams, device: /dev/video0, format: MJPG }", "'MJPG' is not one of");
        expect_error("{ bus: cams, device: /dev/video0, buffers: 1 }", "key 'buffers'");
        expect_error("{ bus: cams, device: /dev/video0, skip: 31 }", "key 'skip'");
        expect_error("{ bus: cams, device: /dev/video0, fps: 0 }", "key 'fps'");
        expect_error("{ bus: cams, device: /dev/video0, unit: 1 }", "key 'unit': unknown key");
        expect_error("{ bus: cams, device: /dev/video0, controls: { gain: high } }",
                     "key 'gain': 'high' is not an integer");
        expect_error("{ bus: cams, device: /dev/video0, controls: [ gain ] }",
                     "expected a mapping of name: value");
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"yuyv", t_yuyv},           {"convert", t_convert},
                {"fourcc", t_fourcc},       {"ctrl-names", t_ctrl_names},
                {"exposure", t_exposure},   {"fps", t_fps},
                {"timestamp", t_timestamp}, {"conf", t_conf},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
