/* laserline-ref.cpp - the OpenCV references of bench/laserline (see laserline-ref.h). Their
 * matrices are kept between frames so that only the processing is timed.
 *
 * LLREF_HORUS follows the algorithm of Horus 0.2 (bq/horus, GPL; only its steps and default
 * settings are reproduced here, in C++): the scanner subtracts the laser-off capture from the
 * laser-on one on the colour image, takes the red plane of a channel split, zeroes what is
 * below the threshold, box-blurs, zeroes below the threshold again, keeps per row only a
 * window around the first maximum (a 0/255 mask and a bitwise and), then takes per row the
 * sum of the pixels and the sum of the pixels times a precomputed matrix holding each
 * pixel's column (double precision, the whole frame), and smooths the centres with a
 * Gaussian along each run of consecutive rows that have a line. Python's slice rules decide
 * the window where it would start before the row (a negative start counts from the row's
 * end). */
#include <cerrno>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "laserline-ref.h"

#define HORUS_THRESHOLD 50 /* DN: threshold_value_scanning */
#define HORUS_BLUR      5  /* px: blur_value_scanning 2, a 2 * 2 + 1 box */
#define HORUS_WINDOW    8  /* px each side of the row's maximum: window_value_scanning */
#define HORUS_SGF_SIGMA 2.0
#define HORUS_SGF_REACH 8 /* rows: the Gaussian cut at 4 sigma, as scipy.ndimage does */

#define TUNED_THRESHOLD 20 /* DN */
#define TUNED_WINDOW    8  /* px each side of the brightest pixel */

struct llref {
        cv::Mat diff, thr, blur, thr2, mask, masked, weight, prod, sum, wsum;
        std::vector<cv::Mat> planes;
        std::vector<double> u, f, kernel;
        std::vector<int> rows;
        cv::Mat red_on, red_off;
};

struct llref *llref_new(int w, int h)
{
        try {
                llref *r = new llref();
                r->weight.create(h, w, CV_64F);
                for (int v = 0; v < h; v++)
                        for (int x = 0; x < w; x++)
                                r->weight.at<double>(v, x) = x;
                for (int k = -HORUS_SGF_REACH; k <= HORUS_SGF_REACH; k++)
                        r->kernel.push_back(
                                std::exp(-0.5 * k * k / (HORUS_SGF_SIGMA * HORUS_SGF_SIGMA)));
                double s = 0;
                for (double k : r->kernel)
                        s += k;
                for (double &k : r->kernel)
                        k /= s;
                return r;
        } catch (...) {
                return nullptr;
        }
}

struct llref *llref_free(struct llref *r)
{
        delete r;
        return nullptr;
}

void llref_threads(int n)
{
        try {
                cv::setNumThreads(n > 0 ? n : -1);
        } catch (...) {
        }
}

/* The Horus window: per row, 255 from the first maximum - WINDOW to + WINDOW, with Python's
 * slice semantics; then the image and the mask. */
static void horus_window(llref *r)
{
        const cv::Mat &img = r->thr2;

        r->mask.create(img.size(), CV_8U);
        r->mask.setTo(0);
        for (int v = 0; v < img.rows; v++) {
                cv::Point at;
                cv::minMaxLoc(img.row(v), nullptr, nullptr, nullptr, &at);
                int lo = at.x - HORUS_WINDOW, hi = std::min(at.x + HORUS_WINDOW + 1, img.cols);
                if (lo < 0)
                        lo = std::max(lo + img.cols, 0);
                if (lo < hi)
                        r->mask.row(v).colRange(lo, hi).setTo(255);
        }
        cv::bitwise_and(img, r->mask, r->masked);
}

/* Index i of a run of n, reflected at both ends as scipy.ndimage's mode 'reflect'. */
static int reflect(int i, int n)
{
        i %= 2 * n;
        if (i < 0)
                i += 2 * n;
        return i < n ? i : 2 * n - 1 - i;
}

/* Horus's segmented Gaussian filter: r->u (one centre per row in r->rows) smoothed along
 * each run of consecutive rows, into r->f. */
static void horus_sgf(llref *r)
{
        size_t n = r->u.size();

        r->f = r->u;
        if (n <= 1)
                return;
        for (size_t a = 0, b; a < n; a = b) {
                for (b = a + 1; b < n && r->rows[b] == r->rows[b - 1] + 1; b++)
                        ;
                int len = (int)(b - a);
                for (int i = 0; i < len; i++) {
                        double s = 0;
                        for (int k = -HORUS_SGF_REACH; k <= HORUS_SGF_REACH; k++)
                                s += r->kernel[k + HORUS_SGF_REACH] * r->u[a + reflect(i + k, len)];
                        r->f[a + i] = s;
                }
        }
}

static void horus(llref *r, const cv::Mat &on, const cv::Mat &off, int h, float *centre)
{
        cv::subtract(on, off, r->diff); /* saturates at 0 */
        cv::split(r->diff, r->planes);
        cv::threshold(r->planes[0], r->thr, HORUS_THRESHOLD, 255, cv::THRESH_TOZERO);
        cv::blur(r->thr, r->blur, cv::Size(HORUS_BLUR, HORUS_BLUR));
        cv::threshold(r->blur, r->thr2, HORUS_THRESHOLD, 255, cv::THRESH_TOZERO);
        horus_window(r);
        cv::reduce(r->masked, r->sum, 1, cv::REDUCE_SUM, CV_64F);
        cv::multiply(r->weight, r->masked, r->prod, 1, CV_64F);
        cv::reduce(r->prod, r->wsum, 1, cv::REDUCE_SUM, CV_64F);
        r->u.clear();
        r->rows.clear();
        for (int v = 0; v < h; v++)
                if (r->sum.at<double>(v) > 0) {
                        r->u.push_back(r->wsum.at<double>(v) / r->sum.at<double>(v));
                        r->rows.push_back(v);
                }
        horus_sgf(r);
        for (int v = 0; v < h; v++)
                centre[v] = NAN;
        for (size_t i = 0; i < r->rows.size(); i++)
                centre[r->rows[i]] = (float)r->f[i];
}

static float tuned_row(const cv::Mat &img, int v)
{
        const uint8_t *p = img.ptr<uint8_t>(v);
        double maxv, s = 0, su = 0;
        cv::Point at;

        cv::minMaxLoc(img.row(v), nullptr, &maxv, nullptr, &at);
        if (maxv <= 0)
                return NAN;
        for (int u = std::max(at.x - TUNED_WINDOW, 0);
             u <= std::min(at.x + TUNED_WINDOW, img.cols - 1); u++) {
                s += p[u];
                su += (double)p[u] * u;
        }
        return (float)(su / s);
}

static void tuned(llref *r, const cv::Mat &on, const cv::Mat &off, int h, float *centre)
{
        cv::extractChannel(on, r->red_on, 0);
        cv::extractChannel(off, r->red_off, 0);
        cv::subtract(r->red_on, r->red_off, r->diff); /* saturates at 0 */
        cv::threshold(r->diff, r->thr, TUNED_THRESHOLD, 0, cv::THRESH_TOZERO);
        cv::GaussianBlur(r->thr, r->blur, cv::Size(5, 5), 0);
        for (int v = 0; v < h; v++)
                centre[v] = tuned_row(r->blur, v);
}

int llref_extract(struct llref *r, enum llref_kind kind, const struct gn_frame *on,
                  const struct gn_frame *off, float *centre)
{
        try {
                cv::Mat a(on->height, on->width, CV_8UC3, on->data, on->stride);
                cv::Mat b(off->height, off->width, CV_8UC3, off->data, off->stride);

                if (kind == LLREF_HORUS)
                        horus(r, a, b, on->height, centre);
                else
                        tuned(r, a, b, on->height, centre);
                return 0;
        } catch (...) {
                return -EIO;
        }
}
