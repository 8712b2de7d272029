/* gcode_emu.c - emulated serial G-code controllers of gonio-sim (see gcode_emu.h and
 * docs/gcode.md): the Horus/Ciclop board and GRBL 1.1 on ptys. Written from the behaviour
 * of the firmwares' public sources (bq/horus-fw, gnea/grbl), not from their code.
 *
 * Per bus: bytes from the pty first go through the realtime filter (?, !, ~, Ctrl-X act at
 * once, as the firmwares' serial interrupt does); the rest wait in a receive buffer and are
 * assembled into lines (blanks and comments dropped, letters upcased) only when the
 * firmware would read them: GRBL while its planner has room and no homing runs, Horus when
 * the previous line's motion has ended (it answers a move at its end). Motion is sim/drive.c
 * in degrees; GRBL plans blocks and runs them in order. Replies collect in an output buffer
 * written to the pty after the lock is dropped. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/axis/gcode/proto.h"
#include "drivers/switch/gcode/proto.h"
#include "sim/drive.h"
#include "sim/gcode_emu.h"
#include "sim/pty.h"

#define GE_POLL_MS       5    /* tick period: the resolution of an "ok" at a move's end */
#define GE_LINE_MAX      80   /* both firmwares' line buffer */
#define GE_RAW_MAX       1024 /* received bytes not read as lines yet (serial buffer) */
#define GE_PLAN_MAX      15   /* GRBL 1.1 planner blocks */
#define GE_OUT_MAX       4096
#define GE_WRITE_TIMEOUT 1000
#define GE_LDR_DARK      180  /* M50: ADC counts with every laser off */
#define GE_LDR_PER_LASER 300  /* ... and more per laser on */
#define GE_NO_REPLY      (-1) /* a line whose reply comes later (at the end of its motion) */

/* Status codes both firmwares number alike. */
enum {
        ST_OK = 0,
        ST_EXPECTED_LETTER = 1,
        ST_BAD_NUMBER = 2,
        ST_INVALID_STATEMENT = 3,
        ST_NEGATIVE = 4,
        ST_SETTING_DISABLED = 5,
        ST_NOT_IDLE = 8,
        ST_ALARM_LOCK = 9,
        ST_OVERFLOW = 11,
        ST_UNSUPPORTED = 20,
        ST_MODAL_VIOLATION = 21,
        ST_UNDEFINED_FEED = 22,
        ST_NOT_INTEGER = 23,
        ST_WORD_REPEATED = 25,
};

/* A planned motion: targets of the axes in axes (bit per letter), at vmax deg/s (NAN: each
 * axis at its max_speed, G0). */
struct ge_block {
        double target[GC_N_AXES];
        unsigned axes;
        double vmax;
};

struct ge_axis {
        const struct rig_axis_conf *conf; /* NULL: no axis on this letter */
        double steps_per_deg;
        struct sim_drive drive;
};

struct ge_bus {
        struct sim_gcode *g;
        const struct rig_bus_conf *conf;
        enum gc_flavor flavor;
        struct sim_pty pty;
        pthread_t thread;
        bool started;
        atomic_int unplug_ms; /* > 0: the thread unplugs the board for that long */
        pthread_mutex_t lock; /* guards everything below */
        struct ge_axis axes[GC_N_AXES];
        bool laser[GCSW_TOOL_MAX];
        double laser_on_at[GCSW_TOOL_MAX];
        bool alarm, hold, homing;
        int owed;    /* lines answered when their motion ends */
        double feed; /* deg/min; 0 after a reset: undefined */
        bool linear; /* modal motion G1 (else G0) */
        struct ge_block plan[GE_PLAN_MAX];
        int n_plan;   /* plan[0] runs once started */
        bool running; /* plan[0] has started */
        char raw[GE_RAW_MAX];
        size_t n_raw;
        char line[GE_LINE_MAX];
        size_t n_line;
        enum { COMMENT_NONE, COMMENT_PAREN, COMMENT_TO_END } comment;
        bool overflow;
        int wco_count, ovr_count; /* GRBL 1.1: reports until WCO/Ov fields come again */
        enum sim_fault fault;
        char out[GE_OUT_MAX];
        size_t n_out;
};

struct sim_gcode {
        const struct rig_config *rc;
        double time_scale;
        uint64_t epoch_ns;
        atomic_bool stop;
        struct ge_bus buses[RIG_MAX_BUSES];
        size_t n_buses;
};

static double ge_now(const struct sim_gcode *g)
{
        return (double)(gn_monotonic_ns() - g->epoch_ns) * 1e-9 * g->time_scale;
}

static bool is_grbl(const struct ge_bus *b)
{
        return b->flavor == GC_FLAVOR_GRBL;
}

/* Appends one reply line (CR LF terminated, as both firmwares end lines). */
static void say(struct ge_bus *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(struct ge_bus *b, const char *fmt, ...)
{
        size_t room = sizeof(b->out) - b->n_out;
        va_list ap;
        int n;

        va_start(ap, fmt);
        n = vsnprintf(b->out + b->n_out, room, fmt, ap);
        va_end(ap);
        if (n < 0 || (size_t)n + 2 >= room)
                return; /* nobody reads: drop, like a full serial buffer */
        memcpy(b->out + b->n_out + n, "\r\n", 2);
        b->n_out += (size_t)n + 2;
}

/* Horus 0.2 words its errors; GRBL 1.1 numbers them. */
static const char *horus_error(int code)
{
        static const char *const texts[] = {
                [ST_EXPECTED_LETTER] = "Expected command letter",
                [ST_BAD_NUMBER] = "Bad number format",
                [ST_INVALID_STATEMENT] = "Invalid statement",
                [ST_NEGATIVE] = "Value < 0",
                [ST_SETTING_DISABLED] = "Setting disabled",
                [ST_NOT_IDLE] = "Not idle",
                [ST_ALARM_LOCK] = "Alarm lock",
                [ST_OVERFLOW] = "Line overflow",
                [ST_UNSUPPORTED] = "Unsupported command",
                [ST_MODAL_VIOLATION] = "Modal group violation",
                [ST_UNDEFINED_FEED] = "Undefined feed rate",
        };

        return code > 0 && code < (int)ELEMENTSOF(texts) ? texts[code] : NULL;
}

static void reply(struct ge_bus *b, int code)
{
        const char *text = horus_error(code);

        if (code == GE_NO_REPLY)
                return;
        if (code == ST_OK)
                say(b, "ok");
        else if (is_grbl(b))
                say(b, "error:%d", code);
        else if (text)
                say(b, "error: %s", text);
        else
                say(b, "error: Invalid gcode ID:%d", code);
}

static void greet(struct ge_bus *b)
{
        say(b, "%s", "");
        say(b, "%s ['$' for help]", is_grbl(b) ? "Grbl 1.1h" : "Horus 0.2");
        if (b->alarm)
                say(b, is_grbl(b) ? "[MSG:'$H'|'$X' to unlock]" : "['$H'|'$X' to unlock]");
}

/* ---- motion ---- */

static bool axes_moving(struct ge_bus *b, double now)
{
        for (int i = 0; i < GC_N_AXES; i++)
                if (b->axes[i].conf && sim_drive_status(&b->axes[i].drive, now).moving)
                        return true;
        return false;
}

/* Whether a machine cycle runs: planned motion not held, or homing. */
static bool in_cycle(struct ge_bus *b, double now)
{
        return b->homing || (!b->hold && (b->n_plan > 0 || axes_moving(b, now)));
}

/* A position as the firmware counts it: whole steps. */
static double steps(const struct ge_axis *a, double deg)
{
        return round(deg * a->steps_per_deg) / a->steps_per_deg;
}

static void start_block(struct ge_bus *b, const struct ge_block *k, double now)
{
        for (int i = 0; i < GC_N_AXES; i++) {
                struct ge_axis *a = &b->axes[i];
                if (!a->conf || !(k->axes & 1u << i))
                        continue;
                double vmax =
                        isnan(k->vmax) ? a->conf->max_speed : fmin(k->vmax, a->conf->max_speed);
                (void)sim_drive_move(&a->drive, now, k->target[i], vmax, a->conf->accel);
        }
        b->running = true;
}

/* Runs the plan: starts the next block when the axes are at rest, answers Horus lines
 * and GRBL's $H when their motion has ended. */
static void tick_motion(struct ge_bus *b, double now)
{
        if (b->hold || axes_moving(b, now))
                return;
        if (b->homing) {
                b->homing = false;
                b->owed = 0;
                reply(b, ST_OK);
                return;
        }
        if (b->running) {
                memmove(b->plan, b->plan + 1, sizeof(b->plan[0]) * (size_t)--b->n_plan);
                b->running = false;
        }
        if (b->n_plan > 0)
                start_block(b, &b->plan[0], now);
        else if (b->owed > 0) {
                b->owed = 0;
                reply(b, ST_OK);
        }
}

/* Horus: a laser on for 255 s goes off by itself. */
static void tick_lasers(struct ge_bus *b, double now)
{
        for (int i = 0; i < GCSW_TOOL_MAX; i++)
                if (!is_grbl(b) && b->laser[i] && now - b->laser_on_at[i] >= GCSW_AUTO_OFF_S)
                        b->laser[i] = false;
}

/* ---- realtime bytes ---- */

static double fmt3(double v)
{
        return fabs(v) < 0.0005 ? 0.0 : v; /* never "-0.000" */
}

static void positions(struct ge_bus *b, double now, double pos[GC_N_AXES], double *rate)
{
        double v2 = 0;

        for (int i = 0; i < GC_N_AXES; i++) {
                struct ge_axis *a = &b->axes[i];
                pos[i] = a->conf ? fmt3(steps(a, sim_drive_position(&a->drive, now))) : 0.0;
                if (a->conf) {
                        double v = motion_velocity(&a->drive.mo, now);
                        v2 += v * v;
                }
        }
        *rate = sqrt(v2) * 60.0;
}

static const char *state_name(struct ge_bus *b, double now)
{
        if (b->alarm)
                return "Alarm";
        if (b->homing)
                return "Home";
        if (b->hold)
                return is_grbl(b) ? "Hold:0" : "Hold";
        return in_cycle(b, now) ? "Run" : "Idle";
}

/* GRBL 1.1: the work offset and override fields come every few reports only. */
static void grbl_extra_fields(struct ge_bus *b, bool busy, char *buf, size_t len)
{
        size_t o = 0;

        buf[0] = '\0';
        if (b->wco_count > 0)
                b->wco_count--;
        else {
                b->wco_count = busy ? 29 : 9;
                if (b->ovr_count == 0)
                        b->ovr_count = 1;
                o += (size_t)snprintf(buf, len, "|WCO:0.000,0.000,0.000");
        }
        if (b->ovr_count > 0)
                b->ovr_count--;
        else {
                b->ovr_count = busy ? 19 : 9;
                snprintf(buf + o, len - o, "|Ov:100,100,100");
        }
}

static void status_report(struct ge_bus *b, double now)
{
        const char *st = state_name(b, now);
        double p[GC_N_AXES], rate;
        char extra[64];

        positions(b, now, p, &rate);
        if (!is_grbl(b)) {
                say(b, "<%s,MPos:%.3f,%.3f,%.3f,WPos:%.3f,%.3f,%.3f>", st, p[0], p[1], p[2], p[0],
                    p[1], p[2]);
                return;
        }
        grbl_extra_fields(b, strcmp(st, "Idle") != 0 && strcmp(st, "Alarm") != 0, extra,
                          sizeof(extra));
        say(b, "<%s|MPos:%.3f,%.3f,%.3f|FS:%.0f,0%s>", st, p[0], p[1], p[2], rate, extra);
}

static void feed_hold(struct ge_bus *b, double now)
{
        if (b->homing || b->hold || !in_cycle(b, now))
                return;
        for (int i = 0; i < GC_N_AXES; i++)
                if (b->axes[i].conf)
                        sim_drive_stop(&b->axes[i].drive, now);
        b->hold = true;
        b->running = false; /* resumes towards plan[0]'s targets */
}

/* Ctrl-X. Motion in progress is killed: an alarm (Horus: also from a hold); the line in
 * progress is still answered "ok"; then the firmware restarts and greets. */
static void soft_reset(struct ge_bus *b, double now)
{
        bool abort = b->homing || in_cycle(b, now) || (!is_grbl(b) && b->hold);

        if (abort) {
                b->alarm = true;
                if (is_grbl(b))
                        say(b, "ALARM:%d", b->homing ? 6 : 3);
                else
                        say(b, "ALARM: Abort during cycle");
        }
        if (b->owed > 0)
                reply(b, ST_OK);
        for (int i = 0; i < GC_N_AXES; i++)
                if (b->axes[i].conf)
                        sim_drive_stop(&b->axes[i].drive, now);
        if (!is_grbl(b))
                memset(b->laser, 0, sizeof(b->laser));
        b->hold = b->homing = b->running = b->overflow = false;
        b->comment = COMMENT_NONE;
        b->owed = b->n_plan = b->wco_count = b->ovr_count = 0;
        b->n_raw = b->n_line = 0;
        b->feed = 0;
        b->linear = false;
        greet(b);
}

/* Acts on a realtime byte; returns false for a byte of a line. */
static bool realtime(struct ge_bus *b, unsigned char c, double now)
{
        switch (c) {
        case GC_RT_STATUS:
                status_report(b, now);
                return true;
        case GC_RT_HOLD:
                feed_hold(b, now);
                return true;
        case GC_RT_RESUME:
                b->hold = false;
                return true;
        case GC_RT_RESET:
                soft_reset(b, now);
                return true;
        default:
                return is_grbl(b) && c >= 0x80; /* 1.1's override bytes: not emulated */
        }
}

/* ---- lines ---- */

static int dollar(struct ge_bus *b, const char *line, double now)
{
        if (strcmp(line, "$X") == 0) {
                if (b->alarm)
                        say(b, is_grbl(b) ? "[MSG:Caution: Unlocked]" : "[Caution: Unlocked]");
                b->alarm = false;
                return ST_OK;
        }
        if (strcmp(line, "$H") != 0)
                return ST_INVALID_STATEMENT; /* settings and reports: not emulated */
        if (!is_grbl(b))
                return ST_SETTING_DISABLED; /* Horus: homing disabled */
        if (in_cycle(b, now) || b->hold)
                return ST_NOT_IDLE;
        for (int i = 0; i < GC_N_AXES; i++) {
                struct ge_axis *a = &b->axes[i];
                if (a->conf)
                        (void)sim_drive_home(&a->drive, now, a->conf->max_speed, a->conf->accel);
        }
        b->homing = true; /* the state is Home, no longer Alarm */
        b->alarm = false;
        b->owed = 1;
        return GE_NO_REPLY;
}

/* One block's words. */
struct ge_words {
        int g, m; /* -1: none */
        double f, t, xyz[GC_N_AXES];
        unsigned seen; /* bit per letter 'A'..'Z' */
};

/* Reads a number as the firmwares do: sign, digits, point, digits; no exponent, no hex. */
static bool read_number(const char *s, size_t *i, double *ret)
{
        size_t j = *i + (s[*i] == '-' || s[*i] == '+');
        size_t digits = 0;
        char num[GE_LINE_MAX];

        for (; s[j] >= '0' && s[j] <= '9'; j++)
                digits++;
        if (s[j] == '.')
                for (j++; s[j] >= '0' && s[j] <= '9'; j++)
                        digits++;
        if (!digits)
                return false;
        memcpy(num, s + *i, j - *i);
        num[j - *i] = '\0';
        *ret = strtod(num, NULL);
        *i = j;
        return true;
}

/* Which command a G or M number is, per flavor: 0 for a known one, else an error. */
static int known_command(const struct ge_bus *b, char letter, double v)
{
        int n = (int)v;

        if (v != n)
                return ST_NOT_INTEGER;
        if (letter == 'G')
                return n == 1 || (is_grbl(b) ? n == 0 : n == 50) ? 0 : ST_UNSUPPORTED;
        if (is_grbl(b))
                return ST_UNSUPPORTED; /* M codes: not emulated */
        return n == 17 || n == 18 || n == 50 || n == 70 || n == 71 ? 0 : ST_UNSUPPORTED;
}

static int word(const struct ge_bus *b, struct ge_words *w, char letter, double v)
{
        unsigned bit = 1u << (letter - 'A');
        int r;

        if (letter == 'G' || letter == 'M') {
                if ((r = known_command(b, letter, v)) != 0)
                        return r;
                if (w->seen & bit)
                        return ST_MODAL_VIOLATION;
                *(letter == 'G' ? &w->g : &w->m) = (int)v;
        } else if (letter == 'F' || letter == 'T') { /* GRBL keeps T and ignores it */
                if (w->seen & bit)
                        return ST_WORD_REPEATED;
                if (v < 0)
                        return ST_NEGATIVE;
                *(letter == 'F' ? &w->f : &w->t) = v;
        } else if (letter == 'X' || (is_grbl(b) && (letter == 'Y' || letter == 'Z'))) {
                if (w->seen & bit)
                        return ST_WORD_REPEATED;
                w->xyz[letter - 'X'] = v;
        } else
                return ST_UNSUPPORTED;
        w->seen |= bit;
        return 0;
}

static int parse_words(const struct ge_bus *b, const char *line, struct ge_words *w)
{
        *w = (struct ge_words){.g = -1, .m = -1};
        for (size_t i = 0; line[i];) {
                char letter = line[i++];
                double v;
                int r;
                if (letter < 'A' || letter > 'Z')
                        return ST_EXPECTED_LETTER;
                if (!read_number(line, &i, &v))
                        return ST_BAD_NUMBER;
                if ((r = word(b, w, letter, v)) != 0)
                        return r;
        }
        return 0;
}

#define SEEN(w, c) ((w)->seen & 1u << ((c) - 'A'))

/* Horus M codes: lasers and the light sensor. M17/M18 (stepper power) change nothing the
 * emulation shows: the firmware powers the stepper for every move anyway. */
static void m_code(struct ge_bus *b, const struct ge_words *w, double now)
{
        int tool = SEEN(w, 'T') ? (int)w->t : 0;
        int lit = 0;

        if ((w->m == 70 || w->m == 71) && tool >= 1 && tool <= GCSW_TOOL_MAX) {
                b->laser[tool - 1] = w->m == 71;
                b->laser_on_at[tool - 1] = now;
        }
        if (w->m == 50) {
                for (int i = 0; i < GCSW_TOOL_MAX; i++)
                        lit += b->laser[i];
                say(b, "%d", GE_LDR_DARK + GE_LDR_PER_LASER * lit);
        }
}

/* Plans the move of w's axis words; the axes not named keep their planned position. */
static void plan_move(struct ge_bus *b, const struct ge_words *w, double now)
{
        struct ge_block k = {.vmax = b->linear ? b->feed / 60.0 : NAN};

        for (int i = 0; i < GC_N_AXES; i++) {
                struct ge_axis *a = &b->axes[i];
                if (!SEEN(w, 'X' + i) || !a->conf)
                        continue;
                k.target[i] = steps(a, w->xyz[i]);
                k.axes |= 1u << i;
        }
        b->plan[b->n_plan++] = k;
        if (!is_grbl(b))
                b->owed = 1; /* answered when the motion has ended */
        tick_motion(b, now);
}

static int gcode(struct ge_bus *b, const char *line, double now)
{
        bool axes = false;
        struct ge_words w;
        int r = parse_words(b, line, &w);

        if (r != 0)
                return r;
        for (int i = 0; i < GC_N_AXES; i++)
                axes = axes || SEEN(&w, 'X' + i);
        if (SEEN(&w, 'F'))
                b->feed = w.f;
        if (w.g == 0 || w.g == 1)
                b->linear = w.g == 1;
        if ((w.g == 1 || (axes && b->linear)) && b->feed <= 0)
                return ST_UNDEFINED_FEED;
        if (w.g == 50)
                for (int i = 0; i < GC_N_AXES; i++)
                        if (b->axes[i].conf)
                                sim_drive_set_origin(&b->axes[i].drive, now);
        if (w.m >= 0)
                m_code(b, &w, now);
        if (axes && w.g != 50) {
                plan_move(b, &w, now);
                return is_grbl(b) ? ST_OK : GE_NO_REPLY;
        }
        return ST_OK;
}

static void execute(struct ge_bus *b, const char *line, double now)
{
        if (b->fault == SIM_FAULT_ERROR && line[0])
                reply(b, ST_UNSUPPORTED);
        else if (b->overflow)
                reply(b, ST_OVERFLOW);
        else if (!line[0]) {
                if (is_grbl(b))
                        reply(b, ST_OK); /* Horus answers nothing to an empty line */
        } else if (line[0] == '$')
                reply(b, dollar(b, line, now));
        else if (b->alarm)
                reply(b, ST_ALARM_LOCK);
        else
                reply(b, gcode(b, line, now));
}

/* Whether the firmware reads no line now. */
static bool busy(const struct ge_bus *b)
{
        return b->owed > 0 || b->homing || b->n_plan >= GE_PLAN_MAX;
}

/* Adds one byte to the line being assembled; executes it at its end. */
static void line_byte(struct ge_bus *b, char c, double now)
{
        if (c == '\n' || c == '\r') {
                b->line[b->n_line] = '\0';
                execute(b, b->line, now);
                b->n_line = 0;
                b->comment = COMMENT_NONE;
                b->overflow = false;
        } else if (b->comment) {
                if (c == ')' && b->comment == COMMENT_PAREN)
                        b->comment = COMMENT_NONE;
        } else if (c <= ' ' || c == '/') {
                /* dropped: blanks, control characters, block delete */
        } else if (c == '(') {
                b->comment = COMMENT_PAREN;
        } else if (c == ';' && is_grbl(b)) {
                b->comment = COMMENT_TO_END; /* GRBL 1.1 only */
        } else if (b->n_line >= GE_LINE_MAX - 1) {
                if (!is_grbl(b)) { /* Horus reports at once and starts over */
                        reply(b, ST_OVERFLOW);
                        b->n_line = 0;
                } else
                        b->overflow = true;
        } else
                b->line[b->n_line++] = c >= 'a' && c <= 'z' ? (char)(c - 'a' + 'A') : c;
}

/* Reads the buffered bytes as lines while the firmware would. */
static void run_lines(struct ge_bus *b, double now)
{
        size_t i = 0;

        while (i < b->n_raw && !busy(b))
                line_byte(b, b->raw[i++], now);
        memmove(b->raw, b->raw + i, b->n_raw - i);
        b->n_raw -= i;
}

/* ---- the bus thread ---- */

/* Takes in bytes received, runs the firmware's loop once and collects its replies into out
 * (at most GE_OUT_MAX); *late: they are to wait. Returns the count of bytes to write. */
static size_t step(struct ge_bus *b, const unsigned char *in, size_t n, char *out, bool *late)
{
        double now;
        size_t k;

        pthread_mutex_lock(&b->lock);
        now = ge_now(b->g);
        for (size_t i = 0; i < n && b->fault != SIM_FAULT_TIMEOUT; i++) {
                if (realtime(b, in[i], now) || b->n_raw >= sizeof(b->raw))
                        continue;
                b->raw[b->n_raw++] = (char)in[i];
                if (in[i] == '\n' || in[i] == '\r')
                        run_lines(b, now); /* before a realtime byte that came after it */
        }
        tick_lasers(b, now);
        tick_motion(b, now);
        run_lines(b, now);
        k = b->fault == SIM_FAULT_TIMEOUT ? 0 : b->n_out;
        memcpy(out, b->out, k);
        b->n_out = 0;
        *late = b->fault == SIM_FAULT_LATE;
        pthread_mutex_unlock(&b->lock);
        return k;
}

static void write_out(struct ge_bus *b, const char *p, size_t n)
{
        while (n > 0) {
                ssize_t k = write(b->pty.master, p, n);
                if (k > 0) {
                        p += k;
                        n -= (size_t)k;
                        continue;
                }
                struct pollfd pf = {.fd = b->pty.master, .events = POLLOUT};
                if ((k < 0 && errno != EAGAIN && errno != EINTR) ||
                    poll(&pf, 1, GE_WRITE_TIMEOUT) <= 0)
                        return; /* nobody reads the line: drop, as a real board would */
        }
}

/* The board loses power: the drives stop where they are, the firmware forgets everything,
 * its position counter starts again at 0 there (a Horus board has no reference; GRBL wants
 * homing again: alarm), the lasers go off. Lock held. */
static void power_cycle(struct ge_bus *b, double now)
{
        for (int i = 0; i < GC_N_AXES; i++)
                if (b->axes[i].conf) {
                        sim_drive_stop(&b->axes[i].drive, now);
                        sim_drive_set_origin(&b->axes[i].drive, now);
                }
        memset(b->laser, 0, sizeof(b->laser));
        b->alarm = is_grbl(b);
        b->hold = b->homing = b->running = b->overflow = false;
        b->comment = COMMENT_NONE;
        b->owed = b->n_plan = b->wco_count = b->ovr_count = 0;
        b->n_raw = b->n_line = b->n_out = 0;
        b->feed = 0;
        b->linear = false;
}

/* The USB cable is pulled for ms: the pty and its symlink go, the board powers down; then
 * a new pty appears at the same path and the board boots and greets. */
static void unplug(struct ge_bus *b, int ms)
{
        uint64_t end = gn_monotonic_ns() + (uint64_t)ms * 1000000u;

        log_info("G-code bus '%s': unplugged for %d ms", b->conf->name, ms);
        pthread_mutex_lock(&b->lock);
        power_cycle(b, ge_now(b->g));
        pthread_mutex_unlock(&b->lock);
        sim_pty_close(&b->pty);
        while (gn_monotonic_ns() < end && !atomic_load(&b->g->stop))
                usleep(10 * 1000);
        if (sim_pty_open(&b->pty, b->conf->port, b->conf->name) < 0) {
                log_error("G-code bus '%s': cannot plug the board back in", b->conf->name);
        } else {
                pthread_mutex_lock(&b->lock);
                greet(b);
                write_out(b, b->out, b->n_out);
                b->n_out = 0;
                pthread_mutex_unlock(&b->lock);
        }
        atomic_store(&b->unplug_ms, 0);
}

static void *bus_thread(void *userdata)
{
        struct ge_bus *b = userdata;
        char *buf = malloc(GE_OUT_MAX);
        bool late;

        while (buf && !atomic_load(&b->g->stop)) {
                int ms = atomic_load(&b->unplug_ms);
                if (ms > 0) {
                        unplug(b, ms);
                        continue;
                }
                struct pollfd pf = {.fd = b->pty.master, .events = POLLIN};
                unsigned char in[256];
                ssize_t n = 0;

                if (poll(&pf, 1, GE_POLL_MS) > 0 && (n = read(b->pty.master, in, sizeof(in))) < 0)
                        n = 0;
                size_t k = step(b, in, (size_t)n, buf, &late);
                if (k > 0 && late)
                        usleep(SIM_GCODE_LATE_MS * 1000);
                write_out(b, buf, k);
        }
        free(buf);
        return NULL;
}

/* ---- setup ---- */

static struct ge_bus *find_bus(struct sim_gcode *g, const char *name)
{
        for (size_t i = 0; i < g->n_buses; i++)
                if (strcmp(g->buses[i].conf->name, name) == 0)
                        return &g->buses[i];
        return NULL;
}

/* The controller of the bus named name, created on first use with flavor. */
static int bus_of(struct sim_gcode *g, const char *name, enum gc_flavor flavor, const char *dev,
                  struct ge_bus **ret)
{
        const struct rig_bus_conf *c = rigconf_bus(g->rc, name);
        struct ge_bus *b = find_bus(g, name);

        if (!c || c->type != RIG_BUS_SERIAL)
                return log_error_errno(SYNTHETIC_ERRNO(EINVAL),
                                       "'%s': bus '%s' is not a serial bus of the rig", dev, name);
        if (b && b->flavor != flavor)
                return log_error_errno(SYNTHETIC_ERRNO(EINVAL),
                                       "'%s': the controller on bus '%s' is %s, not %s", dev, name,
                                       gc_flavor_name(b->flavor), gc_flavor_name(flavor));
        if (!b) {
                b = &g->buses[g->n_buses++];
                *b = (struct ge_bus){.g = g, .conf = c, .flavor = flavor, .pty = SIM_PTY_NULL};
                pthread_mutex_init(&b->lock, NULL);
                b->alarm = flavor == GC_FLAVOR_GRBL; /* homing enabled: locked at power-up */
        }
        *ret = b;
        return 0;
}

static int add_axis(struct sim_gcode *g, const struct rig_axis_conf *c)
{
        const struct gcax_conf *gc = c->backend.conf;
        struct ge_bus *b;
        int r = bus_of(g, c->bus, gc->flavor, c->name, &b);

        if (r < 0)
                return r;
        struct ge_axis *a = &b->axes[gc->axis];
        *a = (struct ge_axis){.conf = c, .steps_per_deg = gc->steps_per_deg};
        /* A Horus turntable has no reference: where it powers up is the world's zero. A
         * GRBL axis homes to its switch at physical 0 from anywhere. */
        if (gc->flavor == GC_FLAVOR_HORUS)
                sim_drive_init_at(&a->drive, c, 0.0);
        else
                sim_drive_init(&a->drive, c);
        return 0;
}

static bool is_laser(const struct rig_switch_conf *c)
{
        return strcmp(c->backend.name, "gcode-laser") == 0;
}

static int add_devices(struct sim_gcode *g)
{
        const struct rig_config *rc = g->rc;
        struct ge_bus *b;
        int r = 0;

        for (size_t i = 0; r >= 0 && i < rc->n_axes; i++)
                if (strcmp(rc->axes[i].backend.name, "gcode") == 0)
                        r = add_axis(g, &rc->axes[i]);
        for (size_t i = 0; r >= 0 && i < rc->n_lamps; i++)
                if (is_laser(&rc->lamps[i]))
                        r = bus_of(g, rc->lamps[i].bus, GC_FLAVOR_HORUS, rc->lamps[i].name, &b);
        for (size_t i = 0; r >= 0 && i < rc->n_lasers; i++)
                if (is_laser(&rc->lasers[i]))
                        r = bus_of(g, rc->lasers[i].bus, GC_FLAVOR_HORUS, rc->lasers[i].name, &b);
        return r;
}

static int bus_start(struct ge_bus *b)
{
        int r = sim_pty_open(&b->pty, b->conf->port, b->conf->name);

        if (r < 0)
                return r;
        greet(b); /* at power-up, into the pty: a client opening the port flushes it */
        write_out(b, b->out, b->n_out);
        b->n_out = 0;
        r = -pthread_create(&b->thread, NULL, bus_thread, b);
        if (r < 0)
                return log_error_errno(r, "G-code bus '%s': cannot start thread: %m",
                                       b->conf->name);
        b->started = true;
        return 0;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_gcode *, sim_gcode_free);

int sim_gcode_new(const struct rig_config *rc, double time_scale, struct sim_gcode **ret)
{
        if (!rc || !ret || !(time_scale > 0.0))
                return -EINVAL;

        _cleanup_(sim_gcode_freep) struct sim_gcode *g = calloc(1, sizeof(*g));
        if (!g)
                return -ENOMEM;
        *g = (struct sim_gcode){.rc = rc, .time_scale = time_scale, .epoch_ns = gn_monotonic_ns()};
        int r = add_devices(g);
        for (size_t i = 0; r >= 0 && i < g->n_buses; i++)
                r = bus_start(&g->buses[i]);
        if (r < 0)
                return r;
        *ret = TAKE_PTR(g);
        return 0;
}

struct sim_gcode *sim_gcode_free(struct sim_gcode *g)
{
        if (!g)
                return NULL;
        atomic_store(&g->stop, true);
        for (size_t i = 0; i < g->n_buses; i++) {
                struct ge_bus *b = &g->buses[i];
                if (b->started)
                        pthread_join(b->thread, NULL);
                sim_pty_close(&b->pty);
                pthread_mutex_destroy(&b->lock);
        }
        free(g);
        return NULL;
}

/* ---- queries and faults ---- */

/* Whether switch c is a laser output of bus b that is on. */
static bool laser_on(const struct ge_bus *b, const struct rig_switch_conf *c)
{
        const struct gcsw_conf *sc = c->backend.conf;

        return is_laser(c) && strcmp(c->bus, b->conf->name) == 0 && b->laser[sc->tool - 1];
}

void sim_gcode_snapshot(struct sim_gcode *g, struct gn_pose *st)
{
        const struct rig_config *rc = g->rc;

        for (size_t i = 0; i < g->n_buses; i++) {
                struct ge_bus *b = &g->buses[i];
                pthread_mutex_lock(&b->lock);
                double now = ge_now(g);
                for (int k = 0; k < GC_N_AXES; k++) {
                        const struct rig_axis_conf *c = b->axes[k].conf;
                        if (c && c->role >= 0 && c->role < GN_ROLE_COUNT)
                                st->deg[c->role] = sim_drive_angle(&b->axes[k].drive, now);
                }
                for (size_t l = 0; l < rc->n_lamps && l < GN_POSE_MAX_LAMPS; l++)
                        st->lamps |= (uint32_t)laser_on(b, &rc->lamps[l]) << l;
                for (size_t l = 0; l < rc->n_lasers; l++)
                        st->lasers |= (uint32_t)laser_on(b, &rc->lasers[l]) << l;
                pthread_mutex_unlock(&b->lock);
        }
}

const char *sim_gcode_pty(struct sim_gcode *g, const char *bus)
{
        struct ge_bus *b = find_bus(g, bus);

        return b ? b->pty.path : NULL;
}

int sim_gcode_unplug(struct sim_gcode *g, const char *bus, int ms)
{
        struct ge_bus *b = find_bus(g, bus);
        int none = 0;

        if (!b)
                return -ENOENT;
        if (ms <= 0)
                return -EINVAL;
        return atomic_compare_exchange_strong(&b->unplug_ms, &none, ms) ? 0 : -EBUSY;
}

int sim_gcode_inject(struct sim_gcode *g, const char *bus, enum sim_fault fault)
{
        struct ge_bus *b = find_bus(g, bus);

        if (!b)
                return -ENOENT;
        if (fault != SIM_FAULT_NONE && fault != SIM_FAULT_TIMEOUT && fault != SIM_FAULT_LATE &&
            fault != SIM_FAULT_ERROR)
                return -EINVAL;
        pthread_mutex_lock(&b->lock);
        b->fault = fault;
        pthread_mutex_unlock(&b->lock);
        return 0;
}
