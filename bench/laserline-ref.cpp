/* laserline-ref.cpp - the OpenCV reference of bench/laserline (see laserline-ref.h). Its
 * matrices are kept between frames so that only the processing is timed. */
#include <cerrno>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "laserline-ref.h"

#define REF_THRESHOLD 20 /* DN */
#define REF_WINDOW    8  /* px each side of the brightest pixel */

struct llref {
        cv::Mat red_on, red_off, diff, thr, blur;
};

struct llref *llref_new(int w, int h)
{
        try {
                return new llref();
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

static float row_centre(const cv::Mat &img, int v)
{
        const uint8_t *p = img.ptr<uint8_t>(v);
        double maxv, s = 0, su = 0;
        cv::Point at;

        cv::minMaxLoc(img.row(v), nullptr, &maxv, nullptr, &at);
        if (maxv <= 0)
                return NAN;
        for (int u = std::max(at.x - REF_WINDOW, 0); u <= std::min(at.x + REF_WINDOW, img.cols - 1);
             u++) {
                s += p[u];
                su += (double)p[u] * u;
        }
        return (float)(su / s);
}

int llref_extract(struct llref *r, const struct gn_frame *on, const struct gn_frame *off,
                  float *centre)
{
        try {
                cv::Mat a(on->height, on->width, CV_8UC3, on->data, on->stride);
                cv::Mat b(off->height, off->width, CV_8UC3, off->data, off->stride);

                cv::extractChannel(a, r->red_on, 0);
                cv::extractChannel(b, r->red_off, 0);
                cv::subtract(r->red_on, r->red_off, r->diff); /* saturates at 0 */
                cv::threshold(r->diff, r->thr, REF_THRESHOLD, 0, cv::THRESH_TOZERO);
                cv::GaussianBlur(r->thr, r->blur, cv::Size(5, 5), 0);
                for (int v = 0; v < on->height; v++)
                        centre[v] = row_centre(r->blur, v);
                return 0;
        } catch (...) {
                return -EIO;
        }
}
