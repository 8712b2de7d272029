/* cv_shim.cpp - OpenCV behind the plain C API of cv_shim.h: the only C++ of calib/.
 * Every entry point catches every exception and returns -errno; the exception's text is
 * kept per thread for cal_cv_last_error(). */
#include <cerrno>
#include <cstring>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "cv_shim.h"

static thread_local char last_error[256];

static int fail(const char *what)
{
        snprintf(last_error, sizeof(last_error), "%s", what);
        return -EIO;
}

extern "C" const char *cal_cv_last_error(void)
{
        return last_error;
}

extern "C" int cal_board_corners(const struct cal_board *b)
{
        return (b->squares_x - 1) * (b->squares_y - 1);
}

extern "C" void cal_board_corner_xy(const struct cal_board *b, int id, double xy[2])
{
        int nx = b->squares_x - 1;

        xy[0] = (id % nx + 1) * b->square_mm;
        xy[1] = (id / nx + 1) * b->square_mm;
}

extern "C" bool cal_board_valid(const struct cal_board *b)
{
        return b->squares_x >= 3 && b->squares_y >= 3 && b->square_mm > 0 &&
               (b->type == CAL_BOARD_CHESSBOARD ||
                (b->type == CAL_BOARD_CHARUCO && b->marker_mm > 0 && b->marker_mm < b->square_mm &&
                 b->squares_x * b->squares_y / 2 <= 50));
}

/* The image as 8-bit gray (16-bit samples scaled by 1/256). */
static cv::Mat gray8(const struct cal_image *im)
{
        int depth = im->bits == 16 ? CV_16U : CV_8U;
        cv::Mat src(im->height, im->width, CV_MAKETYPE(depth, im->channels), (void *)im->data,
                    im->stride),
                gray, out;

        if (im->channels == 3)
                cv::cvtColor(src, gray, cv::COLOR_RGB2GRAY);
        else
                gray = src;
        gray.convertTo(out, CV_8U, im->bits == 16 ? 1.0 / 256 : 1.0);
        return out;
}

/* findChessboardCorners + cornerSubPix rather than findChessboardCornersSB: on the
 * renderer's boards (tests/calib/test-camera.c) SB's corners were up to 0.5 px off on tilted
 * boards and biased fx by 0.2%; these are within 0.1 px. */
static int find_chessboard(const struct cal_board *b, const cv::Mat &g, double *uv, int *ids,
                           int max)
{
        std::vector<cv::Point2f> c;
        cv::Size pattern(b->squares_x - 1, b->squares_y - 1);

        if (!cv::findChessboardCorners(g, pattern, c,
                                       cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE))
                return 0;
        cv::cornerSubPix(
                g, c, cv::Size(5, 5), cv::Size(-1, -1),
                cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
        int n = std::min((int)c.size(), max);
        for (int k = 0; k < n; k++) {
                uv[2 * k] = c[k].x;
                uv[2 * k + 1] = c[k].y;
                ids[k] = k;
        }
        return n;
}

/* OpenCV 4.6's interpolateCornersCharuco returns corners shifted by (+0.5, +0.5) px: it
 * wraps its cornerSubPix call in a spurious half-pixel shift (opencv issue 25539, fixed
 * upstream by pull request 28380). We subtract it; tests/render/test-render-cv.cpp and
 * tests/calib/test-camera.c check the corners against the renderer's exact geometry, so
 * an OpenCV that fixes it shows up as a 0.7 px error there. */
#define CHARUCO_SHIFT_PX 0.5

static int find_charuco(const struct cal_board *b, const cv::Mat &g, double *uv, int *ids, int max)
{
        auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
        auto params = cv::aruco::DetectorParameters::create();
        auto board = cv::aruco::CharucoBoard::create(
                b->squares_x, b->squares_y, (float)b->square_mm, (float)b->marker_mm, dict);
        std::vector<std::vector<cv::Point2f>> mc, rejected;
        std::vector<int> mid, cid;
        std::vector<cv::Point2f> cc;

        params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
        params->cornerRefinementWinSize = 2; /* keep off the nearby chessboard corners */
        cv::aruco::detectMarkers(g, dict, mc, mid, params, rejected);
        if (mid.empty())
                return 0;
        cv::aruco::refineDetectedMarkers(g, board, mc, mid, rejected);
        cv::aruco::interpolateCornersCharuco(mc, mid, g, board, cc, cid);
        int n = std::min((int)cc.size(), max);
        for (int k = 0; k < n; k++) {
                uv[2 * k] = cc[k].x - CHARUCO_SHIFT_PX;
                uv[2 * k + 1] = cc[k].y - CHARUCO_SHIFT_PX;
                ids[k] = cid[k];
        }
        return n;
}

extern "C" int cal_cv_find_corners(const struct cal_board *b, const struct cal_image *im,
                                   double *uv, int *ids, int max)
{
        if (!cal_board_valid(b) || !im->data || im->width < 8 || im->height < 8 ||
            (im->channels != 1 && im->channels != 3) || (im->bits != 8 && im->bits != 16) ||
            max < 0)
                return -EINVAL;
        try {
                cv::Mat g = gray8(im);
                if (b->type == CAL_BOARD_CHESSBOARD)
                        return find_chessboard(b, g, uv, ids, max);
                return find_charuco(b, g, uv, ids, max);
        } catch (const std::exception &e) {
                return fail(e.what());
        }
}

static cv::Mat camera_matrix(const struct cal_intrinsics *k)
{
        return (cv::Mat_<double>(3, 3) << k->fx, 0, k->cx, 0, k->fy, k->cy, 0, 0, 1);
}

static void views_to_cv(const struct cal_cv_views *v, std::vector<std::vector<cv::Point3f>> &obj,
                        std::vector<std::vector<cv::Point2f>> &img)
{
        size_t p = 0;

        for (size_t i = 0; i < v->n_views; i++) {
                obj.emplace_back();
                img.emplace_back();
                for (int j = 0; j < v->counts[i]; j++, p++) {
                        obj.back().emplace_back(v->obj[3 * p], v->obj[3 * p + 1],
                                                v->obj[3 * p + 2]);
                        img.back().emplace_back(v->uv[2 * p], v->uv[2 * p + 1]);
                }
        }
}

static void fit_out(const cv::Mat &K, const cv::Mat &dist, const cv::Mat &std_in,
                    const cv::Mat &per_view, const std::vector<cv::Mat> &rv,
                    const std::vector<cv::Mat> &tv, struct cal_intrinsics *k,
                    struct cal_cv_fit *fit)
{
        k->fx = K.at<double>(0, 0);
        k->fy = K.at<double>(1, 1);
        k->cx = K.at<double>(0, 2);
        k->cy = K.at<double>(1, 2);
        for (int i = 0; i < 5; i++)
                k->dist[i] = dist.at<double>(i);
        for (int i = 0; i < 4; i++)
                fit->std[i] = std_in.at<double>(i);
        for (size_t i = 0; i < rv.size(); i++)
                for (int j = 0; j < 3; j++) {
                        if (fit->view_rms && j == 0)
                                fit->view_rms[i] = per_view.at<double>((int)i);
                        if (fit->rvecs)
                                fit->rvecs[3 * i + j] = rv[i].at<double>(j);
                        if (fit->tvecs)
                                fit->tvecs[3 * i + j] = tv[i].at<double>(j);
                }
}

extern "C" int cal_cv_calibrate(const struct cal_cv_views *v, int width, int height,
                                struct cal_intrinsics *k, struct cal_cv_fit *fit)
{
        if (v->n_views < 1 || width < 1 || height < 1)
                return -EINVAL;
        for (size_t i = 0; i < v->n_views; i++)
                if (v->counts[i] < 4)
                        return -EINVAL;
        try {
                std::vector<std::vector<cv::Point3f>> obj;
                std::vector<std::vector<cv::Point2f>> img;
                cv::Mat K, dist, std_in, std_ex, per_view;
                std::vector<cv::Mat> rv, tv;

                views_to_cv(v, obj, img);
                fit->rms = cv::calibrateCamera(
                        obj, img, cv::Size(width, height), K, dist, rv, tv, std_in, std_ex,
                        per_view, 0,
                        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100,
                                         1e-9));
                fit_out(K, dist, std_in, per_view, rv, tv, k, fit);
                return 0;
        } catch (const std::exception &e) {
                return fail(e.what());
        }
}

extern "C" int cal_cv_solve_pnp(const double *obj, const double *uv, int n,
                                const struct cal_intrinsics *k, double rvec[3], double tvec[3])
{
        if (n < 4)
                return -EINVAL;
        try {
                cv::Mat o(n, 3, CV_64F, (void *)obj), p(n, 2, CV_64F, (void *)uv), r, t;
                cv::Mat dist(1, 5, CV_64F, (void *)k->dist);

                if (!cv::solvePnP(o, p, camera_matrix(k), dist, r, t))
                        return fail("solvePnP found no pose");
                for (int i = 0; i < 3; i++) {
                        rvec[i] = r.at<double>(i);
                        tvec[i] = t.at<double>(i);
                }
                return 0;
        } catch (const std::exception &e) {
                return fail(e.what());
        }
}

extern "C" int cal_cv_project(const double *obj, int n, const double rvec[3], const double tvec[3],
                              const struct cal_intrinsics *k, double *uv)
{
        if (n < 1)
                return -EINVAL;
        try {
                cv::Mat o(n, 1, CV_64FC3, (void *)obj), r(3, 1, CV_64F, (void *)rvec),
                        t(3, 1, CV_64F, (void *)tvec), dist(1, 5, CV_64F, (void *)k->dist);
                cv::Mat out(n, 1, CV_64FC2, uv);

                cv::projectPoints(o, r, t, camera_matrix(k), dist, out);
                if (out.data != (uchar *)uv)
                        return fail("projectPoints reallocated its output");
                return 0;
        } catch (const std::exception &e) {
                return fail(e.what());
        }
}

extern "C" int cal_cv_undistort(const double *uv, int n, const struct cal_intrinsics *k, double *xy)
{
        if (n < 1)
                return -EINVAL;
        try {
                cv::Mat p(n, 1, CV_64FC2, (void *)uv), dist(1, 5, CV_64F, (void *)k->dist);
                cv::Mat out(n, 1, CV_64FC2, xy);

                cv::undistortPoints(
                        p, out, camera_matrix(k), dist, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50,
                                         1e-12));
                if (out.data != (uchar *)xy)
                        return fail("undistortPoints reallocated its output");
                return 0;
        } catch (const std::exception &e) {
                return fail(e.what());
        }
}

extern "C" int cal_cv_find_circles(const struct cal_image *im, double min_r, double max_r,
                                   double *xyr, int max)
{
        if (!im->data || min_r < 1 || max_r < min_r || max < 1)
                return -EINVAL;
        try {
                std::vector<cv::Vec3f> c;
                cv::Mat g = gray8(im), s;

                cv::GaussianBlur(g, s, cv::Size(5, 5), 1.5);
                cv::HoughCircles(s, c, cv::HOUGH_GRADIENT, 1.0, min_r, 40, 30, (int)min_r,
                                 (int)ceil(max_r));
                int n = std::min((int)c.size(), max);
                for (int k = 0; k < n; k++)
                        for (int j = 0; j < 3; j++)
                                xyr[3 * k + j] = c[k][j];
                return n;
        } catch (const std::exception &e) {
                return fail(e.what());
        }
}
