/* ply.c - the point cloud and the mesh as binary PLY files (see ply.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "ply.h"

#define PLY_VERTEX_BYTES (6 * 4 + 3)
#define PLY_FACE_BYTES   (1 + 3 * 4)

static const char vertex_fmt[] = "ply\n"
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
                                 "property uchar blue\n";
static const char face_fmt[] = "element face %zu\n"
                               "property list uchar int vertex_indices\n";
static const char end_header[] = "end_header\n";

/* Stores the 32 bits of u little-endian at b. */
static uint8_t *put_u32(uint8_t *b, uint32_t u)
{
        for (int i = 0; i < 4; i++)
                b[i] = (uint8_t)(u >> (8 * i));
        return b + 4;
}

static uint8_t *put_f32(uint8_t *b, float f)
{
        uint32_t u;

        memcpy(&u, &f, 4);
        return put_u32(b, u);
}

/* Writes a PLY of the n vertices p and the nf faces f (3 indices each; f NULL: none, a
 * point cloud without a face element). */
static int write_ply(int dir_fd, const char *name, const struct sec_point *p, size_t n,
                     const uint32_t *f, size_t nf)
{
        char head[sizeof(vertex_fmt) + sizeof(face_fmt) + sizeof(end_header) + 64];
        int hl = snprintf(head, sizeof(head), vertex_fmt, n);
        size_t len;
        _cleanup_free_ uint8_t *buf = NULL;
        uint8_t *b;

        if (f)
                hl += snprintf(head + hl, sizeof(head) - (size_t)hl, face_fmt, nf);
        hl += snprintf(head + hl, sizeof(head) - (size_t)hl, "%s", end_header);
        len = (size_t)hl + n * PLY_VERTEX_BYTES + (f ? nf * PLY_FACE_BYTES : 0);
        if (!(buf = malloc(len)))
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
        for (size_t i = 0; f && i < nf; i++) {
                *b++ = 3;
                for (int k = 0; k < 3; k++)
                        b = put_u32(b, f[3 * i + k]);
        }
        return gn_write_atomic(dir_fd, name, buf, len, NULL);
}

int ply_write_points(int dir_fd, const char *name, const struct sec_point *p, size_t n)
{
        return write_ply(dir_fd, name, p, n, NULL, 0);
}

int ply_write_mesh(int dir_fd, const char *name, const struct cal_mesh *m)
{
        /* a face element even when empty, so that readers see a mesh */
        static const uint32_t none[3];

        return write_ply(dir_fd, name, m->v, m->n_v, m->n_tri ? m->tri : none, m->n_tri);
}
