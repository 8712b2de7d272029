/* plan.c - the capture plan of a session (see plan.h, docs/sessions.md "Planning").
 *
 * DESIGN
 * A plan is built in one pass over nested loops: calibration shots first (darks at each
 * exposure the session uses, then flats), then the mechanical loops, one per swept role,
 * and at each pose the lights (each lamp, then the laser), each light with its brackets.
 * Lamps and brackets cost milliseconds, moves up to seconds, so they are innermost.
 *
 * Each mechanical loop picks, every time it starts a pass, the way through its angles that
 * costs least from where its axis is (best_way()): the cycle of its sorted angles cut at
 * one gap into a line, entered at one angle, followed one way to the end, then back past
 * the entry to the other end. Entered at an end that is a plain pass: on a limited axis
 * the cheap ones go up or down, so passes alternate (serpentine); on a continuous axis a
 * full circle can as well go on round. The step costs are summed per role once (struct
 * loop), so a way costs O(1) to price and a pass O(n^2) ways (O(n) beyond PLAN_ZIGZAG_MAX
 * angles). The nesting order is decided by building the plan for every order of the swept
 * roles (at most 6) and keeping the one of least estimate: the estimate is the truth the
 * choice is judged by.
 *
 * The timing model (estimate()) follows the rig along the shot list; the lower bound
 * (exposure_bound() + transition_bound()) is what any order of the same captures must take
 * in that model. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "common/riggeom.h"
#include "drivers/axis/axis.h"
#include "plan.h"

/* Two angles closer than this (degrees) are one. */
#define PLAN_ANGLE_EPS 1e-6
/* The lights of a shot (struct builder.light): >= 0 a lamp, LIGHT_NONE nothing lit,
 * LIGHT_LASER(i) the session's laser shot i (session_conf.laser_shots). */
#define LIGHT_NONE        (-1)
#define LIGHT_LASER(i)    (-2 - (int)(i))
#define LIGHT_LASER_OF(l) (-2 - (l))

/* ---- timing model ---- */

/* One leg of a move: profile time, settle and the command/poll overhead. */
static double leg_time(const struct rig_axis_conf *ax, double from, double to)
{
        return axis_move_time(axis_travel(ax, from, to), ax->max_speed, ax->accel) +
               (ax->settle_ms + ax->move_overhead_ms) / 1000.0;
}

double plan_move_time(const struct rig_axis_conf *ax, double from_deg, double to_deg)
{
        double mid;

        if (!ax || fabs(axis_travel(ax, from_deg, to_deg)) < PLAN_ANGLE_EPS)
                return 0;
        mid = axis_takeup_target(ax, from_deg, to_deg);
        if (mid == to_deg)
                return leg_time(ax, from_deg, to_deg);
        return leg_time(ax, from_deg, mid) + leg_time(ax, mid, to_deg);
}

/* A move as a controller without wrap-around makes it: target - position in [0, 360). */
static double naive_move_time(const struct rig_axis_conf *ax, double from, double to)
{
        struct rig_axis_conf flat = *ax;

        if (!ax->continuous)
                return plan_move_time(ax, from, to);
        flat.continuous = false;
        return plan_move_time(&flat, fmod(fmod(from, 360) + 360, 360), to);
}

int plan_shot_exposure_us(const struct rig_config *rc, const struct plan_shot *s, int cam)
{
        return sessconf_exposure_us(&rc->cameras[cam], s->exposure_us, s->ev);
}

double plan_shot_gain(const struct rig_config *rc, const struct plan_shot *s, int cam)
{
        return s->gain > 0 ? s->gain : rc->cameras[cam].gain;
}

/* One frame of camera c in shot s: exposure and readout, no shorter than the camera's
 * frame period. */
static double frame_time(const struct rig_config *rc, const struct plan_shot *s, size_t c)
{
        return fmax(plan_shot_exposure_us(rc, s, c) / 1e6 + rc->cameras[c].readout_ms / 1e3,
                    rc->cameras[c].frame_rate > 0 ? 1.0 / rc->cameras[c].frame_rate : 0);
}

double plan_shot_time(const struct rig_config *rc, const struct plan_shot *s)
{
        double t = 0;

        for (size_t c = 0; c < rc->n_cameras; c++)
                if (s->cameras & (1u << c))
                        t = fmax(t, frame_time(rc, s, c));
        return t;
}

/* The rig as the timing model follows it along a shot list. */
struct track {
        double deg[GN_ROLE_COUNT]; /* NAN: unknown */
        uint32_t lamps;
        uint32_t lasers;
};

static struct track track_start(const struct gn_pose *start)
{
        struct track t = {.lamps = start ? start->lamps : 0, .lasers = start ? start->lasers : 0};

        for (int r = 0; r < GN_ROLE_COUNT; r++)
                t.deg[r] = start ? start->deg[r] : NAN;
        return t;
}

/* Seconds to move the axes of st to shot s's pose, all at once (the longest counts, with
 * the session's extra settle of its role); *moved tells whether any axis is commanded. */
static double move_to(const struct rig_config *rc, struct track *st, const struct plan_shot *s,
                      bool naive, bool *moved)
{
        double t = 0;

        *moved = false;
        for (int r = 0; r < GN_ROLE_COUNT; r++) {
                int a = rigconf_axis_of_role(rc, r);
                double m = 0;

                if (a < 0 || isnan(s->pose.deg[r]))
                        continue;
                if (!isnan(st->deg[r]))
                        m = naive ? naive_move_time(&rc->axes[a], st->deg[r], s->pose.deg[r])
                                  : plan_move_time(&rc->axes[a], st->deg[r], s->pose.deg[r]);
                *moved = *moved || m > 0 || isnan(st->deg[r]);
                t = fmax(t, m > 0 ? m + s->settle_ms[r] / 1000.0 : 0);
                st->deg[r] = s->pose.deg[r];
        }
        return t;
}

/* The longest (longest: true) or shortest warm-up in seconds of the switches sw[0..n) in
 * the bit set on; 0 (longest) or INFINITY for none. */
static double warmup(const struct rig_switch_conf *sw, size_t n, uint32_t on, bool longest)
{
        double t = longest ? 0 : INFINITY;

        for (size_t i = 0; i < n; i++)
                if (on & (UINT32_C(1) << i))
                        t = longest ? fmax(t, sw[i].warmup_ms / 1000.0)
                                    : fmin(t, sw[i].warmup_ms / 1000.0);
        return t;
}

/* Seconds for the lights of shot s to be ready: the warm-up of those it switches on. */
static double light_to(const struct rig_config *rc, struct track *st, const struct plan_shot *s)
{
        double t = fmax(warmup(rc->lamps, rc->n_lamps, s->pose.lamps & ~st->lamps, true),
                        warmup(rc->lasers, rc->n_lasers, s->pose.lasers & ~st->lasers, true));

        st->lamps = s->pose.lamps;
        st->lasers = s->pose.lasers;
        return t;
}

/* The timing model over n shots; t_start (NULL: not wanted) gets each shot's start and
 * *moves (NULL: not wanted) the number of pose changes. Returns the total in seconds. */
static double estimate(const struct rig_config *rc, const struct plan_shot *shots, size_t n,
                       const struct gn_pose *start, bool naive, double *t_start, size_t *moves)
{
        struct track st = track_start(start);
        double t = 0;
        bool moved;

        if (moves)
                *moves = 0;
        for (size_t i = 0; i < n; i++) {
                if (t_start)
                        t_start[i] = t;
                t += move_to(rc, &st, &shots[i], naive, &moved);
                t += light_to(rc, &st, &shots[i]) + plan_shot_time(rc, &shots[i]);
                if (moves && moved)
                        (*moves)++;
        }
        return t;
}

double plan_estimate(const struct rig_config *rc, const struct plan_shot *shots, size_t n,
                     const struct gn_pose *start)
{
        if (!rc || (!shots && n))
                return NAN;
        return estimate(rc, shots, n, start, false, NULL, NULL);
}

/* ---- building ---- */

/* One mechanical loop: its role's angles sorted, and the costs of the steps between
 * neighbours on the cycle of sorted angles, summed twice round so that a stretch of it
 * costs one subtraction: up[k] is the cost of the steps from sorted 0 up to sorted k
 * (indices modulo n; from the last the cycle wraps round to the first, a real move on a
 * limited axis too), down[k] that of the same steps taken downwards. */
struct loop {
        size_t n;
        size_t *sorted;    /* indices into the sweep */
        double *up, *down; /* 2n + 1 each */
};

/* A way through a loop's angles for one pass: the cycle of sorted angles cut before sorted
 * index cut into a line, entered at its s-th angle, one way (dir) to the line's end, then
 * back past s to the other end (a plain pass when s is an end). */
struct way {
        size_t cut, s;
        int dir; /* +1: up first, -1: down first */
};

/* Up to this many angles, a pass may start inside the line (O(n^2) choices per pass);
 * beyond, only at its ends. */
#define PLAN_ZIGZAG_MAX 64

struct builder {
        const struct rig_config *rc;
        const struct session_conf *sc;
        bool naive;
        struct gn_pose geo;       /* the arms where a role is not swept: start's, else 0 */
        double at[GN_ROLE_COUNT]; /* the last target of each role, NAN: unknown */
        struct loop loops[GN_ROLE_COUNT];
        int light; /* the light lit last (LIGHT_*, or a lamp) */
        struct plan *p;
        size_t cap_shots, cap_skips;
};

/* Grows *arr (of *cap items of size bytes) to hold n + 1 items. */
static int grow(void **arr, size_t *cap, size_t n, size_t size)
{
        void *a;

        if (n < *cap)
                return 0;
        a = reallocarray(*arr, *cap ? *cap * 2 : 64, size);
        if (!a)
                return -ENOMEM;
        *arr = a;
        *cap = *cap ? *cap * 2 : 64;
        return 0;
}

/* Appends shot s; the naive plan takes one camera per shot. */
static int add_shots(struct builder *b, const struct plan_shot *s)
{
        struct plan *p = b->p;

        for (size_t c = 0; c < b->rc->n_cameras; c++) {
                uint32_t bit = b->naive ? 1u << c : s->cameras;

                if (!(s->cameras & bit))
                        continue;
                if (grow((void **)&p->shots, &b->cap_shots, p->n_shots, sizeof(*s)) < 0)
                        return -ENOMEM;
                p->shots[p->n_shots] = *s;
                p->shots[p->n_shots++].cameras = bit;
                if (!b->naive)
                        break;
        }
        return 0;
}

/* A shot of kind at pose (angles, lights) for cameras with bracket (-1: none). */
static struct plan_shot shot_new(const struct builder *b, enum plan_kind kind,
                                 const struct gn_pose *pose, uint32_t cameras, int bracket)
{
        struct plan_shot s = {.pose = *pose,
                              .kind = kind,
                              .cameras = cameras,
                              .exposure_us = b->sc->exposure_us,
                              .gain = b->sc->gain,
                              .bracket = bracket,
                              .ev = bracket >= 0 ? b->sc->bracket_ev[bracket] : 0};

        memcpy(s.settle_ms, b->sc->settle_ms, sizeof(s.settle_ms));
        return s;
}

/* count frames of kind with lamps lit and no move, at bracket. */
static int add_frames(struct builder *b, enum plan_kind kind, uint32_t lamps, int bracket,
                      int count)
{
        struct gn_pose pose = gn_pose_none();
        struct plan_shot s;
        int r;

        pose.lamps = lamps;
        s = shot_new(b, kind, &pose, b->sc->cameras, bracket);
        for (int i = 0; i < count; i++)
                if ((r = add_shots(b, &s)) < 0)
                        return r;
        return 0;
}

/* Darks at each exposure the session uses (each bracket, and 0 EV for the laser, unlit and
 * flat frames when no bracket is 0 EV), then flats. */
static int add_calibration(struct builder *b)
{
        const struct session_conf *sc = b->sc;
        bool ev0 = false;
        int r;

        for (size_t i = 0; i < sc->n_brackets; i++) {
                ev0 = ev0 || sc->bracket_ev[i] == 0;
                if ((r = add_frames(b, PLAN_DARK, 0, i, sc->dark_frames)) < 0)
                        return r;
        }
        if (!ev0 && (sc->n_laser_shots || sc->unlit || sc->flat_frames) &&
            (r = add_frames(b, PLAN_DARK, 0, -1, sc->dark_frames)) < 0)
                return r;
        return add_frames(b, PLAN_FLAT, sc->flat_lamps, -1, sc->flat_frames);
}

/* Records that pose with lamp lit gives camera (-1: any camera) no image, and why. */
static int add_skip(struct builder *b, const struct gn_pose *pose, int camera, int lamp,
                    const char *fmt, ...) __attribute__((format(printf, 5, 6)));

static int add_skip(struct builder *b, const struct gn_pose *pose, int camera, int lamp,
                    const char *fmt, ...)
{
        struct plan *p = b->p;
        struct plan_skip *k;
        va_list ap;

        if (grow((void **)&p->skips, &b->cap_skips, p->n_skips, sizeof(*k)) < 0)
                return -ENOMEM;
        k = &p->skips[p->n_skips++];
        *k = (struct plan_skip){.pose = *pose, .camera = camera, .lamp = lamp};
        k->pose.lamps = 1u << lamp;
        k->pose.lasers = 0;
        va_start(ap, fmt);
        vsnprintf(k->reason, sizeof(k->reason), fmt, ap);
        va_end(ap);
        return 0;
}

/* The angle of the arm of role at pose: the pose's, else where it stays. */
static double arm(const struct builder *b, const struct gn_pose *pose, enum gn_role role)
{
        return isnan(pose->deg[role]) ? b->geo.deg[role] : pose->deg[role];
}

static double norm3(const double v[3])
{
        return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* The rig camera (any, not only the session's) whose body hides lamp from the object at
 * pose, the one nearest in angle (*deg); -1 if none. */
static int hiding_camera(const struct builder *b, const struct gn_pose *pose, int lamp, double *deg)
{
        const struct rig_config *rc = b->rc;
        double L[3], C[3];
        int who = -1;

        *deg = INFINITY;
        riggeom_lamp_position(&rc->lamps[lamp], arm(b, pose, GN_ROLE_LIGHT_ARM), L);
        for (size_t c = 0; c < rc->n_cameras; c++) {
                double margin = b->sc->occlusion_deg > 0 ? b->sc->occlusion_deg
                                                         : rc->cameras[c].occlusion_deg;
                double a;

                riggeom_camera_center(&rc->cameras[c], arm(b, pose, GN_ROLE_CAMERA_ARM), C);
                a = riggeom_angle_deg(L, C);
                if (a < margin && norm3(L) > norm3(C) && a < *deg) {
                        *deg = a;
                        who = c;
                }
        }
        return who;
}

/* Whether lamp shines into camera cam at pose: in its field of view, behind the object
 * (farther from the camera than its look-at point); *off gets the angle off its axis. */
static bool glares(const struct builder *b, const struct gn_pose *pose, int lamp, int cam,
                   double *off)
{
        const struct rig_camera_conf *c = &b->rc->cameras[cam];
        double L[3], C[3], cl[3], ct[3], ca = arm(b, pose, GN_ROLE_CAMERA_ARM);

        riggeom_lamp_position(&b->rc->lamps[lamp], arm(b, pose, GN_ROLE_LIGHT_ARM), L);
        riggeom_camera_center(c, ca, C);
        for (int i = 0; i < 3; i++) {
                cl[i] = L[i] - C[i];
                ct[i] = c->target[i] - C[i];
        }
        return riggeom_in_view(c, ca, L, off) && norm3(cl) > norm3(ct);
}

/* The session cameras that get a good image with lamp lit at pose, into *mask; each one
 * left out is recorded as a skip. */
static int lamp_cameras(struct builder *b, const struct gn_pose *pose, int lamp, uint32_t *mask)
{
        const struct rig_config *rc = b->rc;
        const char *name = rc->lamps[lamp].name;
        double deg;
        int c, r;

        *mask = b->sc->cameras;
        if (b->sc->skip_occluded && (c = hiding_camera(b, pose, lamp, &deg)) >= 0) {
                *mask = 0;
                return add_skip(b, pose, -1, lamp, "lamp '%s' hidden behind camera '%s' (%.1f deg)",
                                name, rc->cameras[c].name, deg);
        }
        for (c = 0; b->sc->skip_glare && c < (int)rc->n_cameras; c++) {
                if (!(*mask & (1u << c)) || !glares(b, pose, lamp, c, &deg))
                        continue;
                *mask &= ~(1u << c);
                r = add_skip(b, pose, c, lamp,
                             "lamp '%s' shines into camera '%s' (%.1f deg off its axis)", name,
                             rc->cameras[c].name, deg);
                if (r < 0)
                        return r;
        }
        return 0;
}

/* The shots of one light (a lamp, LIGHT_LASER(i), or LIGHT_NONE: the unlit frame) at pose for
 * cameras. The laser and unlit frames are taken once, at 0 EV (bracket -1). */
static int add_light(struct builder *b, const struct gn_pose *pose, int light, uint32_t cameras)
{
        struct gn_pose lit = *pose;
        int r;

        lit.lamps = light >= 0 ? 1u << light : 0;
        lit.lasers = light < LIGHT_NONE ? b->sc->laser_shots[LIGHT_LASER_OF(light)] : 0;
        if (light < 0) {
                struct plan_shot s = shot_new(b, light < LIGHT_NONE ? PLAN_LASER : PLAN_IMAGE, &lit,
                                              cameras, -1);
                return add_shots(b, &s);
        }
        for (size_t k = 0; k < b->sc->n_brackets; k++) {
                struct plan_shot s = shot_new(b, PLAN_IMAGE, &lit, cameras, k);

                if ((r = add_shots(b, &s)) < 0)
                        return r;
        }
        return 0;
}

/* The shots at one pose: each lamp that lights a camera, then the unlit frame, then the
 * laser shots; reversed when that starts with the light still lit from the last pose. */
static int add_pose(struct builder *b, const struct gn_pose *pose)
{
        int lights[RIG_MAX_LAMPS + 1 + RIG_MAX_LASERS], n = 0, r;
        uint32_t masks[RIG_MAX_LAMPS + 1 + RIG_MAX_LASERS];
        bool rev;

        for (size_t l = 0; l < b->rc->n_lamps; l++) {
                if (!(b->sc->lamps & (1u << l)))
                        continue;
                if ((r = lamp_cameras(b, pose, l, &masks[n])) < 0)
                        return r;
                if (masks[n])
                        lights[n++] = l;
        }
        if (b->sc->unlit) {
                masks[n] = b->sc->cameras;
                lights[n++] = LIGHT_NONE;
        }
        for (size_t i = 0; i < b->sc->n_laser_shots; i++) {
                masks[n] = b->sc->cameras;
                lights[n++] = LIGHT_LASER(i);
        }
        rev = !b->naive && n > 1 && lights[n - 1] == b->light && lights[0] != b->light;
        for (int i = 0; i < n; i++) {
                int k = rev ? n - 1 - i : i;

                if ((r = add_light(b, pose, lights[k], masks[k])) < 0)
                        return r;
        }
        if (n)
                b->light = lights[rev ? 0 : n - 1];
        return 0;
}

/* Seconds to move role's axis from a to b, with the session's extra settle. */
static double role_move(const struct builder *b, enum gn_role role, double from, double to)
{
        double t = plan_move_time(&b->rc->axes[rigconf_axis_of_role(b->rc, role)], from, to);

        return t > 0 ? t + b->sc->settle_ms[role] / 1000.0 : 0;
}

/* qsort_r order of indices into the angles deg. */
static int by_angle(const void *x, const void *y, void *deg)
{
        double a = ((double *)deg)[*(const size_t *)x], c = ((double *)deg)[*(const size_t *)y];

        return (a > c) - (a < c);
}

/* Sorts role's angles and prices the steps between neighbours. */
static int loop_init(struct builder *b, enum gn_role role)
{
        const struct sess_sweep *sw = &b->sc->sweep[role];
        struct loop *l = &b->loops[role];
        size_t n = sw->n;

        l->n = n;
        l->sorted = calloc(n, sizeof(size_t));
        l->up = calloc(2 * n + 1, sizeof(double));
        l->down = calloc(2 * n + 1, sizeof(double));
        if (!l->sorted || !l->up || !l->down)
                return -ENOMEM;
        for (size_t i = 0; i < n; i++)
                l->sorted[i] = i;
        qsort_r(l->sorted, n, sizeof(size_t), by_angle, sw->deg);
        for (size_t k = 0; k < 2 * n; k++) {
                double a = sw->deg[l->sorted[k % n]], c = sw->deg[l->sorted[(k + 1) % n]];

                l->up[k + 1] = l->up[k] + role_move(b, role, a, c);
                l->down[k + 1] = l->down[k] + role_move(b, role, c, a);
        }
        return 0;
}

static void loops_free(struct builder *b)
{
        for (int r = 0; r < GN_ROLE_COUNT; r++) {
                free(b->loops[r].sorted);
                free(b->loops[r].up);
                free(b->loops[r].down);
        }
}

/* The angle at position j of the line of way w through loop l of role. */
static double line_deg(const struct builder *b, enum gn_role role, const struct way *w, size_t j)
{
        const struct loop *l = &b->loops[role];

        return b->sc->sweep[role].deg[l->sorted[(w->cut + j) % l->n]];
}

/* Seconds for the pass w of role's loop from where its axis is (unknown: from its first
 * angle). */
static double way_cost(const struct builder *b, enum gn_role role, const struct way *w)
{
        const struct loop *l = &b->loops[role];
        size_t n = l->n, c = w->cut, s = w->s;
        double t =
                isnan(b->at[role]) ? 0 : role_move(b, role, b->at[role], line_deg(b, role, w, s));

        if (w->dir > 0) { /* up to the end, then from the end down past s */
                t += l->up[c + n - 1] - l->up[c + s];
                if (s > 0)
                        t += role_move(b, role, line_deg(b, role, w, n - 1),
                                       line_deg(b, role, w, s - 1)) +
                             l->down[c + s - 1] - l->down[c];
        } else { /* down to the start, then from there up past s */
                t += l->down[c + s] - l->down[c];
                if (s + 1 < n)
                        t += role_move(b, role, line_deg(b, role, w, 0),
                                       line_deg(b, role, w, s + 1)) +
                             l->up[c + n - 1] - l->up[c + s + 1];
        }
        return t;
}

/* The way of least cost for role's next pass (a tie keeps the first found: upwards from
 * the lowest angle). */
static struct way best_way(const struct builder *b, enum gn_role role)
{
        size_t n = b->loops[role].n;
        struct way best = {.dir = 1}, w;
        double least = INFINITY;

        for (w.cut = 0; w.cut < n; w.cut++)
                for (w.s = 0; w.s < n; w.s++) {
                        if (n > PLAN_ZIGZAG_MAX && w.s != 0 && w.s != n - 1)
                                continue;
                        for (w.dir = 1; w.dir >= -1; w.dir -= 2) {
                                double t = way_cost(b, role, &w);

                                if (t < least - 1e-9) {
                                        least = t;
                                        best = w;
                                }
                        }
                }
        return best;
}

/* The order of role's angles for its next pass into seq (indices into the sweep): the
 * naive plan's file order, else its best way. */
static void pass_order(const struct builder *b, enum gn_role role, size_t *seq)
{
        const struct loop *l = &b->loops[role];
        size_t n = l->n, k = 0;
        struct way w;

        if (b->naive) {
                for (size_t i = 0; i < n; i++)
                        seq[i] = i;
                return;
        }
        w = best_way(b, role);
        if (w.dir > 0) {
                for (size_t j = w.s; j < n; j++)
                        seq[k++] = l->sorted[(w.cut + j) % n];
                for (size_t j = w.s; j-- > 0;)
                        seq[k++] = l->sorted[(w.cut + j) % n];
        } else {
                for (size_t j = w.s + 1; j-- > 0;)
                        seq[k++] = l->sorted[(w.cut + j) % n];
                for (size_t j = w.s + 1; j < n; j++)
                        seq[k++] = l->sorted[(w.cut + j) % n];
        }
}

/* The mechanical loops from level on (order: roles, outermost first) at pose. */
static int visit(struct builder *b, const int *order, int n_order, int level, struct gn_pose *pose)
{
        enum gn_role role;
        _cleanup_free_ size_t *seq = NULL;
        int r;

        if (level == n_order)
                return add_pose(b, pose);
        role = order[level];
        if (!(seq = calloc(b->loops[role].n, sizeof(size_t))))
                return -ENOMEM;
        pass_order(b, role, seq);
        for (size_t i = 0; i < b->loops[role].n; i++) {
                pose->deg[role] = b->at[role] = b->sc->sweep[role].deg[seq[i]];
                if ((r = visit(b, order, n_order, level + 1, pose)) < 0)
                        return r;
        }
        return 0;
}

/* ---- the lower bound ---- */

static bool same_state(const struct gn_pose *a, const struct gn_pose *b)
{
        for (int r = 0; r < GN_ROLE_COUNT; r++)
                if (!(isnan(a->deg[r]) && isnan(b->deg[r])) && a->deg[r] != b->deg[r])
                        return false;
        return a->lamps == b->lamps && a->lasers == b->lasers;
}

static bool same_angles(const struct gn_pose *a, const struct gn_pose *b)
{
        struct gn_pose x = *a;

        x.lamps = b->lamps;
        x.lasers = b->lasers;
        return same_state(&x, b);
}

/* The exposure any order must spend: the shots of one state (pose and lights) cannot
 * overlap those of another, and one camera's frames follow each other; so the sum over
 * states of the longest per-camera total of exposure + readout. The shots of a state must
 * be consecutive (they are in every plan built here). */
static double exposure_bound(const struct rig_config *rc, const struct plan_shot *s, size_t n)
{
        double sum[RIG_MAX_CAMERAS] = {0}, total = 0;

        for (size_t i = 0; i < n; i++) {
                double longest = 0;

                for (size_t c = 0; c < rc->n_cameras; c++)
                        if (s[i].cameras & (1u << c))
                                sum[c] += frame_time(rc, &s[i], c);
                if (i + 1 < n && same_state(&s[i].pose, &s[i + 1].pose))
                        continue;
                for (size_t c = 0; c < rc->n_cameras; c++) {
                        longest = fmax(longest, sum[c]);
                        sum[c] = 0;
                }
                total += longest;
        }
        return total;
}

/* The least time of any change of pose: the fastest move of any swept role between two of
 * its angles (the smallest gap, one leg, no take-up), settles included. */
static double min_pose_change(const struct builder *b)
{
        double best = INFINITY;

        for (int r = 0; r < GN_ROLE_COUNT; r++) {
                const struct loop *l = &b->loops[r];
                const struct rig_axis_conf *ax;
                double gap = INFINITY;

                if (l->n < 2)
                        continue;
                ax = &b->rc->axes[rigconf_axis_of_role(b->rc, r)];
                for (size_t i = 0; i < l->n; i++) {
                        double a = b->sc->sweep[r].deg[l->sorted[i]];
                        double c = b->sc->sweep[r].deg[l->sorted[(i + 1) % l->n]];

                        if (i + 1 < l->n || ax->continuous)
                                gap = fmin(gap,
                                           ax->continuous ? gn_angle_distance(a, c) : fabs(c - a));
                }
                best = fmin(best,
                            axis_move_time(gap, ax->max_speed, ax->accel) +
                                    (ax->settle_ms + ax->move_overhead_ms + b->sc->settle_ms[r]) /
                                            1000.0);
        }
        return best;
}

/* The least warm-up of a change of light at one pose: the least warm-up of the lights the
 * image and laser shots use; 0 when one of them is the unlit frame (a change into it only
 * switches off). */
static double min_light_change(const struct rig_config *rc, const struct plan_shot *s, size_t n)
{
        uint32_t lamps = 0, lasers = 0;

        for (size_t i = 0; i < n; i++)
                if (s[i].kind == PLAN_IMAGE || s[i].kind == PLAN_LASER) {
                        if (!s[i].pose.lamps && !s[i].pose.lasers)
                                return 0; /* an unlit frame: switching off costs nothing */
                        lamps |= s[i].pose.lamps;
                        lasers |= s[i].pose.lasers;
                }
        return fmin(warmup(rc->lamps, rc->n_lamps, lamps, false),
                    warmup(rc->lasers, rc->n_lasers, lasers, false));
}

/* The least time of the first move from start: each swept role that starts at none of its
 * angles must move at least to the nearest one. */
static double start_bound(const struct builder *b, const struct gn_pose *start)
{
        double t = 0;

        for (int r = 0; start && r < GN_ROLE_COUNT; r++) {
                const struct sess_sweep *sw = &b->sc->sweep[r];
                const struct rig_axis_conf *ax;
                double gap = INFINITY;

                if (!sw->n || isnan(start->deg[r]))
                        continue;
                ax = &b->rc->axes[rigconf_axis_of_role(b->rc, r)];
                for (size_t i = 0; i < sw->n; i++)
                        gap = fmin(gap, ax->continuous
                                                ? gn_angle_distance(start->deg[r], sw->deg[i])
                                                : fabs(start->deg[r] - sw->deg[i]));
                if (gap > PLAN_ANGLE_EPS)
                        t = fmax(t, axis_move_time(gap, ax->max_speed, ax->accel) +
                                            (ax->settle_ms + ax->move_overhead_ms +
                                             b->sc->settle_ms[r]) /
                                                    1000.0);
        }
        return t;
}

/* The changes any order must make between the image and laser shots: with P poses and G
 * states (pose, light), P - 1 pose changes and G - P changes of light at one pose (a pose
 * change that also changes the light counts once, at least a pose change's time), plus the
 * first move. Counts runs of consecutive shots: every plan built here visits each pose
 * and each state once. */
static double transition_bound(const struct builder *b, const struct plan_shot *s, size_t n,
                               const struct gn_pose *start)
{
        const struct plan_shot *last = NULL;
        size_t poses = 0, states = 0;
        double m = min_pose_change(b), w, t;

        for (size_t i = 0; i < n; i++) {
                if (s[i].kind != PLAN_IMAGE && s[i].kind != PLAN_LASER)
                        continue;
                states += !last || !same_state(&last->pose, &s[i].pose);
                poses += !last || !same_angles(&last->pose, &s[i].pose);
                last = &s[i];
        }
        w = fmin(min_light_change(b->rc, s, n), m);
        t = poses ? start_bound(b, start) : 0;
        if (poses > 1)
                t += (poses - 1) * m;
        if (states > poses)
                t += (states - poses) * w;
        return t;
}

/* ---- plans ---- */

/* Numbers the captures, times the shots and bounds the plan. */
static int finish(struct builder *b, const struct gn_pose *start)
{
        struct plan *p = b->p;
        _cleanup_free_ double *t = calloc(p->n_shots + 1, sizeof(double));
        int64_t seq = 1;

        if (!t)
                return -ENOMEM;
        for (size_t i = 0; i < p->n_shots; i++) {
                int k = __builtin_popcount(p->shots[i].cameras);

                p->shots[i].seq = seq;
                seq += k;
                p->n_captures += k;
        }
        p->estimate_s = estimate(b->rc, p->shots, p->n_shots, start, b->naive, t, &p->n_moves);
        for (size_t i = 0; i < p->n_shots; i++)
                p->shots[i].t_start_s = t[i];
        p->lower_bound_s = exposure_bound(b->rc, p->shots, p->n_shots) +
                           transition_bound(b, p->shots, p->n_shots, start);
        return 0;
}

/* The plan with the mechanical loops nested in order (n_order roles, outermost first). */
static int build_one(const struct rig_config *rc, const struct session_conf *sc,
                     const struct gn_pose *start, const int *order, int n_order, bool naive,
                     struct plan **ret)
{
        struct builder b = {.rc = rc, .sc = sc, .naive = naive, .light = LIGHT_NONE};
        struct gn_pose pose = gn_pose_none();
        int r = 0;

        if (!(b.p = calloc(1, sizeof(*b.p))))
                return -ENOMEM;
        for (int i = 0; i < GN_ROLE_COUNT; i++) {
                b.at[i] = start ? start->deg[i] : NAN;
                b.geo.deg[i] = isnan(b.at[i]) ? 0 : b.at[i];
        }
        memcpy(b.p->order, order, n_order * sizeof(int));
        b.p->n_order = n_order;
        for (int i = 0; r >= 0 && i < n_order; i++)
                r = loop_init(&b, order[i]);
        if (r >= 0)
                r = add_calibration(&b);
        if (r >= 0)
                r = visit(&b, order, n_order, 0, &pose);
        if (r >= 0)
                r = finish(&b, start);
        loops_free(&b);
        if (r < 0) {
                plan_free(b.p);
                return r;
        }
        *ret = b.p;
        return 0;
}

/* Whether sc fits rc (it was loaded against it). */
static bool fits(const struct rig_config *rc, const struct session_conf *sc)
{
        uint64_t cams = (1ull << rc->n_cameras) - 1, lamps = (1ull << rc->n_lamps) - 1;
        uint32_t lasers = 0;

        for (size_t i = 0; i < sc->n_laser_shots; i++)
                lasers |= sc->laser_shots[i];

        for (int r = 0; r < GN_ROLE_COUNT; r++)
                if (sc->sweep[r].n && rigconf_axis_of_role(rc, r) < 0)
                        return false;
        return !(sc->cameras & ~cams) && !(sc->lamps & ~lamps) && !(sc->flat_lamps & ~lamps) &&
               !(lasers & ~rigconf_all_lasers(rc));
}

/* Whether the plan of sc, one camera per shot when naive, fits PLAN_MAX_SHOTS (counted
 * before skips, in floating point: a product of sweeps may not fit an integer). */
static bool small_enough(const struct rig_config *rc, const struct session_conf *sc, bool naive)
{
        double poses = 1, per_pose, calib;

        for (int r = 0; r < GN_ROLE_COUNT; r++)
                poses *= sc->sweep[r].n ? (double)sc->sweep[r].n : 1;
        per_pose = (double)__builtin_popcount(sc->lamps) * sc->n_brackets + sc->n_laser_shots;
        calib = (double)sc->dark_frames * (sc->n_brackets + 1) + sc->flat_frames;
        return (poses * per_pose + calib) * (naive ? rc->n_cameras : 1) <= PLAN_MAX_SHOTS;
}

/* Steps a to the next permutation in lexicographic order; false after the last. */
static bool next_permutation(int *a, int n)
{
        int i = n - 2, j = n - 1, t;

        while (i >= 0 && a[i] >= a[i + 1])
                i--;
        if (i < 0)
                return false;
        while (a[j] <= a[i])
                j--;
        t = a[i], a[i] = a[j], a[j] = t;
        for (int l = i + 1, h = n - 1; l < h; l++, h--)
                t = a[l], a[l] = a[h], a[h] = t;
        return true;
}

int plan_build(const struct rig_config *rc, const struct session_conf *sc,
               const struct gn_pose *start, struct plan **ret)
{
        int order[GN_ROLE_COUNT], n = 0, r;
        struct plan *best = NULL;

        if (!rc || !sc || !ret || !fits(rc, sc))
                return -EINVAL;
        if (!small_enough(rc, sc, false))
                return -E2BIG;
        for (int i = 0; i < GN_ROLE_COUNT; i++)
                if (sc->sweep[i].n)
                        order[n++] = i;
        do {
                struct plan *p;

                if ((r = build_one(rc, sc, start, order, n, false, &p)) < 0) {
                        plan_free(best);
                        return r;
                }
                if (!best || p->estimate_s < best->estimate_s - 1e-9) {
                        struct plan *t = best;
                        best = p;
                        p = t;
                }
                plan_free(p);
        } while (next_permutation(order, n));
        *ret = best;
        return 0;
}

int plan_build_naive(const struct rig_config *rc, const struct session_conf *sc,
                     const struct gn_pose *start, struct plan **ret)
{
        int order[GN_ROLE_COUNT], n = 0;

        if (!rc || !sc || !ret || !fits(rc, sc))
                return -EINVAL;
        if (!small_enough(rc, sc, true))
                return -E2BIG;
        for (size_t i = 0; i < rc->n_axes; i++)
                if (rc->axes[i].role >= 0 && sc->sweep[rc->axes[i].role].n)
                        order[n++] = rc->axes[i].role;
        return build_one(rc, sc, start, order, n, true, ret);
}

const struct plan_shot *plan_find_seq(const struct plan *p, int64_t seq, int *camera)
{
        size_t lo = 0, hi = p ? p->n_shots : 0;
        const struct plan_shot *s;
        int64_t k;

        while (hi - lo > 1) { /* the last shot whose first seq is <= seq */
                size_t mid = lo + (hi - lo) / 2;

                if (p->shots[mid].seq <= seq)
                        lo = mid;
                else
                        hi = mid;
        }
        if (hi == 0 || seq < 1 || (s = &p->shots[lo])->seq > seq)
                return NULL;
        k = seq - s->seq;
        for (int c = 0; c < 32; c++)
                if ((s->cameras & (1u << c)) && k-- == 0) {
                        if (camera)
                                *camera = c;
                        return s;
                }
        return NULL;
}

struct plan *plan_free(struct plan *p)
{
        if (!p)
                return NULL;
        free(p->shots);
        free(p->skips);
        free(p);
        return NULL;
}
