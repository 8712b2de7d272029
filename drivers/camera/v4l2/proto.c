/* proto.c - the "v4l2" camera backend's rig-file map, pixel conversions, control names,
 * exposure units and timestamps, without I/O (see proto.h). */
#include <ctype.h>
#include <errno.h>
#include <libfyaml.h>
#include <stdint.h>
#include <stdio.h>
#include <linux/videodev2.h>
#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "common/cleanup.h"
#include "drivers/camera/camera.h"
#include "drivers/camera/v4l2/proto.h"

static const struct v4l2p_format formats[] = {
        {V4L2_PIX_FMT_YUYV, 3, 8, 2}, {V4L2_PIX_FMT_UYVY, 3, 8, 2}, {V4L2_PIX_FMT_RGB24, 3, 8, 3},
        {V4L2_PIX_FMT_GREY, 1, 8, 1}, {V4L2_PIX_FMT_Y16, 1, 16, 2},
};

const struct v4l2p_format *v4l2p_format_find(uint32_t fourcc)
{
        for (size_t i = 0; i < ELEMENTSOF(formats); i++)
                if (formats[i].fourcc == fourcc)
                        return &formats[i];
        return NULL;
}

int v4l2p_fourcc_parse(const char *s, uint32_t *fourcc)
{
        size_t n = strlen(s);
        char c[4] = {' ', ' ', ' ', ' '};

        if (n == 0 || n > 4)
                return -EINVAL;
        memcpy(c, s, n);
        *fourcc = v4l2_fourcc(c[0], c[1], c[2], c[3]);
        return 0;
}

const char *v4l2p_fourcc_str(uint32_t fourcc, char buf[static 5])
{
        for (int i = 0; i < 4; i++) {
                char ch = (char)((fourcc >> (8 * i)) & 0xff);
                buf[i] = isprint((unsigned char)ch) ? ch : '?';
        }
        buf[4] = '\0';
        return buf;
}

/* One row of another format than YUYV/UYVY into the frame's row. */
static void convert_row(const struct v4l2p_format *fmt, const uint8_t *src, uint8_t *dst, int width)
{
        if (fmt->fourcc == V4L2_PIX_FMT_YUYV || fmt->fourcc == V4L2_PIX_FMT_UYVY) {
                cam_yuv422_row_to_rgb8(src, dst, width, fmt->fourcc == V4L2_PIX_FMT_UYVY);
        } else if (fmt->fourcc == V4L2_PIX_FMT_Y16) {
                uint16_t *d = (uint16_t *)dst; /* Y16 is little-endian; frames host order */
                for (int x = 0; x < width; x++)
                        d[x] = (uint16_t)(src[2 * x] | src[2 * x + 1] << 8);
        } else {
                memcpy(dst, src, (size_t)width * (size_t)fmt->bytes_pp);
        }
}

int v4l2p_convert(const struct v4l2p_format *fmt, const uint8_t *src, size_t used, size_t stride,
                  struct gn_frame *out)
{
        size_t row = (size_t)out->width * (size_t)fmt->bytes_pp;

        if (out->height <= 0 || stride < row || used < stride * (size_t)(out->height - 1) + row)
                return -EBADMSG;
        for (int y = 0; y < out->height; y++)
                convert_row(fmt, src + stride * (size_t)y, out->data + out->stride * (size_t)y,
                            out->width);
        return 0;
}

void v4l2p_ctrl_name(const char *kernel_name, char *out, size_t len)
{
        size_t n = 0;
        bool sep = false;

        if (len == 0)
                return;
        for (const char *p = kernel_name; *p && n + 1 < len; p++) {
                if (!isalnum((unsigned char)*p)) {
                        sep = n > 0;
                        continue;
                }
                if (sep && n + 2 >= len)
                        break; /* no room for the separator and a character */
                if (sep)
                        out[n++] = '_';
                sep = false;
                out[n++] = (char)tolower((unsigned char)*p);
        }
        out[n] = '\0';
}

const char *v4l2p_ctrl_canonical(const char *name)
{
        static const char *const aliases[][2] = {
                {"exposure_absolute", "exposure_time_absolute"},
                {"exposure_auto", "auto_exposure"},
                {"white_balance_temperature_auto", "white_balance_automatic"},
                {"focus_auto", "focus_automatic_continuous"},
        };

        for (size_t i = 0; i < ELEMENTSOF(aliases); i++)
                if (strcmp(name, aliases[i][0]) == 0)
                        return aliases[i][1];
        return name;
}

struct v4l2_fract v4l2p_interval(double fps)
{
        return (struct v4l2_fract){1000, (uint32_t)lround(fps * 1000)};
}

double v4l2p_fps(const struct v4l2_fract *interval)
{
        return interval->numerator ? (double)interval->denominator / interval->numerator : 0;
}

long v4l2p_exposure_to_dev(int us)
{
        long v = (us + V4L2P_EXPOSURE_UNIT_US / 2) / V4L2P_EXPOSURE_UNIT_US;

        return v < 1 ? 1 : v;
}

int v4l2p_exposure_from_dev(long v)
{
        return (int)(v * V4L2P_EXPOSURE_UNIT_US);
}

uint64_t v4l2p_timestamp_ns(const struct timeval *tv, uint32_t flags, int64_t mono_to_real_ns,
                            int exposure_us)
{
        int64_t t;

        if ((flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC)
                return 0;
        t = (int64_t)tv->tv_sec * 1000000000 + (int64_t)tv->tv_usec * 1000 + mono_to_real_ns;
        if ((flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_EOF)
                t -= (int64_t)exposure_us * 1000;
        return t > 0 ? (uint64_t)t : 0;
}

/* Reads the controls map: control name (v4l2-ctl's spelling) to an integer value. */
static int parse_ctrls(struct yconf *yc, struct fy_node *m, struct cam_v4l2_conf *c)
{
        struct fy_node_pair *pair;
        void *iter = NULL;

        if (!m)
                return 0;
        if (fy_node_get_type(m) != FYNT_MAPPING)
                return yconf_error(yc, m, "controls", "expected a mapping of name: value");
        while ((pair = fy_node_mapping_iterate(m, &iter))) {
                const char *name = fy_node_get_scalar0(fy_node_pair_key(pair));
                struct v4l2p_ctrl *ct = &c->ctrls[c->n_ctrls];

                if (!name || !name[0] || strlen(name) >= V4L2P_CTRL_NAME)
                        return yconf_error(yc, fy_node_pair_key(pair), "controls",
                                           "a control name of 1 to %d characters",
                                           V4L2P_CTRL_NAME - 1);
                if (c->n_ctrls == V4L2P_CTRLS_MAX)
                        return yconf_error(yc, fy_node_pair_key(pair), name,
                                           "more than %d controls", V4L2P_CTRLS_MAX);
                if (yconf_int(yc, m, name, INT32_MIN, INT32_MAX, &ct->value) < 0)
                        return -EINVAL;
                snprintf(ct->name, sizeof(ct->name), "%s", v4l2p_ctrl_canonical(name));
                c->n_ctrls++;
        }
        return 0;
}

/* Reads format: a fourcc the backend converts. */
static int parse_format(struct yconf *yc, struct fy_node *m, struct cam_v4l2_conf *c)
{
        char s[8] = "";
        int r = yconf_str(yc, m, "format", s, sizeof(s));

        if (r <= 0)
                return r;
        if (v4l2p_fourcc_parse(s, &c->fourcc) < 0 || !v4l2p_format_find(c->fourcc))
                return yconf_error(yc, yconf_get(m, "format"), "format",
                                   "'%s' is not one of YUYV, UYVY, RGB3, GREY, Y16", s);
        return 0;
}

int cam_v4l2_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                        void *conf, struct rig_addr *addr)
{
        static const char *const keys[] = {"bus",     "device",   "card", "bus_info", "format",
                                           "buffers", "controls", "skip", "fps",      NULL};
        struct cam_v4l2_conf *c = conf;
        long buffers = V4L2P_BUFFERS_DEF, skip = 0;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_str(yc, m, "device", c->device, sizeof(c->device))) < 0 ||
            (r = yconf_str(yc, m, "card", c->card, sizeof(c->card))) < 0 ||
            (r = yconf_str(yc, m, "bus_info", c->bus_info, sizeof(c->bus_info))) < 0 ||
            (r = yconf_int(yc, m, "buffers", 2, V4L2P_BUFFERS_MAX, &buffers)) < 0 ||
            (r = yconf_int(yc, m, "skip", 0, V4L2P_SKIP_MAX, &skip)) < 0 ||
            (r = parse_format(yc, m, c)) < 0 ||
            (r = yconf_double(yc, m, "fps", 0.01, 1000, &c->fps)) < 0 ||
            (r = parse_ctrls(yc, yconf_get(m, "controls"), c)) < 0)
                return r;
        if (!!c->device[0] + !!c->card[0] + !!c->bus_info[0] != 1)
                return yconf_error(yc, m, "device",
                                   "name the node by exactly one of device, card, bus_info");
        c->buffers = (int)buffers;
        c->skip = (int)skip;
        return 0;
}
