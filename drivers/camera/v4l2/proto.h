/* proto.h - the pure part of the "v4l2" camera backend, without I/O: its rig-file map
 * (struct cam_v4l2_conf), the pixel formats it converts to the class's frame formats
 * (YUYV and UYVY to rgb8, RGB3 to rgb8, GREY to mono8, Y16 to mono16), control names as
 * v4l2-ctl spells them, exposure units and buffer timestamps (docs/drivers.md, "V4L2
 * cameras"). */
#pragma once

#include <stddef.h>
#include <stdint.h>
#include <linux/videodev2.h>
#include <sys/time.h>

#include "common/frame.h"
#include "common/rigconf.h"

#define V4L2P_CTRLS_MAX        16 /* entries of a camera's controls map */
#define V4L2P_CTRL_NAME        32 /* longest control name, NUL included (the kernel's bound) */
#define V4L2P_BUFFERS_MAX      32
#define V4L2P_BUFFERS_DEF      4
#define V4L2P_SKIP_MAX         30
#define V4L2P_EXPOSURE_UNIT_US 100 /* V4L2_CID_EXPOSURE_ABSOLUTE counts 100 us */

struct v4l2p_ctrl {
        char name[V4L2P_CTRL_NAME]; /* canonical (v4l2p_ctrl_canonical) */
        long value;
};

/* What the backend reads from "v4l2: { bus, device | card | bus_info, format, fps, controls,
 * buffers, skip }": exactly one of device, card and bus_info names the node. */
struct cam_v4l2_conf {
        char device[RIG_PATH_MAX]; /* "/dev/video0" */
        char card[32];             /* VIDIOC_QUERYCAP card, e.g. "HD Pro Webcam C920" */
        char bus_info[32];         /* VIDIOC_QUERYCAP bus_info, e.g. "usb-0000:00:14.0-1" */
        uint32_t fourcc;           /* 0: the first format the driver lists that we convert */
        double fps;                /* frame rate to set; 0: the driver's */
        int buffers;               /* mmap buffers, 2..V4L2P_BUFFERS_MAX */
        int skip;                  /* frames dropped after each start, 0..V4L2P_SKIP_MAX */
        struct v4l2p_ctrl ctrls[V4L2P_CTRLS_MAX];
        int n_ctrls;
};

/* A pixel format the backend converts, and the frame it gives. */
struct v4l2p_format {
        uint32_t fourcc;
        int channels, bits; /* of the frame produced */
        int bytes_pp;       /* bytes per pixel in the V4L2 buffer */
};

/* Parses the backend map m into conf (a struct cam_v4l2_conf); the rig_backend parser. */
int cam_v4l2_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                        void *conf, struct rig_addr *addr);

/* The format of fourcc, or NULL when the backend does not convert it. */
const struct v4l2p_format *v4l2p_format_find(uint32_t fourcc);

/* Reads a fourcc written as its four characters ("YUYV"; shorter ones padded with spaces:
 * "Y16"). Returns 0 or -EINVAL. */
int v4l2p_fourcc_parse(const char *s, uint32_t *fourcc);

/* Writes fourcc as text (5 bytes with the NUL, trailing spaces kept) into buf; returns buf. */
const char *v4l2p_fourcc_str(uint32_t fourcc, char buf[static 5]);

/* Converts one V4L2 buffer of format fmt (src, used bytes, rows stride bytes apart) into
 * out, already allocated with fmt's channels and bits and the image's size. Returns 0, or
 * -EBADMSG when used is short of a whole image. */
int v4l2p_convert(const struct v4l2p_format *fmt, const uint8_t *src, size_t used, size_t stride,
                  struct gn_frame *out);

/* The name v4l2-ctl gives a control: the kernel's name in lower case, each run of other
 * characters than letters and digits one '_', none at the ends ("Exposure Time, Absolute"
 * -> "exposure_time_absolute"). out gets at most len - 1 characters. */
void v4l2p_ctrl_name(const char *kernel_name, char *out, size_t len);

/* The current name of a control for an older spelling still in use
 * ("exposure_absolute" -> "exposure_time_absolute"); name itself otherwise. */
const char *v4l2p_ctrl_canonical(const char *name);

/* A frame rate as the frame interval VIDIOC_S_PARM takes (in ms: 1000 / (fps * 1000)), and
 * an interval num/den back as a rate (0 for a zero numerator). */
struct v4l2_fract v4l2p_interval(double fps);
double v4l2p_fps(const struct v4l2_fract *interval);

/* Exposure in us to V4L2_CID_EXPOSURE_ABSOLUTE's 100 us units (nearest, at least 1), and
 * back. */
long v4l2p_exposure_to_dev(int us);
int v4l2p_exposure_from_dev(long v);

/* CLOCK_REALTIME at exposure start, in ns, of a buffer timestamped tv with V4L2 buffer
 * flags, given realtime - monotonic (ns) at dequeue and the exposure applied (0: unknown).
 * Monotonic timestamps only: returns 0 for another clock (the caller uses the dequeue
 * time). An end-of-frame timestamp (V4L2_BUF_FLAG_TSTAMP_SRC_EOF) is moved back by the
 * exposure. */
uint64_t v4l2p_timestamp_ns(const struct timeval *tv, uint32_t flags, int64_t mono_to_real_ns,
                            int exposure_us);
