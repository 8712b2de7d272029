/* board.c - calibration board patterns: chessboard and ChArUco (DICT_4X4_50 markers,
 * the layout of OpenCV 4.6's CharucoBoard), evaluated procedurally in the board frame and
 * box-filtered exactly over the pixel footprint (the parallelogram the pixel covers on the board,
 * clipped against every black square and marker cell), so edges are anti-aliased without bias. The
 * marker table was generated with OpenCV (Dictionary::getBitsFromByteList) and is checked against
 * OpenCV's detector in tests/render/test-render-cv.cpp. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "internal.h"

/* DICT_4X4_50: 4x4 bits per marker, row-major from the top-left, MSB first, 1 = white. */
static const uint16_t dict_4x4_50[50] = {
        0xb532, 0x0f9a, 0x332d, 0x9946, 0x549e, 0x79cd, 0x9e2e, 0xc4f2, 0xfeda, 0xcf56,
        0xf991, 0x11a7, 0x0eb7, 0x2a0f, 0x24b1, 0x263e, 0x4665, 0x6600, 0x6c5e, 0x76af,
        0x868b, 0xb02b, 0xccd5, 0xdd82, 0xfe47, 0x9471, 0xace4, 0xa554, 0x2123, 0x346f,
        0x4415, 0x57b2, 0x9ecf, 0xf0cb, 0x08ae, 0x0929, 0x1875, 0x04ff, 0x0df6, 0x1c5a,
        0x1718, 0x2a28, 0x328c, 0x38b2, 0x24e8, 0x2eeb, 0x2d3f, 0x4b64, 0x502e, 0x5013,
};

int board_marker_bits(int id, uint16_t *bits)
{
        if (id < 0 || id >= (int)(sizeof(dict_4x4_50) / sizeof(dict_4x4_50[0])))
                return -EINVAL;
        *bits = dict_4x4_50[id];
        return 0;
}

/* Marker id in white square (i, j): ids run row by row from the top row (j = 0). */
static int marker_id(const struct board *b, int i, int j)
{
        int id = b->first_id;

        for (int r = 0; r < j; r++)
                id += r % 2 ? (b->nx + 1) / 2 : b->nx / 2;
        return id + (j % 2 ? (i + 1) / 2 : i / 2);
}

/* Marker of white square (i, j): origin (x0, y0) of its top-left corner and its bits. */
static bool marker_at(const struct board *b, int i, int j, float *x0, float *y0, uint16_t *bits)
{
        *x0 = i * b->square + (b->square - b->marker) / 2;
        *y0 = j * b->square + (b->square - b->marker) / 2;
        return board_marker_bits(marker_id(b, i, j), bits) == 0;
}

/* Is cell (r, c) of a 6x6 marker (1-cell black border around 4x4 bits) white? */
static bool cell_white(uint16_t bits, int r, int c)
{
        if (r <= 0 || r >= 5 || c <= 0 || c >= 5)
                return false;
        return (bits >> (15 - ((r - 1) * 4 + (c - 1)))) & 1;
}

static bool marker_white(const struct board *b, int i, int j, float x, float y)
{
        float x0, y0, cell = b->marker / 6;
        uint16_t bits;

        if (!marker_at(b, i, j, &x0, &y0, &bits) || x < x0 || x >= x0 + b->marker || y < y0 ||
            y >= y0 + b->marker)
                return true;
        return cell_white(bits, (int)((y - y0) / cell), (int)((x - x0) / cell));
}

static bool board_white(const struct board *b, float x, float y)
{
        int i, j;

        if (x < 0 || y < 0 || x >= b->nx * b->square || y >= b->ny * b->square)
                return true; /* margin */
        i = (int)(x / b->square);
        j = (int)(y / b->square);
        if ((i + j) % 2 == 0)
                return false;
        return b->kind == BOARD_CHESS || marker_white(b, i, j, x, y);
}

/* Area of the convex polygon p (n vertices, x y pairs) clipped to [x0,x1] x [y0,y1]. */
static float clip_area(const float *p, int n, float x0, float y0, float x1, float y1)
{
        float a[2][2 * 12], area = 0;
        const float lim[4] = {x0, y0, x1, y1};
        int cur = 0;

        memcpy(a[0], p, 2 * n * sizeof(float));
        for (int e = 0; e < 4 && n > 0; e++) { /* Sutherland-Hodgman, one edge at a time */
                int ax = e & 1, m = 0;
                float sgn = e < 2 ? 1 : -1, *in = a[cur], *out = a[!cur];
                for (int k = 0; k < n; k++) {
                        const float *s = in + 2 * k, *t = in + 2 * ((k + 1) % n);
                        float ds = sgn * (s[ax] - lim[e]), dt = sgn * (t[ax] - lim[e]);
                        if (ds >= 0) {
                                out[2 * m] = s[0];
                                out[2 * m++ + 1] = s[1];
                        }
                        if ((ds >= 0) != (dt >= 0)) {
                                float f = ds / (ds - dt);
                                out[2 * m] = s[0] + f * (t[0] - s[0]);
                                out[2 * m++ + 1] = s[1] + f * (t[1] - s[1]);
                        }
                }
                n = m;
                cur = !cur;
        }
        for (int k = 0; k < n; k++) {
                const float *s = a[cur] + 2 * k, *t = a[cur] + 2 * ((k + 1) % n);
                area += s[0] * t[1] - t[0] * s[1];
        }
        return fabsf(area) / 2;
}

/* Black area of the marker in white square (i, j) inside polygon q (bounding box bb). */
static float marker_black_area(const struct board *b, int i, int j, const float *q,
                               const float bb[4])
{
        float x0, y0, cell = b->marker / 6, area = 0;
        uint16_t bits;

        if (!marker_at(b, i, j, &x0, &y0, &bits))
                return 0;
        for (int r = 0; r < 6; r++)
                for (int c = 0; c < 6; c++) {
                        float cx = x0 + c * cell, cy = y0 + r * cell;
                        if (cell_white(bits, r, c) || cx > bb[2] || cx + cell < bb[0] ||
                            cy > bb[3] || cy + cell < bb[1])
                                continue;
                        area += clip_area(q, 4, cx, cy, cx + cell, cy + cell);
                }
        return area;
}

float board_albedo(const struct board *b, float x, float y, const float fp[4])
{
        float q[8], bb[4] = {x, y, x, y}, total, black = 0, sq = b->square;

        for (int k = 0; k < 4; k++) { /* the footprint parallelogram */
                float a = (k == 1 || k == 2) ? 0.5f : -0.5f, c = k >= 2 ? 0.5f : -0.5f;
                q[2 * k] = x + a * fp[0] + c * fp[2];
                q[2 * k + 1] = y + a * fp[1] + c * fp[3];
                bb[0] = fminf(bb[0], q[2 * k]);
                bb[1] = fminf(bb[1], q[2 * k + 1]);
                bb[2] = fmaxf(bb[2], q[2 * k]);
                bb[3] = fmaxf(bb[3], q[2 * k + 1]);
        }
        total = fabsf(fp[0] * fp[3] - fp[1] * fp[2]);
        if (total < 1e-12f || (bb[2] - bb[0]) > 4 * sq || (bb[3] - bb[1]) > 4 * sq)
                return board_white(b, x, y) ? b->white : b->black; /* point sample */
        int i0 = MAX((int)floorf(bb[0] / sq), 0), i1 = MIN((int)floorf(bb[2] / sq), b->nx - 1);
        int j0 = MAX((int)floorf(bb[1] / sq), 0), j1 = MIN((int)floorf(bb[3] / sq), b->ny - 1);
        for (int j = j0; j <= j1; j++)
                for (int i = i0; i <= i1; i++)
                        if ((i + j) % 2 == 0)
                                black +=
                                        clip_area(q, 4, i * sq, j * sq, (i + 1) * sq, (j + 1) * sq);
                        else if (b->kind == BOARD_CHARUCO)
                                black += marker_black_area(b, i, j, q, bb);
        return b->black + (b->white - b->black) * (1 - fminf(black / total, 1));
}
