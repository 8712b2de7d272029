/* test-render-cv.cpp - the renderer against OpenCV: the camera model equals projectPoints
 * (with distortion) within 1e-3 px, both for sim_cam_project and for the rays the renderer
 * traces; ChArUco markers of a rendered board are found by OpenCV's detector with the
 * right ids where the board geometry puts them; chessboard corners likewise. */
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
        "lamps:\n  - { name: l0, backend: modbus-coil, bus: relays, coil: 0, elevation: 35, "
        "radius: 800, azimuth: 10, intensity: 2.0e6 }\n";
static const char cams[] =
        "cameras:\n"
        "  - { name: c0, backend: sim, bus: frames, elevation: 25, distance: 420, azimuth: 0,\n"
        "      target: [0, 0, 60], width: 480, height: 360, fx: 560, fy: 555, cx: 241.2,\n"
        "      cy: 178.9, distortion: [-0.12, 0.08, 0.0011, -0.0007, -0.02], exposure_us: 20000 }\n";

static void geom(const struct rtest *t, const struct sim_rig_state *st, cv::Mat &K,
                 cv::Mat &dist, cv::Mat &rvec, cv::Mat &tvec, struct sim_cam_geom *g)
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
        struct sim_rig_state st = { 17, 0, -35, { true }, false };
        struct sim_expose ex = { 0, 0, 8, true };
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
                double p[3] = { pts[i].x, pts[i].y, pts[i].z }, q[2];
                CHECK(sim_cam_project(&g, p, q) == 0);
                CHECK_NEAR(q[0], uv[i].x, 1e-3);
                CHECK_NEAR(q[1], uv[i].y, 1e-3);
        }
        /* the renderer's rays: each hit point projects back onto its pixel centre */
        rt_render(&t, &st, &ex, 0, &f, SIM_TRUTH_POINT, &tr);
        pts.clear();
        double c = cos(st.turntable_deg * M_PI / 180), s = sin(st.turntable_deg * M_PI / 180);
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
static cv::Point2d board_px(const struct rtest *t, const struct sim_rig_state *st, double x,
                            double y)
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
        "        pose: { translate: [20, -90, 15], rotate_x: 90, rotate_z: 90 } }\n"
        "  turntable: { radius: 150 }\n";

static void test_charuco(void)
{
        struct rtest t;
        struct sim_rig_state st = { 0, 0, 0, { true }, false };
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
        cv::aruco::detectMarkers(gray, dict, corners, ids, params);
        fprintf(stderr, "charuco: %zu markers found\n", ids.size());
        CHECK(ids.size() == 15); /* 6 x 5 squares: 15 white squares, ids 0..14 */
        for (size_t k = 0; k < ids.size(); k++) {
                /* id -> white square, counted row by row from the top row (y = 4) */
                int id = ids[k], n = 0, sx = -1, sy = -1;
                for (int y = 4; y >= 0 && sx < 0; y--)
                        for (int x = 0; x < 6; x++)
                                if ((x + y) % 2 == 1 && n++ == id) {
                                        sx = x;
                                        sy = y;
                                        break;
                                }
                CHECK(sx >= 0);
                double x0 = sx * 30 + 4, y1 = sy * 30 + 26;
                cv::Point2d want[4] = { board_px(&t, &st, x0, y1), board_px(&t, &st, x0 + 22, y1),
                                        board_px(&t, &st, x0 + 22, y1 - 22),
                                        board_px(&t, &st, x0, y1 - 22) };
                for (int c = 0; c < 4; c++) {
                        double e = cv::norm(cv::Point2d(corners[k][c]) - want[c]);
                        worst = std::max(worst, e);
                        if (e >= 0.3) fprintf(stderr, "id %d c %d got %.3f %.3f want %.3f %.3f\n", id, c, corners[k][c].x, corners[k][c].y, want[c].x, want[c].y);
                }
        }
        fprintf(stderr, "charuco: worst marker corner error %.3f px\n", worst);
        /* the ChArUco chessboard corners, interpolated by OpenCV from the markers */
        auto board = cv::aruco::CharucoBoard::create(6, 5, 30, 22, dict);
        std::vector<cv::Point2f> cc;
        std::vector<int> cid;
        cv::aruco::interpolateCornersCharuco(corners, ids, gray, board, cc, cid);
        CHECK(cc.size() == 20);
        worst = 0;
        for (size_t k = 0; k < cc.size(); k++) {
                cv::Point3f p = board->chessboardCorners[cid[k]];
                double e = cv::norm(cv::Point2d(cc[k]) - board_px(&t, &st, p.x, p.y));
                worst = std::max(worst, e);
                CHECK(e < 0.2);
        }
        fprintf(stderr, "charuco: worst chessboard corner error %.3f px\n", worst);
        gn_frame_free_data(&f);
        rt_close(&t);
}

static void test_chessboard(void)
{
        struct rtest t;
        struct sim_rig_state st = { 0, 0, 0, { true }, false };
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
        cv::cornerSubPix(gray, cc, cv::Size(5, 5), cv::Size(-1, -1),
                         cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50,
                                          1e-3));
        for (const auto &p : cc) { /* nearest inner corner of the board */
                double best = 1e9;
                for (int y = 1; y < 5; y++)
                        for (int x = 1; x < 6; x++)
                                best = std::min(best, cv::norm(cv::Point2d(p) -
                                                               board_px(&t, &st, 30 * x, 30 * y)));
                worst = std::max(worst, best);
                CHECK(best < 0.2);
        }
        fprintf(stderr, "chessboard: %zu corners, worst error %.3f px\n", cc.size(), worst);
        gn_frame_free_data(&f);
        rt_close(&t);
}

int main(int argc, char **argv)
{
        const char *which = argc > 1 ? argv[1] : "all";

        if (!strcmp(which, "projection") || !strcmp(which, "all"))
                test_projection();
        if (!strcmp(which, "charuco") || !strcmp(which, "all"))
                test_charuco();
        if (!strcmp(which, "chessboard") || !strcmp(which, "all"))
                test_chessboard();
        return 0;
}
