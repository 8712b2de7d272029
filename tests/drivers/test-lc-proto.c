/* test-lc-proto.c - the libcamera backend's pure parts (drivers/camera/libcamera/proto.c):
 * each pixel format converted to rgb8/mono8 with its channel order and row stride (YUYV
 * with BT.601 colours), short
 * buffers refused, the sensor clock moved onto the wall clock, the option table built from a
 * camera's controls, a stream's sequence check (dropped frames), and the rig-file map parsed
 * with file:line:key errors. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "drivers/camera/libcamera/proto.h"
#include "drivers/registry.h"
#include "tests/test.h"

/* A 2x2 image of format fourcc with bpp bytes per pixel and stride 8: pixel (x, y) has bytes
 * 10*(2y+x)+k at k = 0..bpp-1, padding bytes 0xee. */
static void make_image(uint8_t *buf, int bpp)
{
        memset(buf, 0xee, 16);
        for (int y = 0; y < 2; y++)
                for (int x = 0; x < 2; x++)
                        for (int k = 0; k < bpp; k++)
                                buf[y * 8 + x * bpp + k] = (uint8_t)(10 * (2 * y + x) + k);
}

/* Converts the 2x2 image and checks pixel (1, 1): bytes 30+r, 30+g, 30+b. */
static void check_convert(uint32_t fourcc, int bpp, int r, int g, int b)
{
        struct gn_frame f = {};
        uint8_t buf[16];

        make_image(buf, bpp);
        CHECK_INT(lcproto_convert(fourcc, buf, sizeof(buf), 8, 2, 2, &f), 0);
        CHECK_STR(gn_frame_format(&f), "rgb8");
        CHECK_INT(f.width, 2);
        CHECK_INT(f.data[0], 0 + r);
        CHECK_INT(f.data[3 * 3 + 0], 30 + r);
        CHECK_INT(f.data[3 * 3 + 1], 30 + g);
        CHECK_INT(f.data[3 * 3 + 2], 30 + b);
        gn_frame_free_data(&f);
}

static void test_convert(void)
{
        struct gn_frame f = {};
        uint8_t buf[16];

        check_convert(LCPROTO_BGR888, 3, 0, 1, 2); /* R G B in memory */
        check_convert(LCPROTO_RGB888, 3, 2, 1, 0); /* B G R */
        check_convert(LCPROTO_XBGR8888, 4, 0, 1, 2);
        check_convert(LCPROTO_XRGB8888, 4, 2, 1, 0);

        make_image(buf, 1);
        CHECK_INT(lcproto_convert(LCPROTO_R8, buf, sizeof(buf), 8, 2, 2, &f), 0);
        CHECK_STR(gn_frame_format(&f), "mono8");
        CHECK_INT(f.data[3], 30);
        gn_frame_free_data(&f);

        /* the last row needs only its pixels, not the whole stride */
        CHECK_INT(lcproto_convert(LCPROTO_BGR888, buf, 8 + 6, 8, 2, 2, &f), 0);
        gn_frame_free_data(&f);
        CHECK_INT(lcproto_convert(LCPROTO_BGR888, buf, 8 + 5, 8, 2, 2, &f), -EBADMSG);
        CHECK_INT(lcproto_convert(LCPROTO_BGR888, buf, 16, 5, 2, 2, &f), -EBADMSG);
        CHECK_INT(lcproto_convert(LCPROTO_FOURCC('N', 'V', '1', '2'), buf, 16, 8, 2, 2, &f),
                  -EINVAL);
        CHECK_STR(lcproto_format_name(LCPROTO_RGB888), "RGB888");
        CHECK_STR(lcproto_format_name(0), "?");
        CHECK_INT(lcproto_format_at(0), LCPROTO_BGR888);
        CHECK_INT(lcproto_format_at(LCPROTO_N_FORMATS), 0);
}

/* YUYV, BT.601 limited range: white, black, then a red pair; width 3 takes a whole pair. */
static void test_yuyv(void)
{
        static const uint8_t yuyv[2 * 8] = {235, 128, 16, 128, 81, 90, 81, 240,
                                            235, 128, 16, 128, 81, 90, 81, 240};
        static const uint8_t want[3][3] = {{255, 255, 255}, {0, 0, 0}, {255, 0, 0}};
        struct gn_frame f = {};

        CHECK_INT(lcproto_convert(LCPROTO_YUYV, yuyv, sizeof(yuyv), 8, 3, 2, &f), 0);
        CHECK_STR(gn_frame_format(&f), "rgb8");
        for (int y = 0; y < 2; y++)
                for (int x = 0; x < 3; x++)
                        for (int k = 0; k < 3; k++)
                                CHECK_INT(f.data[y * f.stride + x * 3 + k], want[x][k]);
        gn_frame_free_data(&f);
        CHECK_INT(lcproto_convert(LCPROTO_YUYV, yuyv, sizeof(yuyv) - 1, 8, 3, 2, &f), -EBADMSG);
        CHECK_INT(lcproto_convert(LCPROTO_YUYV, yuyv, sizeof(yuyv), 6, 3, 2, &f), -EBADMSG);
}

static void test_clock(void)
{
        /* stamped 2 ms before the clocks were read */
        CHECK_INT(lcproto_mono_to_realtime(1000000, 3000000, 5000000000), 4998000000);
        /* stamped after */
        CHECK_INT(lcproto_mono_to_realtime(4000000, 3000000, 5000000000), 5001000000);
        CHECK_INT(lcproto_mono_to_realtime(0, 9000000000, 5000000000), 0);
}

static void test_opts(void)
{
        struct opt_desc o[LCPROTO_OPTS_MAX];
        struct lc_caps caps = {0};

        CHECK_INT(lcproto_opts(&caps, o), 1);
        CHECK_INT(o[0].key, OPT_BITS);
        CHECK_INT(o[0].max, 8);
        caps = (struct lc_caps){.has_exposure = 1,
                                .exposure_min_us = 14,
                                .exposure_max_us = 66666,
                                .has_gain = 1,
                                .gain_min = 1,
                                .gain_max = 16};
        CHECK_INT(lcproto_opts(&caps, o), 3);
        CHECK_INT(o[1].key, OPT_EXPOSURE);
        CHECK_INT(o[1].min, 14);
        CHECK_INT(o[1].max, 66666);
        CHECK_INT(o[2].key, OPT_GAIN);
        CHECK_INT(o[2].max, 16);
}

/* Loads a rig file whose one camera has the backend map MAP; returns rigconf_load's result
 * with its message in err, and the parsed conf in *conf when it loaded. */
static int load(const char *map, char *err, size_t len, struct lccam_conf *conf)
{
        char path[] = "/tmp/test-lc-proto.XXXXXX";
        struct rig_config *rc = NULL;
        int fd = mkstemp(path), r;
        FILE *f = fdopen(fd, "w");

        CHECK(f);
        fprintf(f,
                "rig: t\nbuses:\n  - { name: cams, type: local }\ncameras:\n"
                "  - name: cam0\n    libcamera: %s\n",
                map);
        CHECK(fclose(f) == 0);
        err[0] = '\0';
        r = rigconf_load(path, registry_backends, &rc, err, len);
        if (r >= 0)
                *conf = *(const struct lccam_conf *)rc->cameras[0].backend.conf;
        rigconf_free(rc);
        unlink(path);
        return r;
}

/* A stream's sequence numbers: the first frame sets them, a gap is dropped frames (-EIO,
 * naming how many and where), a step back is an error too, and the stream goes on after. */
static void test_seq(void)
{
        uint64_t next = LCPROTO_SEQ_NONE;
        char msg[128] = "";

        CHECK_INT(lcproto_check_seq(&next, 11, msg, sizeof(msg)), 0);
        CHECK_INT(lcproto_check_seq(&next, 12, msg, sizeof(msg)), 0);
        CHECK_INT(lcproto_check_seq(&next, 15, msg, sizeof(msg)), -EIO);
        CHECK_STR(msg, "2 frames dropped (sequence 15 after 12)");
        CHECK_INT(lcproto_check_seq(&next, 16, msg, sizeof(msg)), 0);
        CHECK_INT(lcproto_check_seq(&next, 18, msg, sizeof(msg)), -EIO);
        CHECK_STR(msg, "1 frame dropped (sequence 18 after 16)");
        CHECK_INT(lcproto_check_seq(&next, 3, msg, sizeof(msg)), -EIO);
        CHECK_STR(msg, "frame sequence went back (3 after 18)");
        CHECK_INT(lcproto_check_seq(&next, 4, msg, sizeof(msg)), 0);
}

static void test_conf(void)
{
        struct lccam_conf c;
        char err[512];

        CHECK_INT(load("{ bus: cams, id: 'platform/vimc.0 Sensor B' }", err, sizeof(err), &c), 0);
        CHECK_STR(c.id, "platform/vimc.0 Sensor B");
        CHECK_STR(c.model, "");
        CHECK_INT(load("{ bus: cams, model: imx219, index: 1 }", err, sizeof(err), &c), 0);
        CHECK_STR(c.id, "");
        CHECK_STR(c.model, "imx219");
        CHECK_INT(c.index, 1);
        CHECK_INT(load("{ bus: cams }", err, sizeof(err), &c), 0);
        CHECK_INT(c.index, 0);

        CHECK_INT(load("{ bus: cams, id: a, model: b }", err, sizeof(err), &c), -EINVAL);
        CHECK_STR_CONTAINS(err, ":6: key 'id'");
        CHECK_STR_CONTAINS(err, "drop model and index");
        CHECK_INT(load("{ bus: cams, id: '' }", err, sizeof(err), &c), -EINVAL);
        CHECK_STR_CONTAINS(err, "empty camera id");
        CHECK_INT(load("{ bus: cams, device: /dev/video0 }", err, sizeof(err), &c), -EINVAL);
        CHECK_STR_CONTAINS(err, "device");
        CHECK_INT(load("{ bus: cams, index: -1 }", err, sizeof(err), &c), -EINVAL);
        CHECK_STR_CONTAINS(err, "index");
}

int main(void)
{
        test_convert();
        test_yuyv();
        test_seq();
        test_clock();
        test_opts();
        test_conf();
        return 0;
}
