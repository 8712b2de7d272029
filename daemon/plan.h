/* plan.h - the capture plan of a session: the session file (common/sessconf.h) expanded
 * into shots in the order that takes the least time on the rig, with the (lamp, camera,
 * pose) combinations that cannot give a good image skipped, and its duration from the
 * rig's timing model (docs/sessions.md, "Planning").
 *
 * Pure functions of the rig config and the session config: no I/O, no clock, no device.
 * Deterministic: the same rig, session and start pose give the same plan, seqs included,
 * so a session that keeps the three (the rig and session files' text, the pose it started
 * from) rebuilds its plan on resume.
 * gonioctl session plan prints a plan; the session runner (daemon/session.c) executes its
 * shots in order and re-estimates what remains with plan_estimate(). */
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "common/pose.h"
#include "common/rigconf.h"
#include "common/sessconf.h"

enum plan_kind { PLAN_IMAGE, PLAN_DARK, PLAN_FLAT, PLAN_LASER };

/* Most shots of one plan (about 100 MB of them). */
#define PLAN_MAX_SHOTS 1000000

/* One exposure of several cameras at once. */
struct plan_shot {
        /* target angles by role (NAN: that axis is not moved, or the rig has none), the lamps
         * lit (bits by rig lamp index), the laser */
        struct gn_pose pose;
        enum plan_kind kind;
        uint32_t cameras; /* bit i: rig camera i exposed in this shot */
        /* base exposure (0: each camera's default) and gain (0: each camera's default); camera
         * c exposes sessconf_exposure_us(c, exposure_us, ev) (plan_shot_exposure_us()) */
        int exposure_us;
        double gain;
        int bracket; /* index into the session's bracket_ev, -1: none (laser, flats, and the
                      * darks that go with them when no bracket is 0 EV) */
        double ev;   /* the bracket's EV, 0 with no bracket */
        /* seq of its first camera; the k-th set bit of cameras gets seq + k; seqs start at 1
         * and are dense over the plan */
        int64_t seq;
        /* estimated start, from the session start: the moment the shot's move (if any) is
         * commanded, after the previous shot's last frame is read out */
        double t_start_s;
        int settle_ms[GN_ROLE_COUNT]; /* extra settle after moving that role to this pose
                                       * (the session's settle_ms) */
};

/* A combination the plan leaves out. */
struct plan_skip {
        struct gn_pose pose; /* the angles, with the lamp lit */
        int camera;          /* the rig camera whose image is skipped; -1: every camera (the
                              * lamp's light does not reach the object) */
        int lamp;
        char reason[96];
};

struct plan {
        struct plan_shot *shots;
        size_t n_shots;
        size_t n_captures;    /* images = sum over shots of cameras */
        size_t n_moves;       /* pose changes (axes moved together) */
        double estimate_s;    /* timing model */
        double lower_bound_s; /* unavoidable motion + exposure (docs/sessions.md) */
        struct plan_skip *skips;
        size_t n_skips;
        int order[GN_ROLE_COUNT]; /* swept roles, outermost loop first */
        int n_order;
};

/* Plans session sc on rig rc (sc must have been loaded against rc) with the rig at start
 * (NULL or NAN angles: unknown, the first move of that axis costs nothing in the estimate;
 * the angles of unswept roles place the arms for the occlusion checks, 0 where unknown).
 * Darks and flats come first; at each pose, for each lamp, for each bracket one shot of all
 * cameras, then a laser shot (the light order reversed where that keeps the lit lamp lit);
 * the mechanical loops nested in the order, of all, that gives the least estimate,
 * serpentine, continuous axes the shortest way round. Returns 0 and *ret (free with
 * plan_free()), -EINVAL for bad arguments (sc not of rc), -E2BIG when the session would
 * take more than PLAN_MAX_SHOTS shots, or -ENOMEM. */
int plan_build(const struct rig_config *rc, const struct session_conf *sc,
               const struct gn_pose *start, struct plan **ret);

/* The bench's reference: the same captures (and skips) in nested loops in rig order (axes as
 * listed in the rig file, outermost first, angles in file order; then lamps, brackets and
 * cameras, one camera per shot), no serpentine, and moves estimated as a controller without
 * wrap-around would make them (continuous axes travel target - position, never the short
 * way). Returns like plan_build(). */
int plan_build_naive(const struct rig_config *rc, const struct session_conf *sc,
                     const struct gn_pose *start, struct plan **ret);

/* The shot of p that takes capture seq, with the rig camera that takes it in *camera (may
 * be NULL); NULL when p has no such capture. O(log shots). */
const struct plan_shot *plan_find_seq(const struct plan *p, int64_t seq, int *camera);

/* Frees a plan; NULL is a no-op. Returns NULL. */
struct plan *plan_free(struct plan *p);

/* Seconds for axis ax to move from from_deg to to_deg and be ready: for each leg (one, or
 * two when the backlash take-up applies), the trapezoidal profile time of its travel (the
 * way the axis's direction rules choose, axis_travel()), its settle_ms and its
 * move_overhead_ms. 0 when it does not move. */
double plan_move_time(const struct rig_axis_conf *ax, double from_deg, double to_deg);

/* Seconds the n shots take on rc from start (as plan_build() takes it): for each shot, the
 * move of its axes (concurrent: the longest, with its settle_ms), the warm-up of the lamps it
 * switches on (and of the laser), and its exposure (plan_shot_time()). The runner uses it for
 * the time left. */
double plan_estimate(const struct rig_config *rc, const struct plan_shot *shots, size_t n,
                     const struct gn_pose *start);

/* The exposure in µs of camera cam of rc in shot s. */
int plan_shot_exposure_us(const struct rig_config *rc, const struct plan_shot *s, int cam);

/* The gain of camera cam of rc in shot s. */
double plan_shot_gain(const struct rig_config *rc, const struct plan_shot *s, int cam);

/* Seconds shot s exposes: the longest exposure + readout_ms over its cameras. */
double plan_shot_time(const struct rig_config *rc, const struct plan_shot *s);
