/* export_rti.c - the RTI export (export.h, docs/exports.md "RTI"): per view of the dataset
 * (camera, turntable and camera-arm angle, placed as the fit places them: ap_geometry_read) a
 * folder <camera>[_tt<deg>][_ca<deg>] with its single-lamp images (images/NNN.png, copied as
 * stored), an .lp light file (the format of ds_write_lp: the number of images, then
 * "path dx dy dz" per image), a PTM 1.2 file in PTM_FORMAT_LRGB and a relight web-format
 * folder (info.json, type "ptm", colorspace "rgb", six PNG coefficient planes, as OpenLIME's
 * LayerRTI and ShaderRTI read them). Light directions are unit vectors in the RTI image frame
 * of the view: x right, y up in the image, z towards the camera. The PTM and relight
 * coefficients are one least-squares fit of the biquadratic PTM basis per pixel over the
 * view's images. */
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "appearance/export.h"
#include "appearance/fit_internal.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "dataset/ds_png.h"

#define RTI_NB    6 /* PTM basis functions */
#define PNG_MAX   (256u << 20)
#define PATH_SIZE 4400

struct rti_ctx {
        const char *ds_dir, *dir;
        const struct ap_geometry *g;
        char *err;
        size_t errlen;
};

/* One view of the geometry: its camera and its shots of bracket 0 (one per light). */
struct rti_src {
        const struct ap_camera *cam;
        const struct ap_shot **shots;
        size_t n;
};

/* One view's images: n x W x H x 3 floats (full scale 1), the light directions (RTI frame). */
struct rti_view {
        char name[256];
        int W, H;
        size_t n;
        float *img;
        double (*l)[3];
};

/* Puts the sentence fmt in c->err. Returns r. */
__attribute__((format(printf, 3, 4))) static int fail(struct rti_ctx *c, int r, const char *fmt,
                                                      ...)
{
        va_list ap;

        if (c->err) {
                va_start(ap, fmt);
                vsnprintf(c->err, c->errlen, fmt, ap);
                va_end(ap);
        }
        return r;
}

/* Writes len bytes of buf as the new file path. */
static int put(const char *path, const void *buf, size_t len)
{
        int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644), r;

        if (fd < 0)
                return -errno;
        r = gn_write_all(fd, buf, len, NULL);
        if (close(fd) < 0 && r == 0)
                r = -errno;
        return r;
}

/* "<camera>[_tt<deg>][_ca<deg>]" of view v. */
static void view_name(const struct rti_ctx *c, const struct rti_src *v, char *out, size_t len)
{
        const struct gn_pose *p = &v->shots[0]->row->pose;
        int n = snprintf(out, len, "%s", c->g->rc->cameras[v->shots[0]->cam].name);
        double tt = p->deg[GN_ROLE_TURNTABLE], ca = p->deg[GN_ROLE_CAMERA_ARM];

        if (!isnan(tt))
                n += snprintf(out + n, len - n, "_tt%g", round(tt * 100) / 100);
        if (!isnan(ca))
                snprintf(out + n, len - n, "_ca%g", round(ca * 100) / 100);
}

/* Copies image j of v into the view's images/ and decodes it into rv. */
static int take_image(struct rti_ctx *c, const struct rti_src *v, size_t j, struct rti_view *rv)
{
        _cleanup_free_ void *buf = NULL;
        char path[PATH_SIZE];
        struct gn_frame f = {0};
        size_t len;
        int r;

        snprintf(path, sizeof(path), "%s/%s", c->ds_dir, v->shots[j]->row->file);
        r = gn_read_file_at(AT_FDCWD, path, PNG_MAX, &buf, &len);
        if (r == 0)
                r = ds_png_decode(buf, len, &f);
        if (r < 0)
                return fail(c, r, "%s: %s", path, strerror(-r));
        if (j == 0) {
                rv->W = f.width;
                rv->H = f.height;
                rv->img = malloc(v->n * (size_t)f.width * f.height * 3 * sizeof(float));
        }
        if (f.width != rv->W || f.height != rv->H || !rv->img) {
                gn_frame_free_data(&f);
                return fail(c, rv->img ? -EBADMSG : -ENOMEM, "%s: %s", path,
                            rv->img ? "not the size of the view's first image" : "no memory");
        }
        float *out = rv->img + j * (size_t)rv->W * rv->H * 3;
        for (int y = 0; y < f.height; y++)
                for (int x = 0; x < f.width; x++)
                        for (int ch = 0; ch < 3; ch++) {
                                const uint8_t *row = f.data + (size_t)y * f.stride;
                                size_t i = (size_t)x * f.channels + (f.channels == 3 ? ch : 0);
                                *out++ = f.bits == 8 ? row[i] / 255.0f
                                                     : ((const uint16_t *)row)[i] / 65535.0f;
                        }
        gn_frame_free_data(&f);
        snprintf(path, sizeof(path), "%s/%s/images/%03zu.png", c->dir, rv->name, j);
        r = put(path, buf, len);
        return r < 0 ? fail(c, r, "%s: %s", path, strerror(-r)) : 0;
}

/* The .lp file of the view: its images and their light directions. */
static int write_lp(struct rti_ctx *c, const struct rti_view *rv)
{
        _cleanup_free_ char *text = NULL;
        char path[PATH_SIZE];
        size_t len;
        FILE *f = open_memstream(&text, &len);
        int r;

        if (!f)
                return -ENOMEM;
        fprintf(f, "%zu\n", rv->n);
        for (size_t j = 0; j < rv->n; j++)
                fprintf(f, "images/%03zu.png %.6f %.6f %.6f\n", j, rv->l[j][0], rv->l[j][1],
                        rv->l[j][2]);
        if (fclose(f) != 0)
                return -ENOMEM;
        snprintf(path, sizeof(path), "%s/%s/%s.lp", c->dir, rv->name, rv->name);
        r = put(path, text, len);
        return r < 0 ? fail(c, r, "%s: %s", path, strerror(-r)) : 0;
}

/* The fitted coefficients of a view: per pixel 6 per channel (a[p][ch][k]), 6 of luminance
 * and the pixel's chromaticity (PTM LRGB). */
struct rti_fit {
        float *a;   /* W x H x 3 x 6 */
        float *lum; /* W x H x 6 */
        float *rgb; /* W x H x 3, max 1 */
};

static void fit_free(struct rti_fit *f)
{
        free(f->a);
        free(f->lum);
        free(f->rgb);
}

/* The luminance of pixel p's fit: the colour channels projected on its chromaticity. */
static void fit_luminance(const struct rti_view *rv, struct rti_fit *f, size_t p)
{
        size_t N = (size_t)rv->W * rv->H;
        double m[3] = {0}, mx = 0, nn = 0;

        for (size_t j = 0; j < rv->n; j++)
                for (int ch = 0; ch < 3; ch++)
                        m[ch] += rv->img[(j * N + p) * 3 + ch];
        for (int ch = 0; ch < 3; ch++)
                mx = fmax(mx, m[ch]);
        for (int ch = 0; ch < 3; ch++) {
                f->rgb[3 * p + ch] = mx > 0 ? (float)(m[ch] / mx) : 0;
                nn += f->rgb[3 * p + ch] * f->rgb[3 * p + ch];
        }
        for (int k = 0; k < RTI_NB; k++) {
                double s = 0;
                for (int ch = 0; ch < 3; ch++)
                        s += f->rgb[3 * p + ch] * f->a[(p * 3 + ch) * RTI_NB + k];
                f->lum[p * RTI_NB + k] = nn > 0 ? (float)(s / nn) : 0;
        }
}

/* The per-pixel least-squares fit of the PTM basis to the view's images. */
static int fit_view_ptm(struct rti_ctx *c, const struct rti_view *rv, struct rti_fit *f)
{
        size_t N = (size_t)rv->W * rv->H, L = rv->n;
        _cleanup_free_ double *A = malloc(L * RTI_NB * sizeof(double));
        _cleanup_free_ float *pinv = malloc(L * RTI_NB * sizeof(float));
        int r;

        f->a = malloc(N * 3 * RTI_NB * sizeof(float));
        f->lum = malloc(N * RTI_NB * sizeof(float));
        f->rgb = malloc(N * 3 * sizeof(float));
        if (!A || !pinv || !f->a || !f->lum || !f->rgb)
                return -ENOMEM;
        for (size_t j = 0; j < L; j++) {
                double u = rv->l[j][0], v = rv->l[j][1];
                double row[RTI_NB] = {u * u, v * v, u * v, u, v, 1};
                memcpy(A + j * RTI_NB, row, sizeof(row));
        }
        r = ap_fit_pinv(A, (int)L, RTI_NB, AP_REG_TSVD, 1e-6, pinv, NULL);
        if (r < 0)
                return fail(c, r, "%s: the PTM fit failed", rv->name);
        for (size_t p = 0; p < N; p++) {
                for (int ch = 0; ch < 3; ch++)
                        for (int k = 0; k < RTI_NB; k++) {
                                double s = 0;
                                for (size_t j = 0; j < L; j++)
                                        s += pinv[k * L + j] * rv->img[(j * N + p) * 3 + ch];
                                f->a[(p * 3 + ch) * RTI_NB + k] = (float)s;
                        }
                fit_luminance(rv, f, p);
        }
        return 0;
}

/* The range of values x[i * stride] (n of them) as scale (> 0) and offset lo. */
static void range_of(const float *x, size_t n, size_t stride, double *lo, double *scale)
{
        double a = INFINITY, b = -INFINITY;

        for (size_t i = 0; i < n; i++) {
                a = fmin(a, x[i * stride]);
                b = fmax(b, x[i * stride]);
        }
        *lo = a;
        *scale = b > a ? b - a : 1;
}

static uint8_t byte_of(double v)
{
        return (uint8_t)fmin(255, fmax(0, round(v)));
}

/* The PTM file: header, then per pixel (rows bottom to top) 6 coefficient bytes, then per
 * pixel (same order) 3 colour bytes. A coefficient is (byte - bias) x scale. */
static int write_ptm(struct rti_ctx *c, const struct rti_view *rv, const struct rti_fit *f)
{
        size_t N = (size_t)rv->W * rv->H, len;
        double lo[RTI_NB], scale[RTI_NB];
        int bias[RTI_NB];
        _cleanup_free_ char *text = NULL;
        char path[PATH_SIZE];
        FILE *out = open_memstream(&text, &len);
        int r;

        if (!out)
                return -ENOMEM;
        fprintf(out, "PTM_1.2\nPTM_FORMAT_LRGB\n%d\n%d\n", rv->W, rv->H);
        for (int k = 0; k < RTI_NB; k++) {
                range_of(f->lum + k, N, RTI_NB, &lo[k], &scale[k]);
                scale[k] /= 255;
                bias[k] = (int)lround(-lo[k] / scale[k]);
                fprintf(out, "%.9g%c", scale[k], k < RTI_NB - 1 ? ' ' : '\n');
        }
        for (int k = 0; k < RTI_NB; k++)
                fprintf(out, "%d%c", bias[k], k < RTI_NB - 1 ? ' ' : '\n');
        for (int y = rv->H - 1; y >= 0; y--)
                for (int x = 0; x < rv->W; x++)
                        for (int k = 0; k < RTI_NB; k++)
                                fputc(byte_of(f->lum[((size_t)y * rv->W + x) * RTI_NB + k] /
                                                      scale[k] +
                                              bias[k]),
                                      out);
        for (int y = rv->H - 1; y >= 0; y--)
                for (int x = 0; x < rv->W; x++)
                        for (int ch = 0; ch < 3; ch++)
                                fputc(byte_of(f->rgb[((size_t)y * rv->W + x) * 3 + ch] * 255), out);
        if (fclose(out) != 0)
                return -ENOMEM;
        snprintf(path, sizeof(path), "%s/%s/%s.ptm", c->dir, rv->name, rv->name);
        r = put(path, text, len);
        return r < 0 ? fail(c, r, "%s: %s", path, strerror(-r)) : 0;
}

/* Plane j of the relight folder: the coefficient of relight's PTM basis function j (1, lu,
 * lv, lu^2, lu lv, lv^2: OpenLIME's ShaderRTI) for R, G, B as (value - bias) x scale with
 * value the byte / 255; scale and bias (3 each) appended to the arrays. */
static int write_plane(struct rti_ctx *c, const struct rti_view *rv, const struct rti_fit *f, int j,
                       json_t *scales, json_t *biases)
{
        static const int ptm_index[RTI_NB] = {5, 3, 4, 0, 2, 1};
        int k = ptm_index[j];
        size_t N = (size_t)rv->W * rv->H, len;
        struct gn_frame fr = {.width = rv->W, .height = rv->H, .channels = 3, .bits = 8};
        _cleanup_free_ void *png = NULL;
        char path[PATH_SIZE];
        int r = gn_frame_alloc(&fr, rv->W, rv->H, 3, 8);

        for (int ch = 0; r == 0 && ch < 3; ch++) {
                double lo, scale;
                range_of(f->a + ch * RTI_NB + k, N, 3 * RTI_NB, &lo, &scale);
                json_array_append_new(scales, json_real(scale));
                json_array_append_new(biases, json_real(-lo / scale));
                for (size_t p = 0; p < N; p++)
                        fr.data[(p / rv->W) * fr.stride + (p % rv->W) * 3 + ch] =
                                byte_of((f->a[(p * 3 + ch) * RTI_NB + k] - lo) / scale * 255);
        }
        if (r == 0)
                r = ds_png_encode(&fr, 6, &png, &len);
        gn_frame_free_data(&fr);
        snprintf(path, sizeof(path), "%s/%s/relight/plane_%d.png", c->dir, rv->name, j);
        if (r == 0)
                r = put(path, png, len);
        return r < 0 ? fail(c, r, "%s: %s", path, strerror(-r)) : 0;
}

/* The relight web-format folder: info.json and the six planes. */
static int write_relight(struct rti_ctx *c, const struct rti_view *rv, const struct rti_fit *f)
{
        json_t *scales = json_array(), *biases = json_array();
        _cleanup_free_ char *text = NULL;
        char path[PATH_SIZE];
        int r = 0;

        snprintf(path, sizeof(path), "%s/%s/relight", c->dir, rv->name);
        if (mkdir(path, 0755) < 0)
                r = fail(c, -errno, "%s: %s", path, strerror(errno));
        for (int k = 0; r == 0 && k < RTI_NB; k++)
                r = write_plane(c, rv, f, k, scales, biases);
        json_t *info =
                json_pack("{s:i, s:i, s:s, s:s, s:s, s:i, s:[{s:o, s:o}]}", "width", rv->W,
                          "height", rv->H, "format", "png", "type", "ptm", "colorspace", "rgb",
                          "nplanes", 3 * RTI_NB, "materials", "scale", scales, "bias", biases);
        text = info ? json_dumps(info, JSON_INDENT(1)) : NULL;
        json_decref(info);
        if (r == 0 && !text)
                r = -ENOMEM;
        snprintf(path, sizeof(path), "%s/%s/relight/info.json", c->dir, rv->name);
        if (r == 0 && (r = put(path, text, strlen(text))) < 0)
                r = fail(c, r, "%s: %s", path, strerror(-r));
        return r;
}

/* The direction of shot s's lamp from the object's centre c0 in the RTI frame of camera g. */
static void light_dir(const struct ap_camera *g, const double c0[3], const struct ap_shot *s,
                      double l[3])
{
        double d[3] = {s->lamp[0] - c0[0], s->lamp[1] - c0[1], s->lamp[2] - c0[2]};
        double n = hypot(hypot(d[0], d[1]), d[2]);

        for (int i = 0; i < 3; i++) { /* the camera frame: x right, y down, z ahead */
                double x =
                        (g->R[3 * i] * d[0] + g->R[3 * i + 1] * d[1] + g->R[3 * i + 2] * d[2]) / n;
                l[i] = i == 0 ? x : -x;
        }
}

/* The view's folder, images and light directions. */
static int read_view(struct rti_ctx *c, const struct rti_src *v, struct rti_view *rv)
{
        char path[PATH_SIZE];
        double c0[3];
        int r = 0;

        rv->n = v->n;
        rv->l = calloc(v->n, sizeof(*rv->l));
        if (!rv->l)
                return -ENOMEM;
        fit_camera_centre(v->cam, c0);
        for (size_t j = 0; j < v->n; j++)
                light_dir(v->cam, c0, v->shots[j], rv->l[j]);
        snprintf(path, sizeof(path), "%s/%s", c->dir, rv->name);
        if (mkdir(path, 0755) < 0)
                return fail(c, -errno, "%s: %s", path, strerror(errno));
        snprintf(path, sizeof(path), "%s/%s/images", c->dir, rv->name);
        if (mkdir(path, 0755) < 0)
                return fail(c, -errno, "%s: %s", path, strerror(errno));
        for (size_t j = 0; r == 0 && j < v->n; j++)
                r = take_image(c, v, j, rv);
        return r;
}

/* Writes view v: its folder, images, .lp, PTM and relight folder. */
static int export_view(struct rti_ctx *c, const struct rti_src *v)
{
        struct rti_view rv = {0};
        struct rti_fit f = {0};
        int r;

        view_name(c, v, rv.name, sizeof(rv.name));
        if (v->n < RTI_NB)
                return fail(c, -ENODATA,
                            "view %s has %zu lights on the camera's side with one lamp lit: "
                            "a PTM needs at least %d",
                            rv.name, v->n, RTI_NB);
        r = read_view(c, v, &rv);
        if (r == 0)
                r = write_lp(c, &rv);
        if (r == 0)
                r = fit_view_ptm(c, &rv, &f);
        if (r == 0)
                r = write_ptm(c, &rv, &f);
        if (r == 0)
                r = write_relight(c, &rv, &f);
        fit_free(&f);
        free(rv.img);
        free(rv.l);
        return r;
}

/* Every view of c's geometry (its shots are grouped by view), with its bracket-0 images of
 * lamps on the camera's side of the object (z > 0 in the RTI frame): the PTM basis depends
 * on (x, y) only, which cannot tell a lamp behind the object from its mirror in front. A view
 * lit only from behind is left out. */
static int export_views(struct rti_ctx *c)
{
        const struct ap_geometry *g = c->g;
        _cleanup_free_ const struct ap_shot **shots = malloc((g->n_shots + 1) * sizeof(*shots));
        int r = shots ? 0 : -ENOMEM;

        for (size_t i = 0, j; r == 0 && i < g->n_shots; i = j) {
                struct rti_src v = {.cam = &g->cameras[g->shots[i].view], .shots = shots};
                double c0[3], l[3];
                fit_camera_centre(v.cam, c0);
                for (j = i; j < g->n_shots && g->shots[j].view == g->shots[i].view; j++) {
                        light_dir(v.cam, c0, &g->shots[j], l);
                        if (g->shots[j].row->bracket == 0 && l[2] > 0)
                                shots[v.n++] = &g->shots[j];
                }
                if (v.n > 0)
                        r = export_view(c, &v);
        }
        return r;
}

int ap_export_rti(struct ds *d, const char *ds_dir, const char *dir, const struct ap_export_opts *o,
                  char *err, size_t errlen)
{
        struct rti_ctx c = {.ds_dir = ds_dir, .dir = dir, .err = err, .errlen = errlen};
        struct ap_geometry *g = NULL;
        int r;

        if (!d || !ds_dir || !dir)
                return -EINVAL;
        r = ap_geometry_read(d, o ? o->calibration : NULL, o ? o->backends : NULL, &g, err, errlen);
        if (r < 0)
                return r;
        c.g = g;
        r = export_views(&c);
        ap_geometry_free(g);
        return r;
}
