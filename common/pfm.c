/* pfm.c - the PFM reader (pfm.h): header by sscanf, samples byte-swapped as the sign of the
 * scale says, rows flipped to top first. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/pfm.h"

static float sample_at(const uint8_t *p, bool le)
{
        uint32_t u = le ? p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24
                        : (uint32_t)p[0] << 24 | p[1] << 16 | p[2] << 8 | p[3];
        float v;

        memcpy(&v, &u, 4);
        return isfinite(v) ? v : 0;
}

int gn_pfm_decode(const uint8_t *buf, size_t len, int max_side, float **rgb, int *w, int *h)
{
        long W, H;
        double scale;
        int n = 0, ch;
        float *out;

        if (len < 3 || buf[0] != 'P' || (buf[1] != 'F' && buf[1] != 'f'))
                return -EBADMSG;
        ch = buf[1] == 'F' ? 3 : 1;
        /* buf is not NUL-terminated in general: the header fits in its first 64 bytes */
        char head[65] = {0};
        memcpy(head, buf + 2, MIN(len - 2, sizeof(head) - 1));
        if (sscanf(head, "%ld %ld %lf%n", &W, &H, &scale, &n) != 3 || scale == 0 ||
            !isfinite(scale) || W < 1 || H < 1 || W > max_side || H > max_side)
                return -EBADMSG;
        n += 3; /* "PF" and the single whitespace after the scale */
        if (len < (size_t)n + (size_t)(W * H * ch) * 4)
                return -EBADMSG;
        out = malloc(3 * (size_t)W * (size_t)H * sizeof(float));
        if (!out)
                return -ENOMEM;
        for (long y = 0; y < H; y++)
                for (long x = 0; x < W; x++)
                        for (int c = 0; c < 3; c++)
                                out[(y * W + x) * 3 + c] = sample_at(
                                        buf + n +
                                                (((H - 1 - y) * W + x) * ch + (ch == 3 ? c : 0)) *
                                                        4,
                                        scale < 0);
        *rgb = out;
        *w = (int)W;
        *h = (int)H;
        return 0;
}

int gn_pfm_encode(const float *rgb, int w, int h, void **buf, size_t *len)
{
        char head[64];
        int n;
        size_t row = 3 * (size_t)w * sizeof(float);
        uint8_t *out;

        if (w < 1 || h < 1)
                return -EINVAL;
        n = snprintf(head, sizeof(head), "PF\n%d %d\n-1.0\n", w, h);
        out = malloc((size_t)n + row * h);
        if (!out)
                return -ENOMEM;
        memcpy(out, head, (size_t)n);
        for (int y = 0; y < h; y++)
                for (size_t i = 0; i < 3 * (size_t)w; i++) {
                        uint8_t *p = out + n + row * (h - 1 - y) + 4 * i;
                        uint32_t u;
                        memcpy(&u, &rgb[3 * (size_t)w * y + i], 4);
                        p[0] = (uint8_t)u, p[1] = (uint8_t)(u >> 8), p[2] = (uint8_t)(u >> 16),
                        p[3] = (uint8_t)(u >> 24);
                }
        *buf = out;
        *len = (size_t)n + row * h;
        return 0;
}
