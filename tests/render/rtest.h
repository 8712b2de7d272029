/* rtest.h - helpers for the renderer's tests: a rig file from YAML pieces, pixel access. */
#pragma once

#include "common/rigconf.h"
#include "sim/render/render.h"
#include "tests/test.h"

struct rtest {
        struct rig_config *rc;
        struct sim_scene *s;
        char path[64];
};

/* Writes a rig file made of a fixed header (a relay bus and a frame bus), then lamps,
 * laser, cameras and scene YAML as given (each a complete top-level section or ""),
 * loads it and builds the scene. Exits the test on failure. */
void rt_open(struct rtest *t, const char *lamps, const char *laser, const char *cameras,
             const char *scene);

/* Like rt_open but returns the error of sim_scene_new (or rigconf_load) with its message. */
int rt_try_open(struct rtest *t, const char *lamps, const char *laser, const char *cameras,
                const char *scene, char *err, size_t errlen);

void rt_close(struct rtest *t);

/* Renders camera 0; exits the test on failure. */
void rt_render(struct rtest *t, const struct gn_pose *st, const struct sim_expose *ex, uint64_t seq,
               struct gn_frame *f, unsigned flags, struct sim_truth *truth);

/* Sample (x, y, ch) of a frame as a number. */
double rt_px(const struct gn_frame *f, int x, int y, int ch);

/* Writes a PNG of f when $RTEST_DUMP names a directory (for looking at failures). */
void rt_dump(const struct gn_frame *f, const char *name);
