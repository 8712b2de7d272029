/* scan.c - goniod's continuous laser scan (see scan.h).
 *
 * DESIGN: the scanned range [lo, hi) (each angle +- step/2) is cut into legs short enough
 * that every move goes the way we mean on a continuous axis (under 180 deg). A leg is one
 * move at speed v = step x frame rate from lo_k - run to hi_k + run, where run covers the
 * acceleration, so the table turns at v all through [lo_k, hi_k); between legs the table
 * goes back (at full speed) to the next leg's run-up. The laser is on and the camera
 * streams through all legs. Every read-back of the turntable (rig_track: as often as its
 * bus answers while it moves) is unwrapped and kept with its time; a frame waits until a
 * read-back later than its mid-exposure exists, then its angle is interpolated between the
 * two read-backs around that time. A frame is stored when its time falls in a leg's move
 * and its angle in that leg's range, so every angle is covered by one leg only.
 *
 * Several lasers: one pass of all the legs per laser, that laser alone on (switched off,
 * the next one on, between passes while the table goes back to the first run-up; the stream
 * goes on). Each leg records its laser, so a frame's laser is that of the leg its time falls
 * in. Switching the laser frame by frame instead would need the switch synchronised to the
 * exposures, which no switch backend offers (a G-code or Modbus round trip is several ms
 * and jitters), and a frame exposed across a switch would be lost or, worse, stored with
 * the wrong laser. The passes cost one run-up and the switching per laser: the scan stays
 * within a few percent of the camera bound for N x the frames (docs/scanning.md).
 *
 * Everything runs on the loop thread; the first error ends the scan: stream stopped, motion
 * stopped, every laser off, stores finished, then the reply. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/clock.h"
#include "common/log.h"
#include "datasets.h"
#include "manager.h"
#include "scan.h"

#define SCAN_SAMPLES   8192 /* turntable read-backs kept (about 16 s at 2 ms) */
#define SCAN_PENDING   32   /* frames waiting for a later read-back */
#define SCAN_MAX_LEGS  8
#define SCAN_LEG_DEG   170.0   /* a leg's move, run-up and run-out included, stays below this */
#define SCAN_MARGIN_S  0.1     /* run-up beyond the acceleration: time at speed before lo */
#define SCAN_RUN_MAX   40.0    /* deg: a longer run-up means a speed the axis cannot reach */
#define SCAN_RTT_SLACK 2000000 /* ns: read-backs slower than the fastest by more are not used */

struct sample {
        uint64_t t_ns;
        double deg; /* unwrapped, in the scan's angles */
};

struct pend {
        struct gn_frame f;
        uint64_t t_mid;
};

struct leg {
        double lo, hi;           /* angles stored by this leg: [lo, hi) */
        uint64_t t_start, t_end; /* CLOCK_REALTIME of its move; t_end UINT64_MAX while it runs */
        int laser;               /* the laser on during it (rig-file index) */
};

/* A stored frame's angle, and its pass (laser). */
struct angle {
        double deg;
        int pass;
};

enum step { S_IDLE, S_TO_START, S_LASER_ON, S_LEG, S_BACK, S_LASER_OFF, S_ENDING };

struct scan {
        struct manager *m;
        struct srv_req *req;
        struct scan_params p;
        int axis;
        bool continuous;
        enum step step;
        bool waiting; /* a rig operation's completion is outstanding */
        bool streaming;
        int error;
        char msg[256];
        double v, run;
        size_t n_pos, n_legs, leg; /* n_legs per pass; leg: index in legs, over the passes */
        size_t n_passes;           /* one per laser, in rig-file order */
        struct leg legs[SCAN_MAX_LEGS * RIG_MAX_LASERS];
        struct sample *samples; /* ring of SCAN_SAMPLES */
        size_t n_samples, head; /* head: index of the next write */
        double last_raw;
        uint64_t min_rtt;
        struct pend pending[SCAN_PENDING];
        size_t n_pending;
        struct angle *angles; /* stored angles, n_pos x passes + extra room */
        size_t n_angles, cap_angles;
        unsigned stores; /* in flight */
        unsigned offs;   /* lasers being switched off at the end */
        size_t frames, late, outside;
        double spread;
        int64_t first_id, last_id;
        uint64_t t_begin, t_end;
        char reason[160];
};

static void proceed(struct scan *s);
static void fail(struct scan *s, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

int scan_new(struct manager *m, struct scan **ret)
{
        struct scan *s = calloc(1, sizeof(*s));

        if (!s || !(s->samples = calloc(SCAN_SAMPLES, sizeof(*s->samples)))) {
                free(s);
                return -ENOMEM;
        }
        s->m = m;
        *ret = s;
        return 0;
}

static void drop_pending(struct scan *s)
{
        for (size_t i = 0; i < s->n_pending; i++)
                gn_frame_free_data(&s->pending[i].f);
        s->n_pending = 0;
}

struct scan *scan_free(struct scan *s)
{
        if (!s)
                return NULL;
        drop_pending(s);
        free(s->angles);
        free(s->samples);
        free(s);
        return NULL;
}

void scan_abandon(struct scan *s)
{
        if (s->step == S_IDLE)
                return;
        if (s->streaming)
                rig_stream_stop(s->m->rig, s->p.cam);
        rig_track(s->m->rig, -1, NULL, NULL);
        s->streaming = false;
        s->step = S_IDLE;
        s->req = NULL; /* the server is gone */
}

void scan_cancel(struct scan *s)
{
        if (s->step != S_IDLE && s->step != S_ENDING)
                fail(s, -ECANCELED, "the scan was stopped by a client");
}

bool scan_active(const struct scan *s)
{
        return s->step != S_IDLE;
}

const char *scan_busy_reason(const struct scan *s)
{
        return s->step == S_IDLE ? NULL : s->reason;
}

/* ---- the reply ---- */

static int cmp_angle(const void *a, const void *b)
{
        const struct angle *x = a, *y = b;

        if (x->pass != y->pass)
                return x->pass - y->pass;
        return (x->deg > y->deg) - (x->deg < y->deg);
}

/* The largest step between consecutive stored angles of one pass, and from the range's
 * ends, over the passes. */
static double max_gap(struct scan *s)
{
        double lo = s->p.from, hi = s->p.from + (s->n_pos - 1) * s->p.step, gap = 0;
        size_t b = 0, e;

        qsort(s->angles, s->n_angles, sizeof(*s->angles), cmp_angle);
        for (int pass = 0; pass < (int)s->n_passes; pass++, b = e) {
                for (e = b; e < s->n_angles && s->angles[e].pass == pass; e++)
                        if (e > b)
                                gap = fmax(gap, s->angles[e].deg - s->angles[e - 1].deg);
                if (e == b)
                        return hi - lo + s->p.step; /* a pass stored nothing */
                gap = fmax(gap, fmax(s->angles[b].deg - lo, hi - s->angles[e - 1].deg));
        }
        return gap;
}

/* The names of the scan's lasers, one per pass. */
static json_t *lasers_json(const struct scan *s)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < s->n_passes; i++)
                json_array_append_new(
                        a, json_string(s->m->rc->lasers[s->legs[i * s->n_legs].laser].name));
        return a;
}

static json_t *result_json(struct scan *s)
{
        const struct rig_config *rc = s->m->rc;
        size_t want = s->n_pos * s->n_passes;
        size_t missed = want > s->n_angles ? want - s->n_angles : 0;

        return json_pack("{s:s, s:s, s:I, s:I, s:I, s:I, s:I, s:I, s:f, s:f, s:f, s:I, s:f, s:I, "
                         "s:I, s:o}",
                         "dataset", capture_dataset_name(s->m->capture) ?: "", "camera",
                         rc->cameras[s->p.cam].name, "positions", (json_int_t)s->n_pos, "stored",
                         (json_int_t)s->n_angles, "frames", (json_int_t)s->frames, "missed",
                         (json_int_t)missed, "late", (json_int_t)s->late, "outside",
                         (json_int_t)s->outside, "max_gap_deg", max_gap(s), "interp_spread_deg",
                         s->spread, "speed_deg_s", s->v, "legs", (json_int_t)s->n_legs,
                         "duration_s", (s->t_end - s->t_begin) / 1e9, "first_id",
                         (json_int_t)s->first_id, "last_id", (json_int_t)s->last_id, "lasers",
                         lasers_json(s));
}

/* Answers once the lasers are off, the stream stopped and every store answered. */
static void maybe_reply(struct scan *s)
{
        struct srv_req *req = s->req;

        if (s->step != S_ENDING || s->waiting || s->stores > 0)
                return;
        s->step = S_IDLE;
        s->req = NULL;
        drop_pending(s);
        if (s->error < 0) {
                log_warning("continuous scan ended: %s", s->msg);
                srv_fail_data(req, s->error, json_pack("{s:o}", "scan", result_json(s)), "%s",
                              s->msg);
        } else
                srv_reply(req, result_json(s));
}

static void on_laser_off(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct scan *s = userdata;

        if (s->step == S_IDLE)
                return; /* abandoned */
        s->waiting = --s->offs > 0;
        if (result < 0 && s->error == 0)
                fail(s, result, "switching the laser off failed: %s", msg ?: strerror(-result));
        maybe_reply(s);
}

/* Stops the stream and the tracking, switches every laser off; the reply follows. */
static void end(struct scan *s)
{
        struct rig *rig = s->m->rig;
        int r;

        s->step = S_ENDING;
        s->t_end = gn_realtime_ns();
        if (s->streaming)
                rig_stream_stop(rig, s->p.cam);
        s->streaming = false;
        rig_track(rig, -1, NULL, NULL);
        s->offs = 1; /* held until every switch is asked */
        for (size_t i = 0; i < s->m->rc->n_lasers; i++) {
                r = rig_switch(rig, RIG_SW_LASER(i), false, on_laser_off, s);
                s->offs += r >= 0;
                if (r < 0)
                        log_warning("continuous scan: cannot switch laser '%s' off now: %s",
                                    s->m->rc->lasers[i].name, strerror(-r));
        }
        s->waiting = --s->offs > 0;
        maybe_reply(s);
}

/* Records the first error and ends the scan: motion is stopped at once. */
static void fail(struct scan *s, int err, const char *fmt, ...)
{
        va_list ap;

        if (s->error == 0) {
                s->error = err;
                va_start(ap, fmt);
                vsnprintf(s->msg, sizeof(s->msg), fmt, ap);
                va_end(ap);
        }
        if (s->step == S_ENDING)
                return;
        if (s->waiting && (s->step == S_TO_START || s->step == S_LEG || s->step == S_BACK)) {
                (void)rig_stop(s->m->rig, NULL); /* the move's completion then ends the scan */
                return;
        }
        if (!s->waiting)
                end(s);
}

/* ---- angles ---- */

/* The client that asked went away: the scan ends (nobody would get its result). */
static bool client_gone(struct scan *s)
{
        if (srv_req_connected(s->req))
                return false;
        fail(s, -ECONNRESET, "the client that asked for the scan disconnected");
        return true;
}

/* The two read-backs around t: the later one's index in *after. False when there is no
 * read-back after t yet (*too_old false) or none before it any more (*too_old true). */
static bool bracket(const struct scan *s, uint64_t t, size_t *after, bool *too_old)
{
        size_t i = (s->head + SCAN_SAMPLES - 1) % SCAN_SAMPLES;

        *too_old = false;
        if (s->n_samples < 2 || s->samples[i].t_ns <= t)
                return false;
        for (size_t k = 1; k < s->n_samples; k++) {
                size_t prev = (i + SCAN_SAMPLES - 1) % SCAN_SAMPLES;
                if (s->samples[prev].t_ns <= t) {
                        *after = i;
                        return true;
                }
                i = prev;
        }
        *too_old = true;
        return false;
}

/* The leg whose move was running at t, or NULL. */
static const struct leg *leg_at(const struct scan *s, uint64_t t)
{
        for (size_t k = 0; k < s->n_legs * s->n_passes; k++)
                if (s->legs[k].t_start && t >= s->legs[k].t_start && t <= s->legs[k].t_end)
                        return &s->legs[k];
        return NULL;
}

static void on_stored(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct scan *s = userdata;
        const struct capture_shot *sh = &res->shots[0];

        if (s->step == S_IDLE)
                return; /* abandoned */
        s->stores--;
        if (sh->result < 0)
                fail(s, sh->result, "%s", sh->msg);
        else {
                s->first_id = s->first_id ? s->first_id : sh->row.id;
                s->last_id = sh->row.id;
        }
        maybe_reply(s);
}

/* Stores frame f at turntable angle deg (scan angles), taken during leg. */
static void store(struct scan *s, struct gn_frame *f, double deg, const struct leg *leg)
{
        struct gn_pose pose = rig_pose(s->m->rig);
        const struct capture_tag tag = {.kind = "image"};
        int r;

        pose.deg[GN_ROLE_TURNTABLE] = s->continuous ? fmod(fmod(deg, 360) + 360, 360) : deg;
        pose.lasers = UINT32_C(1) << leg->laser;
        r = capture_store_frame(s->m->capture, s->p.cam, f, &pose, &tag, on_stored, s);
        if (r == -EAGAIN) {
                s->late++; /* the storage queue is full */
                return;
        }
        if (r < 0)
                return fail(s, r, "storing a frame failed: %s", strerror(-r));
        s->stores++;
        if (s->n_angles < s->cap_angles)
                s->angles[s->n_angles++] = (struct angle){deg, (int)((leg - s->legs) / s->n_legs)};
}

/* Gives the oldest pending frame its angle and stores or drops it. False: it must wait. */
static bool resolve_one(struct scan *s)
{
        struct pend *p = &s->pending[0];
        const struct leg *leg;
        size_t b;
        bool too_old;

        if (!bracket(s, p->t_mid, &b, &too_old) && !too_old)
                return false;
        if (too_old)
                s->late++;
        else {
                const struct sample *hi = &s->samples[b],
                                    *lo = &s->samples[(b + SCAN_SAMPLES - 1) % SCAN_SAMPLES];
                double w = (double)(p->t_mid - lo->t_ns) / (double)(hi->t_ns - lo->t_ns);
                double deg = lo->deg + w * (hi->deg - lo->deg);

                leg = leg_at(s, p->t_mid);
                if (leg && deg >= leg->lo && deg < leg->hi) {
                        s->spread = fmax(s->spread, fabs(hi->deg - lo->deg));
                        store(s, &p->f, deg, leg);
                } else
                        s->outside++;
        }
        gn_frame_free_data(&p->f);
        memmove(&s->pending[0], &s->pending[1], --s->n_pending * sizeof(*p));
        return true;
}

static void resolve(struct scan *s)
{
        while (s->n_pending > 0 && s->error == 0 && resolve_one(s))
                ;
}

/* A read-back of the turntable: kept unless its round trip leaves its time uncertain (a
 * descheduled worker, a busy emulator), so that the interpolation bridges only well-timed
 * read-backs; on a constant-speed leg a longer bridge costs nothing. */
static void on_track(void *userdata, int axis, double position_deg, uint64_t t_ns, uint64_t rtt_ns)
{
        struct scan *s = userdata;
        struct sample *prev = &s->samples[(s->head + SCAN_SAMPLES - 1) % SCAN_SAMPLES];
        double ref = s->legs[0].lo - s->run;
        double deg = s->n_samples ? prev->deg + remainder(position_deg - s->last_raw, 360)
                                  : ref + remainder(position_deg - ref, 360);

        if (client_gone(s))
                return;
        s->min_rtt = s->min_rtt && s->min_rtt < rtt_ns ? s->min_rtt : rtt_ns;
        if ((s->n_samples && t_ns <= prev->t_ns) || rtt_ns > s->min_rtt + SCAN_RTT_SLACK)
                return;
        s->samples[s->head] = (struct sample){t_ns, deg};
        s->head = (s->head + 1) % SCAN_SAMPLES;
        s->n_samples += s->n_samples < SCAN_SAMPLES;
        s->last_raw = position_deg;
        resolve(s);
}

static void on_frame(struct rig *rig, int result, struct gn_frame *f, const char *msg,
                     void *userdata)
{
        struct scan *s = userdata;

        if (result < 0) {
                s->streaming = false;
                return fail(s, result, "%s", msg);
        }
        if (client_gone(s))
                return;
        s->frames++;
        if (s->n_pending == SCAN_PENDING) { /* no read-back for too long */
                s->late++;
                gn_frame_free_data(&s->pending[0].f);
                memmove(&s->pending[0], &s->pending[1], --s->n_pending * sizeof(struct pend));
        }
        s->pending[s->n_pending++] =
                (struct pend){*f, f->timestamp_ns + (uint64_t)f->exposure_us * 500};
        *f = (struct gn_frame){0};
        resolve(s);
}

/* ---- the sequence ---- */

static void on_rig_done(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct scan *s = userdata;

        if (s->step == S_IDLE)
                return; /* abandoned */
        s->waiting = false;
        if (s->step == S_LEG)
                s->legs[s->leg].t_end = gn_realtime_ns();
        if (result < 0)
                fail(s, result, "%s%s",
                     result == -ECANCELED ? "the scan was stopped: " : "the scan failed: ",
                     msg ?: strerror(-result));
        proceed(s);
}

/* Moves the turntable to angle deg (scan angles) at speed (0: full speed). */
static int move_to(struct scan *s, double deg, double speed)
{
        double target = s->continuous ? fmod(fmod(deg, 360) + 360, 360) : deg;
        int r = rig_move_at(s->m->rig, s->axis, &target, speed, on_rig_done, s);

        s->waiting = r >= 0;
        return r;
}

/* Starts leg s->leg: the move through its range at the scan's speed. */
static int start_leg(struct scan *s)
{
        s->step = S_LEG;
        s->legs[s->leg].t_start = gn_realtime_ns();
        s->legs[s->leg].t_end = UINT64_MAX;
        return move_to(s, s->legs[s->leg].hi + s->run, s->v);
}

/* Starts the stream (the first pass), then the pass's first leg. */
static int start_pass(struct scan *s)
{
        int r;

        if (!s->streaming) {
                if ((r = rig_stream_start(s->m->rig, s->p.cam, &s->p.req, on_frame, s)) < 0)
                        return r;
                s->streaming = true;
                rig_track(s->m->rig, s->axis, on_track, s);
                s->t_begin = gn_realtime_ns();
        }
        return start_leg(s);
}

/* Switches the laser of leg s->leg on or off. */
static int switch_laser(struct scan *s, bool on)
{
        int r = rig_switch(s->m->rig, RIG_SW_LASER(s->legs[s->leg].laser), on, on_rig_done, s);

        s->waiting = r >= 0;
        return r;
}

/* Between passes: the next pass's first leg, its read-backs unwrapped anew about its start.
 * The return to the start goes the shortest way round, which after a full turn is not back
 * the way the table came, so the old unwrapping would put the new pass a turn off; the
 * frames still waiting belong to the last run-out, outside every leg. */
static void new_pass(struct scan *s)
{
        s->step = S_TO_START;
        s->leg++;
        s->n_samples = 0;
        s->outside += s->n_pending;
        drop_pending(s);
}

/* The next stage once the last one's operation has completed. */
static int next_step(struct scan *s)
{
        switch (s->step) {
        case S_TO_START:
                s->step = S_LASER_ON;
                return switch_laser(s, true);
        case S_LASER_ON:
                return start_pass(s);
        case S_LEG:
                if (s->leg + 1 == s->n_legs * s->n_passes)
                        return end(s), 0;
                if ((s->leg + 1) % s->n_legs == 0) { /* the pass's last leg */
                        s->step = S_LASER_OFF;
                        return switch_laser(s, false);
                }
                s->step = S_BACK;
                return move_to(s, s->legs[s->leg + 1].lo - s->run, 0);
        case S_BACK:
                s->step = S_LEG;
                s->leg++;
                return start_leg(s);
        case S_LASER_OFF:
                new_pass(s);
                return move_to(s, s->legs[s->leg].lo - s->run, 0);
        default:
                return 0;
        }
}

static void proceed(struct scan *s)
{
        int r;

        if (s->waiting || s->step == S_ENDING)
                return;
        if (s->error)
                return end(s);
        r = next_step(s);
        if (r < 0)
                fail(s, r, "the scan failed: %s",
                     r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
}

/* ---- start ---- */

/* The angles of p: their count, and the legs that cover [from - step/2, last + step/2). */
static int plan_legs(struct scan *s, const struct rig_axis_conf *ax, char *msg, size_t len)
{
        const struct scan_params *p = &s->p;
        double span, leg_max;

        if (!(p->step > 0) || !(p->to > p->from))
                return snprintf(msg, len, "the scan needs from < to and step > 0"), -ERANGE;
        s->n_pos = (size_t)floor((p->to - p->from) / p->step + 1e-9) + 1;
        if (s->continuous && s->n_pos > 1 &&
            fabs(remainder(p->from + (s->n_pos - 1) * p->step - p->from, 360)) < 1e-9)
                s->n_pos--; /* a full turn: the last angle is the first */
        span = s->n_pos * p->step;
        s->v = p->step * rig_config(s->m->rig)->cameras[p->cam].frame_rate;
        s->run = s->v * s->v / (2 * ax->accel) + s->v * SCAN_MARGIN_S;
        if (s->v > ax->max_speed || s->run > SCAN_RUN_MAX)
                return snprintf(msg, len,
                                "step x frame rate = %.2f deg/s: beyond what '%s' can do "
                                "(max_speed %g, accel %g)",
                                s->v, ax->name, ax->max_speed, ax->accel),
                       -ERANGE;
        leg_max = SCAN_LEG_DEG - 2 * s->run;
        s->n_legs = (size_t)ceil(span / leg_max);
        if (s->n_legs > SCAN_MAX_LEGS || span > 360 + 1e-9)
                return snprintf(msg, len, "the scan covers more than one turn"), -ERANGE;
        s->n_passes = s->m->rc->n_lasers;
        for (size_t i = 0; i < s->n_legs * s->n_passes; i++) {
                size_t k = i % s->n_legs;

                s->legs[i] = (struct leg){.lo = p->from - p->step / 2 + span * k / s->n_legs,
                                          .hi = p->from - p->step / 2 + span * (k + 1) / s->n_legs,
                                          .laser = (int)(i / s->n_legs)};
        }
        return 0;
}

/* Why the scan cannot start now (msg), or 0. */
static int refusal(struct scan *s, char *msg, size_t len)
{
        struct manager *m = s->m;
        const char *why = session_busy_reason(m->session);
        const char *state = rig_state(m->rig);

        if (s->step != S_IDLE)
                return snprintf(msg, len, "%s", s->reason), -EBUSY;
        if (why)
                return snprintf(msg, len, "%s", why), -EBUSY;
        if (strcmp(state, "fault") == 0)
                return snprintf(msg, len, "the rig is in fault state (gonioctl fault clear)"),
                       -ESTALE;
        if (strcmp(state, "idle") != 0 || capture_in_flight(m->capture) > 0)
                return snprintf(msg, len, "the rig is busy (%s)", state), -EBUSY;
        if ((s->axis = rigconf_axis_of_role(m->rc, GN_ROLE_TURNTABLE)) < 0)
                return snprintf(msg, len, "this rig has no turntable"), -ENOENT;
        if (!m->rc->n_lasers)
                return snprintf(msg, len, "this rig has no laser"), -ENOENT;
        if (isnan(rig_pose(m->rig).deg[GN_ROLE_TURNTABLE]))
                return snprintf(msg, len, "the turntable is not homed (home first)"), -EPERM;
        if (!rig_axis_speed_settable(m->rig, s->axis))
                return snprintf(msg, len,
                                "the turntable's drive cannot turn at a chosen speed: "
                                "use a stop-and-go scan"),
                       -EOPNOTSUPP;
        if (!capture_dataset(m->capture))
                return snprintf(msg, len, "no dataset is open (dataset.open first)"), -ESTALE;
        return 0;
}

/* Forgets the last scan (its results), keeping the read-back ring. */
static void reset(struct scan *s, struct srv_req *req, const struct scan_params *p, int axis)
{
        struct sample *samples = s->samples;
        struct manager *m = s->m;

        free(s->angles);
        *s = (struct scan){.m = m, .req = req, .p = *p, .samples = samples, .axis = axis};
}

int scan_start(struct scan *s, struct srv_req *req, const struct scan_params *p, char *msg,
               size_t len)
{
        const struct rig_config *rc = s->m->rc;
        int axis, r;

        if ((r = refusal(s, msg, len)) < 0)
                return r;
        axis = s->axis;
        reset(s, req, p, axis);
        s->continuous = rc->axes[axis].continuous;
        if ((r = plan_legs(s, &rc->axes[axis], msg, len)) < 0)
                return r;
        s->cap_angles = (s->n_pos * 2 + 64) * s->n_passes;
        if (!(s->angles = malloc(s->cap_angles * sizeof(*s->angles))))
                return snprintf(msg, len, "out of memory"), -ENOMEM;
        r = move_to(s, s->legs[0].lo - s->run, 0);
        if (r < 0)
                return snprintf(msg, len, "cannot move the turntable to the start: %s",
                                r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r)),
                       r;
        s->step = S_TO_START;
        snprintf(s->reason, sizeof(s->reason),
                 "a continuous scan with camera '%s' into dataset '%s' is running",
                 rc->cameras[p->cam].name, capture_dataset_name(s->m->capture));
        log_info("continuous scan: %zu angles from %g deg, step %g deg, at %.2f deg/s in %zu legs, "
                 "%zu pass(es), one per laser",
                 s->n_pos, p->from, p->step, s->v, s->n_legs, s->n_passes);
        return 0;
}
