/* proto.c - the "libcamera" backend's pure parts (see proto.h): rig-file map, pixel format
 * conversion, clock conversion and the option table, all without libcamera or I/O. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/yconf.h"
#include "drivers/camera/camera.h"
#include "drivers/camera/libcamera/proto.h"

int lcproto_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                       struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "id", "model", "index", NULL};
        struct lccam_conf *c = conf;
        long index = 0;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_str(yc, m, "id", c->id, sizeof(c->id))) < 0 ||
            (r = yconf_str(yc, m, "model", c->model, sizeof(c->model))) < 0 ||
            (r = yconf_int(yc, m, "index", 0, RIG_MAX_CAMERAS * 8, &index)) < 0)
                return r;
        if (c->id[0] && (yconf_get(m, "model") || yconf_get(m, "index")))
                return yconf_error(yc, yconf_get(m, "id"), "id",
                                   "names the camera already: drop model and index");
        if (yconf_get(m, "id") && !c->id[0])
                return yconf_error(yc, yconf_get(m, "id"), "id", "empty camera id");
        c->index = (int)index;
        *addr = (struct rig_addr){0};
        return 0;
}

/* One accepted format: its name, bytes per pixel, where R, G, B sit in a pixel (packed
 * RGB), and the function that converts a row of it. */
struct fmt {
        uint32_t fourcc;
        const char *name;
        int bpp, r, g, b;
        void (*row)(const struct fmt *f, const uint8_t *src, uint8_t *dst, int width);
};

static void rgb_row(const struct fmt *f, const uint8_t *src, uint8_t *dst, int width)
{
        for (int x = 0; x < width; x++, src += f->bpp, dst += 3) {
                dst[0] = src[f->r];
                dst[1] = src[f->g];
                dst[2] = src[f->b];
        }
}

static void grey_row(const struct fmt *f, const uint8_t *src, uint8_t *dst, int width)
{
        memcpy(dst, src, (size_t)width);
}

static void yuyv_row(const struct fmt *f, const uint8_t *src, uint8_t *dst, int width)
{
        cam_yuv422_row_to_rgb8(src, dst, width, false);
}

static const struct fmt fmts[] = {
        {LCPROTO_BGR888, "BGR888", 3, 0, 1, 2, rgb_row},
        {LCPROTO_RGB888, "RGB888", 3, 2, 1, 0, rgb_row},
        {LCPROTO_XBGR8888, "XBGR8888", 4, 0, 1, 2, rgb_row},
        {LCPROTO_XRGB8888, "XRGB8888", 4, 2, 1, 0, rgb_row},
        {LCPROTO_R8, "R8", 1, 0, 0, 0, grey_row},
        {LCPROTO_YUYV, "YUYV", 2, 0, 0, 0, yuyv_row},
};

_Static_assert(ELEMENTSOF(fmts) == LCPROTO_N_FORMATS, "LCPROTO_N_FORMATS");

uint32_t lcproto_format_at(size_t i)
{
        return i < ELEMENTSOF(fmts) ? fmts[i].fourcc : 0;
}

static const struct fmt *find_fmt(uint32_t fourcc)
{
        for (size_t i = 0; i < ELEMENTSOF(fmts); i++)
                if (fmts[i].fourcc == fourcc)
                        return &fmts[i];
        return NULL;
}

const char *lcproto_format_name(uint32_t fourcc)
{
        const struct fmt *f = find_fmt(fourcc);

        return f ? f->name : "?";
}

int lcproto_convert(uint32_t fourcc, const uint8_t *src, size_t bytes, size_t stride, int width,
                    int height, struct gn_frame *out)
{
        const struct fmt *f = find_fmt(fourcc);
        size_t row;
        int r;

        if (!f || width <= 0 || height <= 0)
                return -EINVAL;
        row = (size_t)width * f->bpp + (f->row == yuyv_row ? (size_t)(width % 2) * 2 : 0);
        if (stride < row || bytes < stride * (size_t)(height - 1) + row)
                return -EBADMSG;
        r = gn_frame_alloc(out, width, height, f->row == grey_row ? 1 : 3, 8);
        if (r < 0)
                return r;
        for (int y = 0; y < height; y++)
                f->row(f, src + stride * y, out->data + out->stride * y, width);
        return 0;
}

uint64_t lcproto_mono_to_realtime(uint64_t mono_ns, uint64_t mono_now_ns, uint64_t real_now_ns)
{
        uint64_t age = mono_now_ns > mono_ns ? mono_now_ns - mono_ns : 0;

        if (mono_ns > mono_now_ns) /* stamped after the clocks were read */
                return real_now_ns + (mono_ns - mono_now_ns);
        return real_now_ns > age ? real_now_ns - age : 0;
}

int lcproto_opts(const struct lc_caps *caps, struct opt_desc *opts)
{
        int n = 0;

        opts[n++] = (struct opt_desc){OPT_BITS, OPT_GET | OPT_SET | OPT_LIST, .min = 8, .max = 8};
        if (caps->has_exposure)
                opts[n++] = (struct opt_desc){OPT_EXPOSURE, OPT_GET | OPT_SET, .unit = "us",
                                              .min = caps->exposure_min_us,
                                              .max = caps->exposure_max_us};
        if (caps->has_gain)
                opts[n++] = (struct opt_desc){OPT_GAIN, OPT_GET | OPT_SET, .min = caps->gain_min,
                                              .max = caps->gain_max};
        return n;
}

int lcproto_check_seq(uint64_t *next, uint64_t seq, char *msg, size_t len)
{
        uint64_t want = *next;

        *next = seq + 1;
        if (want == LCPROTO_SEQ_NONE || seq == want)
                return 0;
        if (seq > want)
                snprintf(msg, len, "%llu frame%s dropped (sequence %llu after %llu)",
                         (unsigned long long)(seq - want), seq - want == 1 ? "" : "s",
                         (unsigned long long)seq, (unsigned long long)(want - 1));
        else
                snprintf(msg, len, "frame sequence went back (%llu after %llu)",
                         (unsigned long long)seq, (unsigned long long)(want - 1));
        return -EIO;
}
