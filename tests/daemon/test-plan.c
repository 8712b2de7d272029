/* test-plan.c - the capture planner (daemon/plan.h): expansion counts and dense seqs,
 * calibration frames first, lamps and brackets innermost with the lit lamp kept lit across
 * poses, serpentine passes and the nesting order of least estimate, continuous axes the
 * shortest way round, occlusion and glare skips on a rig where they must happen, and the
 * estimate against sums of plan_move_time() and exposures, above the lower bound; `laser: each`
 * on the two-laser Ciclop rig: one frame per laser alone at every pose, next to the unlit.
 * Usage: test-plan SIM-RIG DEMO-SESSION PAPER-RIG PAPER-SESSION CASE; an unknown CASE fails. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "common/riggeom.h"
#include "common/sessconf.h"
#include "daemon/plan.h"
#include "drivers/axis/axis.h"
#include "drivers/registry.h"
#include "tests/test.h"

static const char *sim_rig_path, *demo_path, *paper_rig_path, *paper_path;

/* A rig with a continuous turntable (speed %g, accel %g) and a limited light arm (speed %g,
 * accel %g, backlash %g), two lamps at 800 mm (elevations 12 and 40) farther than two cameras
 * at 600 mm (elevations 10 and 40), all at azimuth 0: at light arm 0 the cameras hide the
 * lamps, at 180 lamp l0 shines into camera c0. */
#define TEST_RIG                                                                                   \
        "rig: t\n"                                                                                 \
        "buses:\n"                                                                                 \
        "  - { name: d, type: modbus-rtu, port: /dev/null }\n"                                     \
        "  - { name: f, type: sim, port: /tmp/f.sock }\n"                                          \
        "axes:\n"                                                                                  \
        "  - { name: turntable, continuous: true, max_speed: %g, accel: %g, settle_ms: 50,\n"      \
        "      modbus: { bus: d, unit: 1 } }\n"                                                    \
        "  - { name: light_arm, limits: [-180, 180], max_speed: %g, accel: %g, settle_ms: 100,\n"  \
        "      backlash: %g, modbus: { bus: d, unit: 2 } }\n"                                      \
        "lamps:\n"                                                                                 \
        "  - { name: l0, elevation: 12, radius: 800, warmup_ms: 100,\n"                            \
        "      modbus-coil: { bus: d, unit: 10, coil: 0 } }\n"                                     \
        "  - { name: l1, elevation: 40, radius: 800, warmup_ms: 100,\n"                            \
        "      modbus-coil: { bus: d, unit: 10, coil: 1 } }\n"                                     \
        "laser: { name: laser, warmup_ms: 10, modbus-coil: { bus: d, unit: 10, coil: 2 } }\n"      \
        "cameras:\n"                                                                               \
        "  - { name: c0, elevation: 10, distance: 600, sim: { bus: f } }\n"                        \
        "  - { name: c1, elevation: 40, distance: 600, sim: { bus: f } }\n"

static struct rig_config *rig_load(const char *path)
{
        struct rig_config *rc = NULL;
        char err[512];
        int r = rigconf_load(path, registry_backends, &rc, err, sizeof(err));

        if (r < 0)
                fprintf(stderr, "%s\n", err);
        CHECK_INT(r, 0);
        return rc;
}

/* The test rig with the given timing. */
static struct rig_config *test_rig(double tt_speed, double tt_accel, double la_speed,
                                   double la_accel, double backlash)
{
        char path[] = "/tmp/gonio-test-plan-XXXXXX", text[2048];
        struct rig_config *rc;
        int fd = mkstemp(path);

        CHECK(fd >= 0);
        snprintf(text, sizeof(text), TEST_RIG, tt_speed, tt_accel, la_speed, la_accel, backlash);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        close(fd);
        rc = rig_load(path);
        unlink(path);
        return rc;
}

static struct session_conf *session(const struct rig_config *rc, const char *text)
{
        struct session_conf *sc = NULL;
        char err[512];
        int r = sessconf_load_string("/tmp/t.yaml", text, rc, &sc, err, sizeof(err));

        if (r < 0)
                fprintf(stderr, "%s\n", err);
        CHECK_INT(r, 0);
        return sc;
}

static struct plan *build(const struct rig_config *rc, const struct session_conf *sc,
                          const struct gn_pose *start)
{
        struct plan *p = NULL;

        CHECK_INT(plan_build(rc, sc, start, &p), 0);
        CHECK(p != NULL);
        return p;
}

/* Seqs are dense from 1, captures their count, starts non-decreasing, and the estimate is
 * plan_estimate()'s and above the lower bound. */
static void check_invariants(const struct rig_config *rc, const struct plan *p,
                             const struct gn_pose *start)
{
        int64_t seq = 1;

        for (size_t i = 0; i < p->n_shots; i++) {
                CHECK_INT(p->shots[i].seq, seq);
                CHECK(p->shots[i].cameras != 0);
                seq += __builtin_popcount(p->shots[i].cameras);
                CHECK(i == 0 || p->shots[i].t_start_s >= p->shots[i - 1].t_start_s);
        }
        CHECK_INT(p->n_captures, seq - 1);
        CHECK_NEAR(plan_estimate(rc, p->shots, p->n_shots, start), p->estimate_s, 1e-9);
        CHECK(p->lower_bound_s <= p->estimate_s + 1e-9);
        CHECK(p->lower_bound_s > 0 || p->n_shots == 0);
}

static bool same_angles(const struct gn_pose *a, const struct gn_pose *b)
{
        for (int r = 0; r < GN_ROLE_COUNT; r++)
                if (!(isnan(a->deg[r]) && isnan(b->deg[r])) && a->deg[r] != b->deg[r])
                        return false;
        return true;
}

/* Every capture of p is found by its seq, and nothing else. */
static void check_seqs(const struct plan *p)
{
        int cam = -1;

        for (size_t i = 0; i < p->n_shots; i++)
                for (int c = 0, k = 0; c < RIG_MAX_CAMERAS; c++)
                        if (p->shots[i].cameras & (1u << c)) {
                                CHECK(plan_find_seq(p, p->shots[i].seq + k++, &cam) ==
                                      &p->shots[i]);
                                CHECK_INT(cam, c);
                        }
        CHECK(plan_find_seq(p, 0, &cam) == NULL);
        CHECK(plan_find_seq(p, (int64_t)p->n_captures + 1, &cam) == NULL);
        CHECK(plan_find_seq(NULL, 1, NULL) == NULL);
}

/* Brackets without 0 EV: darks at each, and at 0 EV for the laser and the flats; then each
 * lamp's brackets in order. */
static void check_calibration(const struct rig_config *rc)
{
        struct session_conf *sc;
        struct plan *p;

        sc = session(rc, "dataset: d\nsweep: { turntable: [0, 90] }\ncameras: [cam1]\n"
                         "lamps: [lamp0, lamp1]\nbrackets: [-1, 1]\nlaser: true\n"
                         "dark_frames: 2\nflat_frames: 3\nexposure_us: 8000\n");
        p = build(rc, sc, NULL);
        check_invariants(rc, p, NULL);
        CHECK_INT(p->n_shots, 6 + 3 + 2 * (2 * 2 + 1));
        for (size_t i = 0; i < 6; i++) {
                CHECK_INT(p->shots[i].kind, PLAN_DARK);
                CHECK_INT(p->shots[i].bracket, i < 4 ? (int)i / 2 : -1);
                CHECK_NEAR(p->shots[i].ev, i < 4 ? (i < 2 ? -1 : 1) : 0, 0);
        }
        CHECK_INT(plan_shot_exposure_us(rc, &p->shots[0], 1), 4000);
        for (size_t i = 6; i < 9; i++) {
                CHECK_INT(p->shots[i].kind, PLAN_FLAT);
                CHECK_INT(p->shots[i].pose.lamps, 0x3);
        }
        CHECK_INT(p->shots[9].bracket, 0);
        CHECK_INT(p->shots[10].bracket, 1);
        CHECK_INT(p->shots[9].pose.lamps, p->shots[10].pose.lamps);
        CHECK_NEAR(plan_shot_gain(rc, &p->shots[9], 1), rc->cameras[1].gain, 0);
        plan_free(p);
        sessconf_free(sc);
}

/* unlit: a frame with lamps and laser off at each pose, right next to the laser frame, at
 * 0 EV like it (bracket -1), with its darks. */
static void check_unlit(const struct rig_config *rc)
{
        struct session_conf *sc;
        struct plan *p;

        sc = session(rc, "dataset: d\nsweep: { turntable: [0, 90, 180] }\ncameras: [cam1]\n"
                         "lamps: [lamp0]\nbrackets: [1]\nlaser: true\nunlit: true\n"
                         "dark_frames: 1\n");
        p = build(rc, sc, NULL);
        check_invariants(rc, p, NULL);
        CHECK_INT(p->n_shots, 2 + 3 * 3); /* darks at +1 and 0 EV; lamp, unlit, laser */
        for (size_t i = 2; i < p->n_shots; i++) {
                const struct plan_shot *x = &p->shots[i];

                if (x->kind == PLAN_LASER || x->pose.lamps)
                        continue;
                CHECK_INT(x->kind, PLAN_IMAGE); /* the unlit frame */
                CHECK(!x->pose.lasers);
                CHECK_INT(x->bracket, -1);
                const struct plan_shot *l = i + 1 < p->n_shots && p->shots[i + 1].kind == PLAN_LASER
                                                    ? &p->shots[i + 1]
                                                    : &p->shots[i - 1];
                CHECK_INT(l->kind, PLAN_LASER); /* next to the laser, at its exposure */
                CHECK_INT(plan_shot_exposure_us(rc, x, 1), plan_shot_exposure_us(rc, l, 1));
        }
        CHECK_INT(p->shots[1].bracket, -1);
        plan_free(p);
        sessconf_free(sc);
}

static void case_expansion(void)
{
        struct rig_config *rc = rig_load(sim_rig_path);
        struct session_conf *sc = NULL;
        struct plan *p;
        size_t kinds[4] = {0};
        char err[512];

        CHECK_INT(sessconf_load(demo_path, rc, &sc, err, sizeof(err)), 0);
        p = build(rc, sc, NULL);
        check_invariants(rc, p, NULL);
        /* 1 dark + 8 poses x (4 lamps + laser), each of both cameras */
        CHECK_INT(p->n_shots, 41);
        CHECK_INT(p->n_captures, 82);
        CHECK_INT(p->n_moves, 8);
        CHECK_INT(p->n_skips, 0);
        CHECK_INT(p->shots[0].kind, PLAN_DARK);
        CHECK_INT(p->shots[0].pose.lamps, 0);
        CHECK(!gn_pose_has(&p->shots[0].pose, GN_ROLE_TURNTABLE));
        for (size_t i = 0; i < p->n_shots; i++) {
                kinds[p->shots[i].kind]++;
                CHECK_INT(p->shots[i].cameras, 0x3);
                CHECK_INT(p->shots[i].settle_ms[GN_ROLE_TURNTABLE], 20);
                CHECK(p->shots[i].kind == PLAN_DARK ||
                      !gn_pose_has(&p->shots[i].pose, GN_ROLE_CAMERA_ARM)); /* not swept */
        }
        CHECK_INT(kinds[PLAN_DARK], 1);
        CHECK_INT(kinds[PLAN_LASER], 8);
        CHECK_INT(kinds[PLAN_IMAGE], 32);
        check_seqs(p);
        plan_free(p);
        sessconf_free(sc);
        check_calibration(rc);
        check_unlit(rc);

        /* 3600 x 3600 poses: refused before anything is built */
        sc = session(rc, "dataset: d\nsweep:\n  turntable: { from: 0, to: 359.9, step: 0.1 }\n"
                         "  light_arm: { from: 0, to: 359.9, step: 0.1 }\n");
        p = NULL;
        CHECK_INT(plan_build(rc, sc, NULL, &p), -E2BIG);
        CHECK_INT(plan_build_naive(rc, sc, NULL, &p), -E2BIG);
        CHECK(p == NULL);
        sessconf_free(sc);
        rigconf_free(rc);
}

/* At each pose the shots are together (poses visited once), each lamp's brackets together
 * and in order, and the lamp lit last at a pose is the first at the next. */
static void case_innermost(void)
{
        struct rig_config *rc = rig_load(sim_rig_path);
        struct session_conf *sc = session(
                rc, "dataset: d\nsweep:\n  turntable: { from: 0, to: 360, step: 60 }\n"
                    "  light_arm: [0, 30, 60]\n  camera_arm: [-30, 30]\nbrackets: [-1, 0, 1]\n");
        struct plan *p = build(rc, sc, NULL);
        size_t runs = 0;

        check_invariants(rc, p, NULL);
        CHECK_INT(p->n_shots, 6 * 3 * 2 * 4 * 3);
        CHECK_INT(p->n_moves, 6 * 3 * 2);
        CHECK_INT(p->n_order, 3);
        for (size_t i = 0; i < p->n_shots; i++) {
                const struct plan_shot *s = &p->shots[i];

                CHECK_INT(__builtin_popcount(s->pose.lamps), 1);
                CHECK_INT(s->bracket, (int)(i % 3));
                if (i == 0 || !same_angles(&s->pose, &s[-1].pose)) {
                        runs++; /* a new pose: never seen before, starts with the last lamp */
                        for (size_t j = 0; j < i; j++)
                                CHECK(!same_angles(&s->pose, &p->shots[j].pose));
                        CHECK(i == 0 || s->pose.lamps == s[-1].pose.lamps);
                }
        }
        CHECK_INT(runs, 36);
        plan_free(p);
        sessconf_free(sc);
        rigconf_free(rc);
}

/* The angles of role at the image shots' successive poses, into deg; returns their number. */
static size_t pose_angles(const struct plan *p, enum gn_role role, double *deg, size_t max)
{
        size_t n = 0;

        for (size_t i = 0; i < p->n_shots && n < max; i++)
                if (p->shots[i].kind == PLAN_IMAGE &&
                    (n == 0 || !same_angles(&p->shots[i].pose, &p->shots[i - 1].pose)))
                        deg[n++] = p->shots[i].pose.deg[role];
        return n;
}

static void case_serpentine(void)
{
        struct rig_config *rc = test_rig(10, 20, 200, 400, 0); /* the light arm is fast */
        struct session_conf *sc = session(
                rc, "dataset: d\nsweep:\n  turntable: [0, 120, 240]\n"
                    "  light_arm: [-90, -60, -30, 30, 60, 90]\nlamps: [l1]\ncameras: [c1]\n");
        struct plan *p = build(rc, sc, NULL);
        double la[32], tt[32];
        size_t n = pose_angles(p, GN_ROLE_LIGHT_ARM, la, 32);

        check_invariants(rc, p, NULL);
        CHECK_INT(pose_angles(p, GN_ROLE_TURNTABLE, tt, 32), 18);
        CHECK_INT(n, 18);
        /* the slow turntable outside, the fast light arm inside */
        CHECK_INT(p->n_order, 2);
        CHECK_INT(p->order[0], GN_ROLE_TURNTABLE);
        CHECK_INT(p->order[1], GN_ROLE_LIGHT_ARM);
        for (size_t pass = 0; pass < 3; pass++)
                for (size_t i = 0; i < 6; i++) {
                        double want = -90.0 + 30.0 * (i < 3 ? i : i + 1);

                        /* up, down, up: the light arm stays put while the turntable steps */
                        CHECK_NEAR(la[pass * 6 + (pass % 2 ? 5 - i : i)], want, 1e-9);
                        CHECK_NEAR(tt[pass * 6 + i], 120 * pass, 1e-9);
                }
        plan_free(p);
        rigconf_free(rc);

        /* a fast turntable goes inside instead */
        rc = test_rig(200, 400, 10, 20, 0);
        p = build(rc, sc, NULL);
        CHECK_INT(p->order[0], GN_ROLE_LIGHT_ARM);
        CHECK_INT(p->order[1], GN_ROLE_TURNTABLE);
        CHECK_INT(pose_angles(p, GN_ROLE_LIGHT_ARM, la, 32), 18);
        for (size_t i = 1; i < 18; i++) /* the light arm steps only between passes */
                CHECK(la[i] == la[i - 1] || i % 3 == 0);
        plan_free(p);
        sessconf_free(sc);
        rigconf_free(rc);
}

/* Total travel of role over the image shots, the way the axis goes. */
static double travel(const struct rig_config *rc, const struct plan *p, enum gn_role role,
                     double from, double *longest)
{
        const struct rig_axis_conf *ax = &rc->axes[rigconf_axis_of_role(rc, role)];
        double deg[64], t = 0;
        size_t n = pose_angles(p, role, deg, 64);

        *longest = 0;
        for (size_t i = 0; i < n; i++) {
                double d = fabs(axis_travel(ax, i ? deg[i - 1] : from, deg[i]));

                t += d;
                *longest = fmax(*longest, d);
        }
        return t;
}

/* The least time to visit the 4 angles deg from 0 with axis ax, of all 24 orders. */
static double best_order(const struct rig_axis_conf *ax, const double *deg)
{
        double best = INFINITY;

        for (int a = 0; a < 4; a++)
                for (int b = 0; b < 4; b++)
                        for (int c = 0; c < 4; c++) {
                                int d = 6 - a - b - c;

                                if (a == b || a == c || b == c || d == a || d == b || d == c)
                                        continue;
                                best = fmin(best, plan_move_time(ax, 0, deg[a]) +
                                                          plan_move_time(ax, deg[a], deg[b]) +
                                                          plan_move_time(ax, deg[b], deg[c]) +
                                                          plan_move_time(ax, deg[c], deg[d]));
                        }
        return best;
}

static void case_shortest(void)
{
        struct rig_config *rc = test_rig(90, 180, 30, 60, 0);
        struct session_conf *sc =
                session(rc, "dataset: d\nsweep: { turntable: [20, 350, 0, 10] }\nlamps: [l1]\n"
                            "cameras: [c1]\n");
        struct gn_pose start = gn_pose_none();
        const struct rig_axis_conf *tt = &rc->axes[0];
        struct plan *p, *naive = NULL;
        double longest, deg[8], shot = 0.010 + 0.030;

        start.deg[GN_ROLE_TURNTABLE] = 0;
        start.deg[GN_ROLE_LIGHT_ARM] = 90; /* at 0 the cameras would hide the lamps */
        p = build(rc, sc, &start);
        check_invariants(rc, p, &start);
        /* from 0: 0, down to 350, then up through 0 to 10 (20 deg, not 340 the other way
         * round) and 20: of all 24 orders the quickest, and never the long way */
        CHECK_INT(pose_angles(p, GN_ROLE_TURNTABLE, deg, 8), 4);
        for (int i = 0; i < 4; i++)
                CHECK_NEAR(deg[i], ((double[]){0, 350, 10, 20})[i], 1e-9);
        CHECK_NEAR(travel(rc, p, GN_ROLE_TURNTABLE, 0, &longest), 40, 1e-9);
        CHECK_NEAR(longest, 20, 1e-9);
        CHECK_NEAR(p->estimate_s, best_order(tt, (double[]){20, 350, 0, 10}) + 0.1 + 4 * shot,
                   1e-9);
        CHECK_NEAR(plan_move_time(tt, 350, 10), plan_move_time(tt, 0, 20), 1e-12);
        CHECK_INT(plan_build_naive(rc, sc, &start, &naive), 0);
        /* the naive estimate is its own (no wrap-around), still above the bound */
        CHECK(naive->lower_bound_s <= naive->estimate_s);
        CHECK(naive->estimate_s > plan_estimate(rc, naive->shots, naive->n_shots, &start));
        CHECK(naive->estimate_s > p->estimate_s);
        plan_free(naive);
        plan_free(p);
        sessconf_free(sc);

        /* a full turn within passes: no move longer than a step, whichever way round */
        sc = session(rc, "dataset: d\nsweep:\n  turntable: { from: 0, to: 360, step: 45 }\n"
                         "  light_arm: [90, 135]\nlamps: [l1]\ncameras: [c1]\n");
        p = build(rc, sc, &start);
        check_invariants(rc, p, &start);
        CHECK_NEAR(travel(rc, p, GN_ROLE_TURNTABLE, 0, &longest), 14 * 45, 1e-9);
        CHECK_NEAR(longest, 45, 1e-9);
        CHECK_INT(p->n_moves, 15); /* 16 poses, the first where the rig starts */
        plan_free(p);
        sessconf_free(sc);
        rigconf_free(rc);
}

/* The skips of p with camera cam (-1: all) whose reason contains text. */
static size_t count_skips(const struct plan *p, int cam, const char *text)
{
        size_t n = 0;

        for (size_t i = 0; i < p->n_skips; i++)
                n += p->skips[i].camera == cam && strstr(p->skips[i].reason, text);
        return n;
}

/* The shots of p of kind with lamps lit at light arm angle la. */
static size_t count_shots(const struct plan *p, enum plan_kind kind, uint32_t lamps, double la)
{
        size_t n = 0;

        for (size_t i = 0; i < p->n_shots; i++)
                n += p->shots[i].kind == kind && p->shots[i].pose.lamps == lamps &&
                     p->shots[i].pose.deg[GN_ROLE_LIGHT_ARM] == la;
        return n;
}

static void case_occlusion(void)
{
        static const char *base = "dataset: d\nsweep:\n  turntable: [0, 180]\n"
                                  "  light_arm: [0, 90, 180]\nlaser: true\n";
        struct rig_config *rc = test_rig(90, 180, 30, 60, 0);
        struct session_conf *sc = session(rc, base);
        struct plan *p = build(rc, sc, NULL);
        char text[256];

        check_invariants(rc, p, NULL);
        /* at light arm 0 each camera hides the lamp behind it, from every camera's image */
        CHECK_INT(count_skips(p, -1, "lamp 'l0' hidden behind camera 'c0' (2.0 deg)"), 2);
        CHECK_INT(count_skips(p, -1, "lamp 'l1' hidden behind camera 'c1' (0.0 deg)"), 2);
        CHECK_INT(count_shots(p, PLAN_IMAGE, 0x1, 0) + count_shots(p, PLAN_IMAGE, 0x2, 0), 0);
        CHECK_INT(count_shots(p, PLAN_LASER, 0, 0), 2); /* the laser is not a lamp */
        /* at 180 lamp l0 shines into camera c0 only */
        CHECK_INT(count_skips(p, 0, "lamp 'l0' shines into camera 'c0'"), 2);
        CHECK_INT(p->n_skips, 6);
        check_seqs(p);
        for (size_t i = 0; i < p->n_shots; i++)
                if (p->shots[i].pose.lamps == 0x1 && p->shots[i].pose.deg[GN_ROLE_LIGHT_ARM] == 180)
                        CHECK_INT(p->shots[i].cameras, 0x2);
        CHECK_INT(count_shots(p, PLAN_IMAGE, 0x1, 90), 2);
        CHECK_INT(p->n_captures, 2 * (2 * 3) + 2 * (4 + 1 + 2));
        plan_free(p);
        sessconf_free(sc);

        /* with camera c0 alone, l0 at 180 lights no camera: the shot is dropped */
        snprintf(text, sizeof(text), "%scameras: [c0]\n", base);
        sc = session(rc, text);
        p = build(rc, sc, NULL);
        CHECK_INT(count_shots(p, PLAN_IMAGE, 0x1, 180), 0);
        CHECK_INT(count_shots(p, PLAN_IMAGE, 0x2, 180), 2);
        plan_free(p);
        sessconf_free(sc);

        /* the session's margin (1 deg) lets l0 (2 deg off c0) through; each kind turns off */
        snprintf(text, sizeof(text), "%socclusion_deg: 1\nskip_glare: false\n", base);
        sc = session(rc, text);
        p = build(rc, sc, NULL);
        CHECK_INT(p->n_skips, 2);
        CHECK_INT(count_skips(p, -1, "lamp 'l1' hidden behind camera 'c1'"), 2);
        plan_free(p);
        sessconf_free(sc);
        snprintf(text, sizeof(text), "%sskip_occluded: false\n", base);
        sc = session(rc, text);
        p = build(rc, sc, NULL);
        CHECK_INT(p->n_skips, 2);
        CHECK_INT(count_skips(p, 0, "shines into"), 2);
        plan_free(p);
        sessconf_free(sc);
        rigconf_free(rc);
}

static void case_geometry(void)
{
        struct rig_config *rc = test_rig(90, 180, 30, 60, 0);
        struct gn_pose pose = gn_pose_none();
        double dir[3], C[3], e = 12 * M_PI / 180;

        pose.deg[GN_ROLE_TURNTABLE] = 90;
        riggeom_lamp_dir_object(rc, 0, &pose, dir); /* the world's +x seen from the object */
        CHECK_NEAR(dir[0], 0, 1e-12);
        CHECK_NEAR(dir[1], -cos(e), 1e-12);
        CHECK_NEAR(dir[2], sin(e), 1e-12);
        pose.deg[GN_ROLE_LIGHT_ARM] = 90;
        riggeom_lamp_dir_object(rc, 0, &pose, dir);
        CHECK_NEAR(dir[0], cos(e), 1e-12);
        CHECK_NEAR(dir[1], 0, 1e-12);
        riggeom_camera_center(&rc->cameras[1], 90, C);
        CHECK_NEAR(C[0], 0, 1e-9);
        CHECK_NEAR(C[1], 600 * cos(40 * M_PI / 180), 1e-9);
        CHECK_NEAR(C[2], 600 * sin(40 * M_PI / 180), 1e-9);
        rigconf_free(rc);
}

/* The light-arm moves of test rig rc: one leg, the backlash's two legs, the way round. */
static void check_move_times(const struct rig_config *rc)
{
        const struct rig_axis_conf *la = &rc->axes[1];
        struct rig_axis_conf tt = rc->axes[0];
        double leg = axis_move_time(30, 30, 60) + 0.1 + 0.035;

        CHECK_NEAR(plan_move_time(la, 60, 90), leg, 1e-12);
        CHECK_NEAR(plan_move_time(la, 90, 90), 0, 0);
        /* against the backlash (2 deg, from below): past the target, then back up */
        CHECK_NEAR(plan_move_time(la, 90, 60),
                   axis_move_time(32, 30, 60) + axis_move_time(2, 30, 60) + 2 * 0.135, 1e-12);
        tt.direction = 1; /* cables: only upwards, the long way */
        CHECK_NEAR(plan_move_time(&tt, 10, 350), axis_move_time(340, 90, 180) + 0.085, 1e-12);
        tt.direction = 0;
        CHECK_NEAR(plan_move_time(&tt, 10, 350), axis_move_time(20, 90, 180) + 0.085, 1e-12);
}

/* Two axes moved into one pose move at once: the longer move counts, with its settle. */
static void check_concurrent(const struct rig_config *rc)
{
        struct plan_shot shots[2] = {{.pose = gn_pose_none(), .cameras = 0x2, .bracket = -1}};
        double shot = 0.010 + 0.030, tt, la;

        shots[0].pose.deg[GN_ROLE_TURNTABLE] = 0;
        shots[0].pose.deg[GN_ROLE_LIGHT_ARM] = 90;
        shots[0].pose.lamps = 0x2;
        shots[1] = shots[0];
        shots[1].pose.deg[GN_ROLE_TURNTABLE] = 90;
        shots[1].pose.deg[GN_ROLE_LIGHT_ARM] = 100;
        shots[1].settle_ms[GN_ROLE_TURNTABLE] = 500;
        tt = plan_move_time(&rc->axes[0], 0, 90) + 0.5;
        la = plan_move_time(&rc->axes[1], 90, 100);
        CHECK(tt > la);
        CHECK_NEAR(plan_estimate(rc, shots, 2, NULL), 0.1 + 2 * shot + tt, 1e-12);
        shots[1].settle_ms[GN_ROLE_TURNTABLE] = 0;
        shots[1].pose.deg[GN_ROLE_LIGHT_ARM] = 170;
        la = plan_move_time(&rc->axes[1], 90, 170);
        CHECK(la > tt - 0.5);
        CHECK_NEAR(plan_estimate(rc, shots, 2, NULL), 0.1 + 2 * shot + la, 1e-12);
}

static void case_estimate(void)
{
        struct rig_config *rc = test_rig(90, 180, 30, 60, 2);
        struct session_conf *sc =
                session(rc, "dataset: d\nsweep: { light_arm: [90, 120, 60] }\nlamps: [l1]\n"
                            "cameras: [c1]\n");
        const struct rig_axis_conf *la = &rc->axes[1];
        struct gn_pose start = gn_pose_none();
        double shot = 0.010 + 0.030, want;
        struct plan *p;

        check_move_times(rc);
        /* start unknown: up from the lowest, the first move free, the lamp warms up once */
        p = build(rc, sc, NULL);
        check_invariants(rc, p, NULL);
        CHECK_INT(p->n_shots, 3);
        CHECK_NEAR(p->shots[0].pose.deg[GN_ROLE_LIGHT_ARM], 60, 0);
        want = plan_move_time(la, 60, 90) + plan_move_time(la, 90, 120) + 0.1 + 3 * shot;
        CHECK_NEAR(p->estimate_s, want, 1e-9);
        CHECK_NEAR(p->shots[1].t_start_s, 0.1 + shot, 1e-9);
        CHECK_NEAR(p->shots[2].t_start_s, want - shot - plan_move_time(la, 90, 120), 1e-9);
        plan_free(p);
        /* from 130: down is against the backlash, so from 120 up still pays once to get to 60 */
        start.deg[GN_ROLE_LIGHT_ARM] = 130;
        p = build(rc, sc, &start);
        check_invariants(rc, p, &start);
        want = fmin(plan_move_time(la, 130, 60) + plan_move_time(la, 60, 90) +
                            plan_move_time(la, 90, 120),
                    plan_move_time(la, 130, 120) + plan_move_time(la, 120, 90) +
                            plan_move_time(la, 90, 60));
        CHECK_NEAR(p->estimate_s, want + 0.1 + 3 * shot, 1e-9);
        /* the bound: the least step (30 deg) twice, one leg each, plus the way to 120 */
        CHECK_NEAR(p->lower_bound_s,
                   3 * shot + 2 * (axis_move_time(30, 30, 60) + 0.135) +
                           axis_move_time(10, 30, 60) + 0.135,
                   1e-9);
        plan_free(p);
        sessconf_free(sc);
        check_concurrent(rc);
        rigconf_free(rc);
}

/* a and b have the same shots. */
static void check_same(const struct plan *a, const struct plan *b)
{
        CHECK_INT(a->n_shots, b->n_shots);
        for (size_t i = 0; i < a->n_shots; i++) {
                const struct plan_shot *x = &a->shots[i], *y = &b->shots[i];

                CHECK(same_angles(&x->pose, &y->pose));
                CHECK(x->pose.lamps == y->pose.lamps && x->pose.lasers == y->pose.lasers);
                CHECK(x->seq == y->seq && x->cameras == y->cameras && x->bracket == y->bracket);
                CHECK(x->kind == y->kind && x->t_start_s == y->t_start_s);
        }
}

/* The paper's capture: the plan beats the naive order and both are above the bound. */
static void case_paper(void)
{
        struct rig_config *rc = rig_load(paper_rig_path);
        struct session_conf *sc = NULL;
        struct plan *p, *naive = NULL, *again;
        char err[512];

        CHECK_INT(sessconf_load(paper_path, rc, &sc, err, sizeof(err)), 0);
        p = build(rc, sc, NULL);
        CHECK_INT(plan_build_naive(rc, sc, NULL, &naive), 0);
        check_invariants(rc, p, NULL);
        CHECK(naive->lower_bound_s <= naive->estimate_s);
        CHECK_INT(naive->n_captures, p->n_captures);
        CHECK_INT(naive->n_skips, p->n_skips);
        CHECK(p->n_skips > 0);
        CHECK(p->estimate_s < naive->estimate_s);
        CHECK_INT(p->n_moves, 400);
        check_seqs(p);
        check_same(p, again = build(rc, sc, NULL)); /* deterministic */
        plan_free(again);
        plan_free(naive);
        plan_free(p);
        sessconf_free(sc);
        rigconf_free(rc);
}

/* laser: each on the Ciclop rig (beside SIM-RIG): at each of 3 poses the unlit frame and one
 * laser frame per laser with that laser alone on, the three consecutive; the warm-up of a
 * laser switched on counts in the estimate. */
static void case_lasers(void)
{
        const char *slash = strrchr(sim_rig_path, '/');
        char path[4096];
        struct rig_config *rc;
        struct session_conf *sc;
        struct plan *p;

        snprintf(path, sizeof(path), "%.*s/ciclop.yaml", (int)(slash ? slash - sim_rig_path : 1),
                 slash ? sim_rig_path : ".");
        rc = rig_load(path);
        sc = session(rc, "dataset: d\nsweep: { turntable: [0, 90, 180] }\nlamps: []\n"
                         "laser: each\nunlit: true\n");
        p = build(rc, sc, NULL);
        check_invariants(rc, p, NULL);
        CHECK_INT(p->n_shots, 3 * 3);
        for (size_t i = 0; i < p->n_shots; i += 3) {
                uint32_t seen = 0;

                for (size_t k = i; k < i + 3; k++) {
                        const struct plan_shot *x = &p->shots[k];

                        CHECK(x->pose.deg[GN_ROLE_TURNTABLE] == p->shots[i].pose.deg[0]);
                        CHECK_INT(x->kind, x->pose.lasers ? PLAN_LASER : PLAN_IMAGE);
                        CHECK(x->pose.lasers == 0 || x->pose.lasers == 1 || x->pose.lasers == 2);
                        CHECK(!(seen & (1u << x->pose.lasers)));
                        seen |= 1u << x->pose.lasers;
                }
                CHECK_INT(seen, 0x7); /* unlit, left alone, right alone */
        }
        plan_free(p);
        sessconf_free(sc);
        rigconf_free(rc);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"expansion", case_expansion},   {"innermost", case_innermost},
                {"serpentine", case_serpentine}, {"shortest", case_shortest},
                {"occlusion", case_occlusion},   {"geometry", case_geometry},
                {"estimate", case_estimate},     {"paper", case_paper},
                {"lasers", case_lasers},
        };

        if (argc < 5) {
                fprintf(stderr, "usage: %s SIM-RIG DEMO PAPER-RIG PAPER [CASE]\n", argv[0]);
                return 1;
        }
        sim_rig_path = argv[1];
        demo_path = argv[2];
        paper_rig_path = argv[3];
        paper_path = argv[4];
        return TEST_RUN_CASES(cases, argc - 4, argv + 4);
}
