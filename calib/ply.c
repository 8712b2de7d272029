/* ply.c - the point cloud as a binary PLY file (see ply.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "ply.h"

#define PLY_VERTEX_BYTES (6 * 4 + 3)

static const char header_fmt[] = "ply\n"
                                 "format binary_little_endian 1.0\n"
                                 "comment gonio scan, object frame, mm\n"
                                 "element vertex %zu\n"
                                 "property float x\n"
                                 "property float y\n"
                                 "property float z\n"
                                 "property float nx\n"
                                 "property float ny\n"
                                 "property float nz\n"
                                 "property uchar red\n"
                                 "property uchar green\n"
                                 "property uchar blue\n"
                                 "end_header\n";

/* Stores a float little-endian at b. */
static uint8_t *put_f32(uint8_t *b, float f)
{
        uint32_t u;

        memcpy(&u, &f, 4);
        for (int i = 0; i < 4; i++)
                b[i] = (uint8_t)(u >> (8 * i));
        return b + 4;
}

int ply_write_points(int dir_fd, const char *name, const struct sec_point *p, size_t n)
{
        char head[sizeof(header_fmt) + 32];
        int hl = snprintf(head, sizeof(head), header_fmt, n);
        size_t len = (size_t)hl + n * PLY_VERTEX_BYTES;
        _cleanup_free_ uint8_t *buf = malloc(len);
        uint8_t *b;

        if (!buf)
                return -ENOMEM;
        memcpy(buf, head, (size_t)hl);
        b = buf + hl;
        for (size_t i = 0; i < n; i++) {
                for (int k = 0; k < 3; k++)
                        b = put_f32(b, p[i].x[k]);
                for (int k = 0; k < 3; k++)
                        b = put_f32(b, p[i].n[k]);
                memcpy(b, p[i].rgb, 3);
                b += 3;
        }
        return gn_write_atomic(dir_fd, name, buf, len, NULL);
}
