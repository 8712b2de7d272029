/* proto.c - encode/decode of gonio-sim's frame-socket messages (see proto.h, docs/sim.md). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "common/cleanup.h"
#include "drivers/camera/sim/proto.h"

int simproto_encode_render(const struct simproto_render *rq, char *buf, size_t len)
{
        if (!rq->camera || !rq->camera[0])
                return -EINVAL;

        json_auto_t *o = json_pack("{s:s, s:s}", "cmd", "render", "camera", rq->camera);
        if (!o)
                return -ENOMEM;
        if ((rq->exposure_us &&
             json_object_set_new(o, "exposure_us", json_integer(rq->exposure_us)) < 0) ||
            (rq->gain > 0.0 && json_object_set_new(o, "gain", json_real(rq->gain)) < 0) ||
            (rq->bits && json_object_set_new(o, "bits", json_integer(rq->bits)) < 0))
                return -ENOMEM;
        size_t n = json_dumpb(o, buf, len, JSON_COMPACT);
        if (n == 0)
                return -ENOMEM;
        if (n + 2 > len || n + 2 > SIMPROTO_LINE_MAX)
                return -ENOBUFS;
        buf[n] = '\n';
        buf[n + 1] = '\0';
        return (int)n + 1;
}

int simproto_errno(const char *name)
{
        static const struct {
                const char *name;
                int err;
        } table[] = {
                {"EINVAL", EINVAL},     {"ENOENT", ENOENT},   {"ETIMEDOUT", ETIMEDOUT},
                {"ENOMEM", ENOMEM},     {"EIO", EIO},         {"EPROTO", EPROTO},
                {"EMSGSIZE", EMSGSIZE}, {"ENOTSUP", ENOTSUP}, {"EOPNOTSUPP", EOPNOTSUPP},
                {"EBADMSG", EBADMSG},   {"ERANGE", ERANGE},   {"EAGAIN", EAGAIN},
        };

        for (size_t i = 0; name && i < ELEMENTSOF(table); i++)
                if (strcmp(name, table[i].name) == 0)
                        return -table[i].err;
        return -EIO;
}

/* Sums the "bytes" of the ground-truth arrays listed in the header. */
static int truth_bytes(json_t *truth, size_t *out)
{
        size_t i;
        json_t *t;

        *out = 0;
        if (!truth)
                return 0;
        if (!json_is_array(truth))
                return -EBADMSG;
        json_array_foreach(truth, i, t)
        {
                json_int_t n = json_integer_value(json_object_get(t, "bytes"));
                if (n <= 0 || (size_t)n > SIMPROTO_FRAME_MAX)
                        return -EBADMSG;
                *out += (size_t)n;
        }
        return 0;
}

static int check_header(const struct simproto_header *h)
{
        if (h->width <= 0 || h->height <= 0 || h->width > 65535 || h->height > 65535 ||
            (h->channels != 1 && h->channels != 3) || (h->bits != 8 && h->bits != 16))
                return -EBADMSG;
        size_t row = (size_t)h->width * (size_t)h->channels * (size_t)(h->bits / 8);
        if (h->stride < row || h->bytes != h->stride * (size_t)h->height ||
            h->bytes > SIMPROTO_FRAME_MAX)
                return -EBADMSG;
        return 0;
}

static int decode_error(json_t *o, char *msg, size_t msglen)
{
        const char *m = json_string_value(json_object_get(o, "message"));

        snprintf(msg, msglen, "%s", m ? m : "error without message");
        return simproto_errno(json_string_value(json_object_get(o, "error")));
}

int simproto_decode_header(const char *line, size_t len, struct simproto_header *h, char *msg,
                           size_t msglen)
{
        json_error_t jerr;
        json_int_t w, ht, ch, bits, stride, bytes, seq = 0, ts = 0, exp = 0;
        int ok;

        json_auto_t *o = json_loadb(line, len, 0, &jerr);
        if (!o || json_unpack(o, "{s:b}", "ok", &ok) < 0)
                return -EBADMSG;
        if (!ok)
                return decode_error(o, msg, msglen);

        *h = (struct simproto_header){0};
        if (json_unpack(o, "{s:I, s:I, s:I, s:I, s:I, s:I, s?I, s?I, s?I, s?F}", "width", &w,
                        "height", &ht, "channels", &ch, "bits", &bits, "stride", &stride, "bytes",
                        &bytes, "seq", &seq, "timestamp_ns", &ts, "exposure_us", &exp, "gain",
                        &h->gain) < 0 ||
            w < 0 || ht < 0 || ch < 0 || bits < 0 || stride < 0 || bytes < 0 || seq < 0 || ts < 0 ||
            exp < 0 || w > 65535 || ht > 65535 || ch > 3 || bits > 16 || exp > 1000000000)
                return -EBADMSG;
        *h = (struct simproto_header){
                .width = (int)w,
                .height = (int)ht,
                .channels = (int)ch,
                .bits = (int)bits,
                .stride = (size_t)stride,
                .bytes = (size_t)bytes,
                .seq = (uint64_t)seq,
                .timestamp_ns = (uint64_t)ts,
                .exposure_us = (int)exp,
                .gain = h->gain,
        };
        if (truth_bytes(json_object_get(o, "truth"), &h->extra_bytes) < 0)
                return -EBADMSG;
        return check_header(h);
}
