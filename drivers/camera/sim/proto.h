/* proto.h - the messages of gonio-sim's frame socket (docs/sim.md, "Frame socket"),
 * encoded and decoded without I/O: the render request line a client sends and the
 * header line that precedes a frame's bytes. */
#pragma once

#include <stddef.h>
#include <stdint.h>

/* Longest request or header line, newline included (the server's bound). */
#define SIMPROTO_LINE_MAX 4096

/* Largest frame accepted by a client, in bytes (a 16-bit RGB 8192x8192 image). */
#define SIMPROTO_FRAME_MAX ((size_t)8192 * 8192 * 6)

struct simproto_render {
        const char *camera; /* borrowed */
        int exposure_us;    /* 0 = camera default */
        double gain;        /* 0 = camera default */
        int bits;           /* 0 = camera default, else 8 or 16 */
};

/* The header of a rendered frame. */
struct simproto_header {
        int width, height, channels, bits;
        size_t stride;      /* bytes per row of the pixels that follow */
        size_t bytes;       /* pixel bytes that follow the header (stride * height) */
        size_t extra_bytes; /* ground-truth bytes that follow the pixels */
        uint64_t seq, timestamp_ns;
        int exposure_us;
        double gain;
};

/* Writes the request line (with its newline, NUL-terminated) into buf. Returns its length,
 * -EINVAL without a camera name, -ENOBUFS when it does not fit, -ENOMEM. */
int simproto_encode_render(const struct simproto_render *rq, char *buf, size_t len);

/* Decodes a reply header line of len bytes (newline optional). Returns 0 for a frame
 * header; for an error reply, the negative errno it names (-EIO when unknown) with its
 * message copied into msg; -EBADMSG for a malformed or inconsistent header. */
int simproto_decode_header(const char *line, size_t len, struct simproto_header *h, char *msg,
                           size_t msglen);

/* The negative errno for an error name such as "ETIMEDOUT" (-EIO when unknown). */
int simproto_errno(const char *name);
