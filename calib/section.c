/* section.c - light sectioning: ray-plane triangulation of the laser line (see section.h). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "section.h"

#define DEG         (M_PI / 180)
#define UNDIST_ITER 200
#define UNDIST_TOL  1e-6 /* px */
#define GRAZING     1e-3 /* |cos| between the ray and the plane's normal below which we skip */

static double dot3(const double a[3], const double b[3])
{
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Brown-Conrady distortion of normalised point (x, y) into pixels uv. */
static void distort(const struct cal_intrinsics *k, double x, double y, double uv[2])
{
        const double *d = k->dist;
        double r2 = x * x + y * y;
        double rad = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
        double xd = x * rad + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
        double yd = y * rad + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;

        uv[0] = k->fx * xd + k->cx;
        uv[1] = k->fy * yd + k->cy;
}

int sec_undistort(const struct cal_intrinsics *k, double u, double v, double xy[2])
{
        double xd = (u - k->cx) / k->fx, yd = (v - k->cy) / k->fy, x = xd, y = yd, uv[2];
        const double *d = k->dist;

        /* fixed point of x = (xd - tangential(x)) / radial(x), as cv::undistortPoints */
        for (int i = 0; i < UNDIST_ITER; i++) {
                double r2 = x * x + y * y;
                double rad = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
                double dx = 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
                double dy = d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
                double nx = (xd - dx) / rad, ny = (yd - dy) / rad;

                if (!(rad > 0))
                        return -EDOM;
                if (fabs(nx - x) < 1e-14 && fabs(ny - y) < 1e-14) {
                        x = nx;
                        y = ny;
                        break;
                }
                x = nx;
                y = ny;
        }
        distort(k, x, y, uv);
        if (!(hypot(uv[0] - u, uv[1] - v) < UNDIST_TOL))
                return -EDOM;
        xy[0] = x;
        xy[1] = y;
        return 0;
}

int sec_init(struct sec_ctx *c, const struct sec_camera *cam)
{
        const double *R = cam->R;

        memset(c, 0, sizeof(*c));
        if (!(cam->k.fx > 0 && cam->k.fy > 0) || cam->width <= 0 || cam->height <= 0 ||
            !(isfinite(cam->k.fx * cam->k.fy * cam->k.cx * cam->k.cy) &&
              isfinite(cam->t[0] + cam->t[1] + cam->t[2])))
                return -EINVAL;
        for (int i = 0; i < 3; i++) /* a rotation (NAN fails every comparison) */
                for (int j = 0; j < 3; j++)
                        if (!(fabs(dot3(R + 3 * i, R + 3 * j) - (i == j)) <= 1e-6))
                                return -EINVAL;
        c->cam = *cam;
        for (int i = 0; i < 3; i++) /* C = -R^T t */
                c->eye[i] = -(R[i] * cam->t[0] + R[3 + i] * cam->t[1] + R[6 + i] * cam->t[2]);
        return 0;
}

void sec_free(struct sec_ctx *c)
{
        free(c->pts);
        free(c->lines);
        memset(c, 0, sizeof(*c));
}

int sec_add_laser(struct sec_ctx *c, const double p[3], const double n[3])
{
        double len = sqrt(dot3(n, n));

        if (!(len > 0))
                return -EINVAL;
        if (c->n_lasers >= SEC_MAX_LASERS)
                return -ENOSPC;
        for (int i = 0; i < 3; i++) {
                c->plane_p[c->n_lasers][i] = p[i];
                c->plane_n[c->n_lasers][i] = n[i] / len;
        }
        return c->n_lasers++;
}

void sec_rig_laser_plane(double azimuth_deg, double p[3], double n[3])
{
        p[0] = p[1] = p[2] = 0;
        n[0] = -sin(azimuth_deg * DEG);
        n[1] = cos(azimuth_deg * DEG);
        n[2] = 0;
}

/* The world point where the ray of pixel (u, v) meets laser plane l. Returns 0 or -EDOM. */
static int ray_plane(const struct sec_ctx *c, int l, double u, double v, double X[3])
{
        const double *R = c->cam.R, *pn = c->plane_n[l];
        double xy[2], d[3], pc[3], s, den;

        if (sec_undistort(&c->cam.k, u, v, xy) < 0)
                return -EDOM;
        for (int i = 0; i < 3; i++) /* world direction R^T (x, y, 1) */
                d[i] = R[i] * xy[0] + R[3 + i] * xy[1] + R[6 + i];
        for (int i = 0; i < 3; i++)
                pc[i] = c->plane_p[l][i] - c->eye[i];
        den = dot3(pn, d);
        if (fabs(den) < GRAZING * sqrt(dot3(d, d)))
                return -EDOM;
        s = dot3(pn, pc) / den;
        if (!(s > 0))
                return -EDOM;
        for (int i = 0; i < 3; i++)
                X[i] = c->eye[i] + s * d[i];
        return 0;
}

/* World point w rotated by minus the turntable angle about z: the object frame. */
static void to_object(const double w[3], double turntable_deg, double o[3])
{
        double a = -turntable_deg * DEG;

        o[0] = cos(a) * w[0] - sin(a) * w[1];
        o[1] = sin(a) * w[0] + cos(a) * w[1];
        o[2] = w[2];
}

/* Sample (x, y) of channel ch of f, bilinear, as 8 bits. */
static uint8_t texel(const struct gn_frame *f, double x, double y, int ch)
{
        int x0 = (int)floor(x), y0 = (int)floor(y);
        double fx = x - x0, fy = y - y0, sum = 0;

        for (int j = 0; j < 2; j++)
                for (int i = 0; i < 2; i++) {
                        int xi = x0 + i < 0 ? 0 : x0 + i >= f->width ? f->width - 1 : x0 + i;
                        int yj = y0 + j < 0 ? 0 : y0 + j >= f->height ? f->height - 1 : y0 + j;
                        const uint8_t *row = f->data + (size_t)yj * f->stride;
                        size_t at = (size_t)xi * f->channels + ch;
                        double s = f->bits == 8 ? row[at] : ((const uint16_t *)row)[at] / 257.0;
                        sum += s * (i ? fx : 1 - fx) * (j ? fy : 1 - fy);
                }
        return (uint8_t)lround(sum);
}

static void colour(const struct gn_frame *f, double u, double v, uint8_t rgb[3])
{
        for (int i = 0; i < 3; i++)
                rgb[i] = f ? texel(f, u, v, f->channels == 3 ? i : 0) : 0;
}

/* Makes room for n more points and one more line. Returns 0 or -ENOMEM. */
static int reserve(struct sec_ctx *c, size_t n)
{
        if (c->n_pts + n > c->cap_pts) {
                size_t cap = c->cap_pts * 2 > c->n_pts + n ? c->cap_pts * 2 : c->n_pts + n;
                struct sec_point *p = realloc(c->pts, cap * sizeof(*p));
                if (!p)
                        return -ENOMEM;
                c->pts = p;
                c->cap_pts = cap;
        }
        if (c->n_lines == c->cap_lines) {
                size_t cap = c->cap_lines ? 2 * c->cap_lines : 64;
                struct sec_line *l = realloc(c->lines, cap * sizeof(*l));
                if (!l)
                        return -ENOMEM;
                c->lines = l;
                c->cap_lines = cap;
        }
        return 0;
}

static bool line_args_ok(const struct sec_ctx *c, int laser, const struct laserline_result *r,
                         bool columns, const struct gn_frame *tex)
{
        if (laser < 0 || laser >= c->n_lasers || !r || r->n < 0)
                return false;
        if (r->n > (columns ? c->cam.width : c->cam.height))
                return false;
        return !tex ||
               (tex->width == c->cam.width && tex->height == c->cam.height &&
                (tex->channels == 1 || tex->channels == 3) && (tex->bits == 8 || tex->bits == 16));
}

/* Whether centre i of r is vouched for by its neighbours: the first and last row of a run mix the
 * line's end with the dark beyond it, and a row off the mean of its neighbours straddles a step
 * or an occlusion; both give points up to 1.5 mm off the surface. */
static bool vouched(const struct laserline_result *r, int i)
{
        double a, b;

        if (i == 0 || i + 1 >= r->n)
                return false;
        a = r->centre[i - 1];
        b = r->centre[i + 1];
        return !isnan(a) && !isnan(b) && fabs(a - 2 * r->centre[i] + b) <= SEC_MAX_KINK_PX;
}

int sec_add_line(struct sec_ctx *c, int laser, double turntable_deg,
                 const struct laserline_result *r, bool columns, const struct gn_frame *texture)
{
        struct sec_line *ln;
        int ret;

        if (!line_args_ok(c, laser, r, columns, texture))
                return -EINVAL;
        if ((ret = reserve(c, (size_t)r->n)) < 0)
                return ret;
        ln = &c->lines[c->n_lines];
        *ln = (struct sec_line){.laser = laser, .turntable_deg = turntable_deg, .first = c->n_pts};
        to_object(c->eye, turntable_deg, ln->eye);
        for (int i = 0; i < r->n; i++) {
                double cu = r->centre[i], u = columns ? i : cu, v = columns ? cu : i, w[3], o[3];
                struct sec_point *p = &c->pts[c->n_pts];

                if (isnan(cu))
                        continue;
                if (!vouched(r, i)) {
                        c->unvouched++;
                        continue;
                }
                if (ray_plane(c, laser, u, v, w) < 0) {
                        c->rejected++;
                        continue;
                }
                to_object(w, turntable_deg, o);
                *p = (struct sec_point){.laser = (uint8_t)laser,
                                        .row = i,
                                        .line = (int32_t)c->n_lines,
                                        .u = (float)cu};
                for (int k = 0; k < 3; k++)
                        p->x[k] = (float)o[k];
                colour(texture, u, v, p->rgb);
                c->n_pts++;
        }
        ln->count = c->n_pts - ln->first;
        c->n_lines++;
        return (int)ln->count;
}

/* The point of line l at row, or NULL. */
static const struct sec_point *at_row(const struct sec_ctx *c, const struct sec_line *l, int row)
{
        size_t lo = l->first, hi = l->first + l->count;

        while (lo < hi) { /* points are in row order */
                size_t m = lo + (hi - lo) / 2;
                if (c->pts[m].row < row)
                        lo = m + 1;
                else
                        hi = m;
        }
        return lo < l->first + l->count && c->pts[lo].row == row ? &c->pts[lo] : NULL;
}

/* Line of the same laser next to line i in direction dir (+1 or -1), or NULL. */
static const struct sec_line *next_line(const struct sec_ctx *c, size_t i, int dir)
{
        int laser = c->lines[i].laser;

        for (size_t j = i + dir; j < c->n_lines; j += dir) /* wraps below 0 to SIZE_MAX */
                if (c->lines[j].laser == laser)
                        return &c->lines[j];
        return NULL;
}

/* Difference b - a of two neighbours (either may be NULL, then p stands in). */
static bool tangent(const struct sec_point *p, const struct sec_point *a, const struct sec_point *b,
                    double t[3])
{
        if (!a && !b)
                return false;
        a = a ? a : p;
        b = b ? b : p;
        for (int k = 0; k < 3; k++)
                t[k] = (double)b->x[k] - a->x[k];
        return true;
}

static bool point_normal(const struct sec_ctx *c, size_t li, struct sec_point *p)
{
        const struct sec_line *l = &c->lines[li], *prev = next_line(c, li, -1),
                              *next = next_line(c, li, +1);
        double tr[3], ta[3], n[3], len, eye[3];

        if (!tangent(p, at_row(c, l, p->row - 1), at_row(c, l, p->row + 1), tr) ||
            !tangent(p, prev ? at_row(c, prev, p->row) : NULL,
                     next ? at_row(c, next, p->row) : NULL, ta))
                return false;
        n[0] = tr[1] * ta[2] - tr[2] * ta[1];
        n[1] = tr[2] * ta[0] - tr[0] * ta[2];
        n[2] = tr[0] * ta[1] - tr[1] * ta[0];
        len = sqrt(dot3(n, n));
        if (!(len > 0))
                return false;
        for (int k = 0; k < 3; k++)
                eye[k] = l->eye[k] - p->x[k];
        if (dot3(n, eye) < 0)
                len = -len;
        for (int k = 0; k < 3; k++)
                p->n[k] = (float)(n[k] / len);
        return true;
}

size_t sec_normals(struct sec_ctx *c)
{
        size_t done = 0;

        for (size_t li = 0; li < c->n_lines; li++)
                for (size_t i = 0; i < c->lines[li].count; i++)
                        done += point_normal(c, li, &c->pts[c->lines[li].first + i]);
        return done;
}
