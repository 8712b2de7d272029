/* test-sessconf.c - the session file loader: the example sessions load with the values
 * written in them, defaults are filled in, ranges expand as documented, and each mistake an
 * operator makes is refused with file, line and key (unknown camera or lamp, a sweep outside
 * an axis's soft limits or of a role the rig has no axis for, a missing dataset, a negative
 * exposure, bad brackets, unknown keys...); the `laser` key on a two-laser rig (the Ciclop
 * example beside SIM-RIG): false, true, all, each, a name, a list, and its mistakes.
 * Usage: test-sessconf SIM-RIG PAPER-RIG DEMO-SESSION PAPER-SESSION CASE; an unknown CASE
 * fails. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>

#include "common/cleanup.h"
#include "common/sessconf.h"
#include "drivers/registry.h"
#include "tests/test.h"

static const char *sim_rig_path, *paper_rig_path, *demo_path, *paper_path;
static struct rig_config *sim_rig, *paper_rig;

/* The path error messages name. */
#define FILE_NAME "/tmp/s.yaml"

static struct rig_config *load_rig(const char *path)
{
        struct rig_config *rc = NULL;
        char err[512];
        int r = rigconf_load(path, registry_backends, &rc, err, sizeof(err));

        if (r < 0)
                fprintf(stderr, "%s\n", err);
        CHECK_INT(r, 0);
        return rc;
}

/* Parses text against rc and expects success. Free with sessconf_free. */
static struct session_conf *expect_ok(const struct rig_config *rc, const char *text)
{
        struct session_conf *sc = NULL;
        char err[512] = "";
        int r = sessconf_load_string(FILE_NAME, text, rc, &sc, err, sizeof(err));

        if (r < 0)
                fprintf(stderr, "for:\n%s\ngot %d: %s\n", text, r, err);
        CHECK_INT(r, 0);
        return sc;
}

/* Expects the parse to fail with "FILE:LINE: key 'KEY': " followed by text containing msg. */
static void expect_at(const struct rig_config *rc, const char *text, int line, const char *key,
                      const char *msg)
{
        struct session_conf *sc = NULL;
        char err[512] = "", want[128];
        int r = sessconf_load_string(FILE_NAME, text, rc, &sc, err, sizeof(err));

        snprintf(want, sizeof(want), "%s:%d: key '%s': ", FILE_NAME, line, key);
        if (r != -EINVAL || strncmp(err, want, strlen(want)) != 0 || !strstr(err, msg))
                fprintf(stderr, "for:\n%s\nwant %s...%s\ngot %d: %s\n", text, want, msg, r, err);
        CHECK_INT(r, -EINVAL);
        CHECK(strncmp(err, want, strlen(want)) == 0);
        CHECK_STR_CONTAINS(err, msg);
        CHECK(sc == NULL);
}

static void check_sweep(const struct session_conf *sc, enum gn_role role, const double *deg,
                        size_t n)
{
        CHECK_INT(sc->sweep[role].n, n);
        for (size_t i = 0; i < n; i++)
                CHECK_NEAR(sc->sweep[role].deg[i], deg[i], 1e-9);
}

static void case_examples(void)
{
        struct session_conf *sc = NULL;
        char err[512];

        CHECK_INT(sessconf_load(demo_path, sim_rig, &sc, err, sizeof(err)), 0);
        CHECK_STR(sc->name, "demo");
        CHECK_STR(sc->dataset, "demo");
        check_sweep(sc, GN_ROLE_TURNTABLE, (double[]){0, 90, 180, 270}, 4);
        check_sweep(sc, GN_ROLE_LIGHT_ARM, (double[]){0, 90}, 2);
        CHECK_INT(sc->sweep[GN_ROLE_CAMERA_ARM].n, 0);
        CHECK_INT(sc->cameras, 0x3);
        CHECK_INT(sc->lamps, 0xf);
        CHECK(sc->n_laser_shots == 1 && sc->laser_shots[0] == 1);
        CHECK_INT(sc->dark_frames, 1);
        CHECK_INT(sc->settle_ms[GN_ROLE_TURNTABLE], 20);
        CHECK_STR(sc->metadata_json, "{\"purpose\": \"demo\"}");
        CHECK_STR_CONTAINS(sc->text, "dataset: demo");
        sessconf_free(sc);

        CHECK_INT(sessconf_load(paper_path, paper_rig, &sc, err, sizeof(err)), 0);
        CHECK_INT(sc->sweep[GN_ROLE_TURNTABLE].n, 20); /* a full turn: 360 is 0 */
        CHECK_NEAR(sc->sweep[GN_ROLE_TURNTABLE].deg[19], 342, 1e-9);
        CHECK_INT(sc->sweep[GN_ROLE_LIGHT_ARM].n, 20);
        CHECK_NEAR(sc->sweep[GN_ROLE_LIGHT_ARM].deg[0], -180, 1e-9);
        CHECK_INT(sc->cameras, 0x1f);
        CHECK_INT(sc->lamps, 0xff);
        CHECK_INT(sc->exposure_us, 33000);
        sessconf_free(sc);

        CHECK_INT(sessconf_load("/nonexistent/s.yaml", sim_rig, &sc, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, "/nonexistent/s.yaml: ");
}

static void case_defaults(void)
{
        struct session_conf *sc = expect_ok(sim_rig, "dataset: d\n");

        CHECK_STR(sc->name, "s"); /* the file's basename without .yaml */
        CHECK_INT(sc->cameras, 0x3);
        CHECK_INT(sc->lamps, 0xf);
        CHECK_INT(sc->flat_lamps, 0xf);
        for (int r = 0; r < GN_ROLE_COUNT; r++) {
                CHECK_INT(sc->sweep[r].n, 0);
                CHECK_INT(sc->settle_ms[r], 0);
        }
        CHECK_INT(sc->exposure_us, 0);
        CHECK_NEAR(sc->gain, 0, 0);
        CHECK_INT(sc->n_brackets, 1);
        CHECK_NEAR(sc->bracket_ev[0], 0, 0);
        CHECK(!sc->n_laser_shots && !sc->unlit);
        CHECK_INT(sc->dark_frames, 0);
        CHECK_INT(sc->dark_max_age_s, 86400);
        CHECK_INT(sc->flat_frames, 0);
        CHECK(sc->skip_occluded && sc->skip_glare);
        CHECK_NEAR(sc->occlusion_deg, 0, 0);
        CHECK_STR(sc->metadata_json, "{}");
        sessconf_free(sc);

        sc = expect_ok(sim_rig, "name: n1\ndataset: d\ncameras: [cam1]\nlamps: [lamp2]\n"
                                "flat_frames: 2\nbrackets: [-1, 0, 2]\nexposure_us: 1000\n"
                                "gain: 2\nskip_glare: no\nlaser: yes\nunlit: true\n");
        CHECK_STR(sc->name, "n1");
        CHECK(sc->unlit);
        CHECK_INT(sc->cameras, 0x2);
        CHECK_INT(sc->lamps, 0x4);
        CHECK_INT(sc->flat_lamps, 0x4); /* the session's lamps */
        CHECK_INT(sc->n_brackets, 3);
        CHECK_NEAR(sc->bracket_ev[2], 2, 0);
        CHECK_INT(sessconf_exposure_us(&sim_rig->cameras[1], sc->exposure_us, 2), 4000);
        CHECK_INT(sessconf_exposure_us(&sim_rig->cameras[1], 0, -1), 10000); /* 20000 / 2 */
        CHECK(sc->skip_occluded && !sc->skip_glare);
        sessconf_free(sc);
}

static void case_ranges(void)
{
        static const struct {
                const char *sweep; /* the value of sweep.ROLE */
                enum gn_role role;
                double deg[8];
                size_t n;
        } rows[] = {
                {"{ from: 0, to: 360, step: 90 }", GN_ROLE_TURNTABLE, {0, 90, 180, 270}, 4},
                {"{ from: 350, to: 370, step: 10 }", GN_ROLE_TURNTABLE, {350, 0, 10}, 3},
                {"{ from: -90, to: 0, step: 45 }", GN_ROLE_TURNTABLE, {270, 315, 0}, 3},
                {"{ from: 90, to: 0, step: 45 }", GN_ROLE_CAMERA_ARM, {90, 45, 0}, 3},
                {"{ from: 0, to: 100, step: 30 }", GN_ROLE_CAMERA_ARM, {0, 30, 60, 90}, 4},
                {"[-170, 170, 0]", GN_ROLE_CAMERA_ARM, {-170, 170, 0}, 3},
                {"[720.5]", GN_ROLE_LIGHT_ARM, {0.5}, 1},
                {"45", GN_ROLE_LIGHT_ARM, {45}, 1},
        };
        char text[256];

        for (size_t i = 0; i < ELEMENTSOF(rows); i++) {
                struct session_conf *sc;

                snprintf(text, sizeof(text), "dataset: d\nsweep:\n  %s: %s\n",
                         gn_role_name(rows[i].role), rows[i].sweep);
                sc = expect_ok(sim_rig, text);
                check_sweep(sc, rows[i].role, rows[i].deg, rows[i].n);
                sessconf_free(sc);
        }
}

/* Each operator mistake: the file, the line, the key and what is wrong. */
static const struct {
        const char *text;
        int line;
        const char *key, *msg;
        bool paper; /* against the paper's rig (no camera arm) */
} mistakes[] = {
        {"dataset: d\ncameras: [cam0, cam9]\n", 2, "cameras",
         "unknown camera 'cam9' (rig 'sim-furukawa' has: cam0, cam1)"},
        {"dataset: d\ncameras:\n  - cam0\n  - cam0\n", 4, "cameras", "'cam0' is listed twice"},
        {"dataset: d\ncameras: []\n", 2, "cameras", "no camera"},
        {"dataset: d\nlamps: [lamp0, lamp7]\n", 2, "lamps", "unknown lamp 'lamp7'"},
        {"dataset: d\nlamps: []\n", 2, "lamps", "nothing to capture"},
        {"dataset: d\nlamps: []\nunlit: 3\n", 3, "unlit", ""},
        {"dataset: d\nflat_lamps: [bulb]\n", 2, "flat_lamps", "unknown lamp 'bulb'"},
        {"dataset: d\nsweep:\n  camera_arm: [0, 45,\n    200]\n", 4, "sweep.camera_arm",
         "200 deg is outside the soft limits [-170, 170] of axis 'camera_arm'"},
        {"dataset: d\nsweep:\n  camera_arm:\n    from: 0\n    to: 180\n    step: 90\n", 5,
         "sweep.camera_arm", "180 deg is outside the soft limits"},
        {"dataset: d\nsweep:\n  camera_arm: [10]\n", 3, "sweep.camera_arm",
         "rig 'furukawa-2006' has no axis of role 'camera_arm'", true},
        {"dataset: d\nsweep:\n  tilt: [10]\n", 3, "sweep.tilt", "unknown key"},
        {"dataset: d\nsweep:\n  turntable: [0, 360]\n", 3, "sweep.turntable",
         "angle 0 deg is listed twice (angles are taken modulo 360)"},
        {"dataset: d\nsweep:\n  turntable: []\n", 3, "sweep.turntable", "an empty sweep"},
        {"dataset: d\nsweep:\n  turntable: { from: 0, to: 90, step: 0 }\n", 3, "sweep.turntable",
         "step must be > 0"},
        {"dataset: d\nsweep:\n  turntable: { from: 0, step: 5 }\n", 3, "sweep.turntable",
         "'to' is missing"},
        {"dataset: d\nsweep:\n  turntable: { from: 0, to: 1, step: 1, by: 2 }\n", 3, "by",
         "unknown key"},
        {"dataset: d\nsweep:\n  turntable: [0, ten]\n", 3, "sweep.turntable",
         "'ten' is not a number"},
        {"dataset: d\nsweep: [0]\n", 2, "sweep", "expected a mapping"},
        {"name: n\nlamps: all\n", 1, "dataset", "required key is missing"},
        {"dataset: a/b\n", 1, "dataset", "may not contain '/'"},
        {"name: ''\ndataset: d\n", 1, "name", "must not be empty"},
        {"dataset: d\nexposure_us: -5\n", 2, "exposure_us", "cannot be negative"},
        {"dataset: d\nexposure_us: 20000000\n", 2, "exposure_us", "longer than"},
        {"dataset: d\nexposure_us: 1.5\n", 2, "exposure_us", "not an integer"},
        {"dataset: d\ngain: 100\n", 2, "gain", "out of range"},
        {"dataset: d\nbrackets: [0, 1, 0]\n", 2, "brackets", "+0 EV is listed twice"},
        {"dataset: d\nbrackets: [12]\n", 2, "brackets", "out of range"},
        {"dataset: d\nbrackets: []\n", 2, "brackets", "expected 1 to 8 EVs"},
        {"dataset: d\nbrackets: [0, 1, 2, 3, 4, 5, 6, 7, 8]\n", 2, "brackets",
         "expected 1 to 8 EVs"},
        {"dataset: d\nexposure_us: 6000000\nbrackets:\n  - 0\n  - 1\n", 5, "brackets",
         "+1 EV gives camera 'cam0' an exposure of 12000000 us"},
        {"dataset: d\nbrackets: [-15]\n", 2, "brackets", "out of range"},
        {"dataset: d\nexpsoure_us: 100\n", 2, "expsoure_us", "unknown key"},
        {"dataset: d\ndark_frames: -1\n", 2, "dark_frames", "out of range"},
        {"dataset: d\nsettle_ms: { camera_arm: 5 }\n", 2, "settle_ms.camera_arm",
         "has no axis of role 'camera_arm'", true},
        {"dataset: d\nsettle_ms: { turntable: -5 }\n", 2, "settle_ms.turntable", "whole ms"},
        {"dataset: d\nsettle_ms: { spin: 5 }\n", 2, "settle_ms.spin", "unknown key"},
        {"dataset: d\nmetadata: [1, 2]\n", 2, "metadata", "expected a mapping"},
        {"dataset: d\nskip_glare: maybe\n", 2, "skip_glare", "not a boolean"},
        {"dataset: d\noccluson_deg: 3\n", 2, "occluson_deg", "unknown key"},
        {"---\n", 0, "(root)", "the session file is empty"},
        {" \n", 0, "(root)", "the session file is empty"},
        {"- dataset: d\n", 1, "(root)", "expected a mapping"},
};

static void case_mistakes(void)
{
        struct session_conf *sc = NULL;
        char err[512];

        for (size_t i = 0; i < ELEMENTSOF(mistakes); i++)
                expect_at(mistakes[i].paper ? paper_rig : sim_rig, mistakes[i].text,
                          mistakes[i].line, mistakes[i].key, mistakes[i].msg);
        CHECK_INT(sessconf_load_string(FILE_NAME, "dataset: [d\n", sim_rig, &sc, err, sizeof(err)),
                  -EINVAL);
        CHECK_STR_CONTAINS(err, FILE_NAME ":");
        CHECK_STR_CONTAINS(err, "YAML syntax error");
}

static void case_metadata(void)
{
        struct session_conf *sc = expect_ok(
                sim_rig, "dataset: d\nmetadata:\n  object: bronze mirror\n"
                         "  year: 2006\n  tags: [a, 'b c']\n  note: \"say \\\"hi\\\"\"\n");

        CHECK_STR(sc->metadata_json, "{\"object\": \"bronze mirror\", \"year\": 2006, \"tags\": "
                                     "[\"a\", \"b c\"], \"note\": \"say \\\"hi\\\"\"}");
        sessconf_free(sc);
}

/* The laser shots of `laser: value` on rig rc, as a bit set per shot in want (n of them). */
static void expect_shots(const struct rig_config *rc, const char *value, const uint32_t *want,
                         size_t n)
{
        char text[256];
        struct session_conf *sc;

        snprintf(text, sizeof(text), "dataset: d\nlamps: []\nunlit: true\nlaser: %s\n", value);
        sc = expect_ok(rc, text);
        if (sc->n_laser_shots != n)
                fprintf(stderr, "laser: %s: %zu shots, want %zu\n", value, sc->n_laser_shots, n);
        CHECK_INT(sc->n_laser_shots, n);
        for (size_t i = 0; i < n; i++)
                CHECK_INT(sc->laser_shots[i], want[i]);
        sessconf_free(sc);
}

static void case_lasers(void)
{
        char path[4096];
        const char *slash = strrchr(sim_rig_path, '/');
        struct rig_config *ciclop;

        snprintf(path, sizeof(path), "%.*s/ciclop.yaml", (int)(slash ? slash - sim_rig_path : 1),
                 slash ? sim_rig_path : ".");
        ciclop = load_rig(path);
        CHECK_INT(ciclop->n_lasers, 2);
        expect_shots(ciclop, "false", NULL, 0);
        expect_shots(ciclop, "true", (uint32_t[]){3}, 1);
        expect_shots(ciclop, "all", (uint32_t[]){3}, 1);
        expect_shots(ciclop, "each", (uint32_t[]){1, 2}, 2);
        expect_shots(ciclop, "laser_right", (uint32_t[]){2}, 1);
        expect_shots(ciclop, "[laser_right, laser_left]", (uint32_t[]){3}, 1);
        expect_shots(ciclop, "[]", NULL, 0);
        expect_shots(sim_rig, "each", (uint32_t[]){1}, 1); /* one laser: as true */
        expect_at(ciclop, "dataset: d\nlaser: laser_middle\n", 2, "laser",
                  "unknown laser 'laser_middle' (rig 'ciclop' has: laser_left, laser_right)");
        expect_at(ciclop, "dataset: d\nlaser: [laser_left, laser_left]\n", 2, "laser",
                  "laser 'laser_left' is listed twice");
        expect_at(ciclop, "dataset: d\nlaser: { each: true }\n", 2, "laser", "expected a list");
        rigconf_free(ciclop);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"examples", case_examples}, {"defaults", case_defaults}, {"ranges", case_ranges},
                {"mistakes", case_mistakes}, {"metadata", case_metadata}, {"lasers", case_lasers},
        };
        int r;

        if (argc < 5) {
                fprintf(stderr, "usage: %s SIM-RIG PAPER-RIG DEMO PAPER [CASE]\n", argv[0]);
                return 1;
        }
        sim_rig_path = argv[1];
        paper_rig_path = argv[2];
        demo_path = argv[3];
        paper_path = argv[4];
        sim_rig = load_rig(sim_rig_path);
        paper_rig = load_rig(paper_rig_path);
        r = TEST_RUN_CASES(cases, argc - 4, argv + 4);
        rigconf_free(sim_rig);
        rigconf_free(paper_rig);
        return r;
}
