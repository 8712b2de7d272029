/* board.c - calibration board patterns: chessboard and ChArUco (DICT_4X4_50 markers,
 * OpenCV 4.6 layout), evaluated procedurally in the board frame and box-filtered over
 * the pixel footprint by 4x4 supersampling, so edges are anti-aliased without texture
 * maps. The marker table was generated with OpenCV (Dictionary::getBitsFromByteList)
 * and is checked against OpenCV's detector in tests/render/test-render-cv.cpp. */
#include <errno.h>
#include <math.h>

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

/* Marker id in white square (i, j): ids run row by row from the top row (j = ny - 1). */
static int marker_id(const struct board *b, int i, int j)
{
        int id = b->first_id;

        for (int r = j + 1; r < b->ny; r++)
                id += r % 2 ? (b->nx + 1) / 2 : b->nx / 2;
        return id + (j % 2 ? (i + 1) / 2 : i / 2);
}

static bool marker_white(const struct board *b, int i, int j, float x, float y)
{
        float x0 = i * b->square + (b->square - b->marker) / 2;
        float y1 = j * b->square + (b->square + b->marker) / 2; /* marker top edge */
        float cell = b->marker / 6;
        int c, r;
        uint16_t bits;

        if (x < x0 || x >= x0 + b->marker || y > y1 || y <= y1 - b->marker)
                return true;
        if (board_marker_bits(marker_id(b, i, j), &bits) < 0)
                return true;
        c = (int)((x - x0) / cell);
        r = (int)((y1 - y) / cell);
        if (c <= 0 || c >= 5 || r <= 0 || r >= 5)
                return false;
        return (bits >> (15 - ((r - 1) * 4 + (c - 1)))) & 1;
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

float board_albedo(const struct board *b, float x, float y, const float fp[4])
{
        int white = 0;

        for (int k = 0; k < 16; k++) {
                float a = ((k & 3) + 0.5f) / 4 - 0.5f, c = ((k >> 2) + 0.5f) / 4 - 0.5f;
                white += board_white(b, x + a * fp[0] + c * fp[2], y + a * fp[1] + c * fp[3]);
        }
        return b->black + (b->white - b->black) * white / 16.0f;
}
