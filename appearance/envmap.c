/* envmap.c - lat-long environment maps (envmap.h): PNG through the dataset's decoder, PFM
 * through common/pfm.h, and the projection
 * onto the SH basis by summing over pixels with each row's exact solid angle. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "appearance/envmap.h"
#include "appearance/model.h"
#include "appearance/sh.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/pfm.h"
#include "dataset/ds_png.h"

#define ENVMAP_FILE_MAX ((size_t)1 << 31)

static int bad(char *err, size_t errlen, const char *path, const char *why, int r)
{
        snprintf(err, errlen, "%s: %s", path, why);
        return r;
}

static int alloc_rgb(struct ap_envmap *out, long w, long h)
{
        if (w < 1 || h < 1 || w > AP_ENVMAP_MAX_SIDE || h > AP_ENVMAP_MAX_SIDE)
                return -EBADMSG;
        out->width = (int)w;
        out->height = (int)h;
        out->rgb = malloc(3 * (size_t)w * (size_t)h * sizeof(float));
        return out->rgb ? 0 : -ENOMEM;
}

static int load_png(const uint8_t *buf, size_t len, struct ap_envmap *out)
{
        struct gn_frame f = {0};
        int r = ds_png_decode(buf, len, &f);
        float full;

        if (r < 0)
                return r;
        if ((r = alloc_rgb(out, f.width, f.height)) < 0) {
                gn_frame_free_data(&f);
                return r;
        }
        full = f.bits == 16 ? 65535.f : 255.f;
        for (int y = 0; y < f.height; y++) {
                const uint8_t *row = f.data + (size_t)y * f.stride;
                for (int x = 0; x < f.width; x++)
                        for (int c = 0; c < 3; c++) {
                                int s = (x * f.channels + (f.channels == 3 ? c : 0));
                                float v = f.bits == 16 ? ((const uint16_t *)row)[s] : row[s];
                                out->rgb[((size_t)y * f.width + x) * 3 + c] = v / full;
                        }
        }
        gn_frame_free_data(&f);
        return 0;
}

static int load_pfm(const uint8_t *buf, size_t len, struct ap_envmap *out)
{
        return gn_pfm_decode(buf, len, AP_ENVMAP_MAX_SIDE, &out->rgb, &out->width, &out->height);
}

/* A lat-long map holds light: its width twice its height, every texel finite and not
 * negative, one of them positive. Frees e when not. */
static int check_light(struct ap_envmap *e, const char *path, char *err, size_t errlen)
{
        size_t n = 3 * (size_t)e->width * e->height;
        float peak = 0;
        char why[160];

        for (size_t i = 0; i < n; i++)
                peak = isfinite(e->rgb[i]) && e->rgb[i] >= 0 && peak >= 0 ? fmaxf(peak, e->rgb[i])
                                                                          : -1;
        if (e->width == 2 * e->height && peak > 0)
                return 0;
        snprintf(why, sizeof(why), "%s",
                 e->width != 2 * e->height
                         ? "not a lat-long map (its width must be twice its height)"
                 : peak < 0 ? "a negative or non-finite texel (radiance is >= 0)"
                            : "no light: every texel is 0");
        if (e->width != 2 * e->height)
                snprintf(why + strlen(why), sizeof(why) - strlen(why), ": %dx%d", e->width,
                         e->height);
        ap_envmap_free(e);
        return bad(err, errlen, path, why, -EBADMSG);
}

int ap_envmap_load(const char *path, struct ap_envmap *out, char *err, size_t errlen)
{
        static const uint8_t png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
        _cleanup_free_ void *buf = NULL;
        size_t len = 0;
        int r;

        memset(out, 0, sizeof(*out));
        r = gn_read_file_at(AT_FDCWD, path, ENVMAP_FILE_MAX, &buf, &len);
        if (r < 0) {
                snprintf(err, errlen, "%s: cannot read: %s", path, strerror(-r));
                return r;
        }
        if (len >= 8 && !memcmp(buf, png_sig, 8))
                r = load_png(buf, len, out);
        else if (len >= 3 && !memcmp(buf, "PF", 2))
                r = load_pfm(buf, len, out);
        else if (len >= 3 && !memcmp(buf, "Pf", 2))
                r = load_pfm(buf, len, out);
        else
                return bad(err, errlen, path, "not a PNG or PFM image", -EBADMSG);
        if (r < 0) {
                ap_envmap_free(out);
                return bad(err, errlen, path,
                           r == -EOPNOTSUPP ? "PNG with alpha or a palette (use grey or RGB)"
                           : r == -ENOMEM   ? "out of memory"
                                            : "malformed or truncated image",
                           r);
        }
        out->ldr = buf && !memcmp(buf, png_sig, 8);
        return check_light(out, path, err, errlen);
}

void ap_envmap_free(struct ap_envmap *e)
{
        free(e->rgb);
        memset(e, 0, sizeof(*e));
}

void ap_envmap_dir(int width, int height, double x, double y, double d[3])
{
        double phi = 2 * M_PI * x / width, theta = M_PI * y / height;

        d[0] = sin(theta) * cos(phi);
        d[1] = sin(theta) * sin(phi);
        d[2] = cos(theta);
}

void ap_envmap_project(const struct ap_envmap *e, int order, double *coef)
{
        int m = ap_n_coef(order);
        double y[AP_ORDER_MAX * AP_ORDER_MAX], d[3];

        memset(coef, 0, 3 * (size_t)m * sizeof(double));
        for (int row = 0; row < e->height; row++) {
                double t0 = M_PI * row / e->height, t1 = M_PI * (row + 1) / e->height;
                double dw = (cos(t0) - cos(t1)) * 2 * M_PI / e->width;
                for (int x = 0; x < e->width; x++) {
                        const float *px = &e->rgb[((size_t)row * e->width + x) * 3];
                        ap_envmap_dir(e->width, e->height, x + 0.5, row + 0.5, d);
                        ap_sh_eval(order, d, y);
                        for (int i = 0; i < m; i++)
                                for (int c = 0; c < 3; c++)
                                        coef[i * 3 + c] += px[c] * y[i] * dw;
                }
        }
}

void ap_envmap_bilinear(const float *px, int width, int height, int channels, float x, float y,
                        float *out)
{
        float fx = floorf(x), fy = floorf(y), tx = x - fx, ty = y - fy;
        int x0 = ((int)fx % width + width) % width, x1 = (x0 + 1) % width;
        int y0 = CLAMP((int)fy, 0, height - 1), y1 = CLAMP((int)fy + 1, 0, height - 1);
        const float *a = px + (size_t)channels * ((size_t)y0 * width + x0);
        const float *b = px + (size_t)channels * ((size_t)y0 * width + x1);
        const float *c = px + (size_t)channels * ((size_t)y1 * width + x0);
        const float *d = px + (size_t)channels * ((size_t)y1 * width + x1);

        for (int q = 0; q < channels; q++)
                out[q] = (1 - ty) * ((1 - tx) * a[q] + tx * b[q]) +
                         ty * ((1 - tx) * c[q] + tx * d[q]);
}
