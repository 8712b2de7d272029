/* proto.h - the "libcamera" camera backend's pure parts, without libcamera or I/O: its rig-file
 * map (which camera), the pixel formats it accepts and their conversion to gonio frames, the
 * sensor timestamp's clock, the sequence check of a stream, and the option table built from
 * the controls a camera offers. */
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "common/frame.h"
#include "common/rigconf.h"
#include "drivers/camera/libcamera/lc_shim.h"
#include "drivers/opt.h"

/* Longest camera id or model name, NUL included ("platform/vimc.0 Sensor B"). */
#define LCPROTO_ID_MAX 128

/* Which camera: by id when id[0], else the index-th camera (from 0, in libcamera's order)
 * whose Model property is model, or the index-th camera of all when model is "" too. */
struct lccam_conf {
        char id[LCPROTO_ID_MAX];
        char model[LCPROTO_ID_MAX];
        int index;
};

/* Parses "libcamera: { bus: cams, id: ID }" or "{ bus: cams, model: MODEL, index: N }" into conf
 * (a struct lccam_conf); id excludes model and index. addr gets no address (a camera is named
 * by id, which rigconf cannot compare). 0 or -EINVAL (yconf_error: file, line, key). */
int lcproto_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                       struct rig_addr *addr);

/* DRM fourccs (libcamera's formats::, linux/drm_fourcc.h; names give the bits of a
 * little-endian word, so BGR888 is R, G, B in memory). */
#define LCPROTO_FOURCC(a, b, c, d)                                                                 \
        ((uint32_t)(a) | (uint32_t)(b) << 8 | (uint32_t)(c) << 16 | (uint32_t)(d) << 24)
#define LCPROTO_BGR888   LCPROTO_FOURCC('B', 'G', '2', '4') /* R G B */
#define LCPROTO_RGB888   LCPROTO_FOURCC('R', 'G', '2', '4') /* B G R */
#define LCPROTO_XBGR8888 LCPROTO_FOURCC('X', 'B', '2', '4') /* R G B x */
#define LCPROTO_XRGB8888 LCPROTO_FOURCC('X', 'R', '2', '4') /* B G R x */
#define LCPROTO_R8       LCPROTO_FOURCC('R', '8', ' ', ' ') /* grey */
#define LCPROTO_YUYV     LCPROTO_FOURCC('Y', 'U', 'Y', 'V') /* Y0 U Y1 V (UVC cameras) */

/* The formats the backend converts, most preferred first (no reordering first): the i-th, or 0
 * past the last (LCPROTO_N_FORMATS). */
#define LCPROTO_N_FORMATS 6
uint32_t lcproto_format_at(size_t i);

/* Converts a width x height image of format fourcc (rows stride bytes apart, bytes in all)
 * into out, which it allocates (rgb8, or mono8 for R8; YUYV as BT.601 limited range; owned by the
 * caller, gn_frame_free_data). Returns 0; -EINVAL for a format not in that list; -EBADMSG when
 * stride or bytes are too short for the shape; -ENOMEM. */
int lcproto_convert(uint32_t fourcc, const uint8_t *src, size_t bytes, size_t stride, int width,
                    int height, struct gn_frame *out);

/* The format's name ("BGR888"), or "?" for any other. Never NULL. */
const char *lcproto_format_name(uint32_t fourcc);

/* A CLOCK_MONOTONIC time (libcamera's SensorTimestamp, start of exposure) on CLOCK_REALTIME,
 * given both clocks read at one moment. Never fails; 0 when the result would be negative. */
uint64_t lcproto_mono_to_realtime(uint64_t mono_ns, uint64_t mono_now_ns, uint64_t real_now_ns);

/* The next sequence number of a stream before its first frame: any is accepted. */
#define LCPROTO_SEQ_NONE UINT64_MAX

/* Checks a streamed frame's sequence number seq against *next, the one expected
 * (LCPROTO_SEQ_NONE before the first frame), and sets *next to seq + 1. Returns 0, or -EIO
 * with the cause in msg when frames were dropped (a gap: "2 frames dropped (sequence 14
 * after 11)") or seq went back. Pure. */
int lcproto_check_seq(uint64_t *next, uint64_t seq, char *msg, size_t len);

/* Longest option table lcproto_opts() writes. */
#define LCPROTO_OPTS_MAX 3

/* Writes the camera's option table into opts (LCPROTO_OPTS_MAX entries): OPT_BITS (8 only),
 * plus OPT_EXPOSURE and OPT_GAIN with the camera's ranges when it offers the control, so
 * cam_check_request() refuses the others with -EOPNOTSUPP. Returns the entries written. */
int lcproto_opts(const struct lc_caps *caps, struct opt_desc *opts);
