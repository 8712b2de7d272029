/* api.c - the "gpio-stepper" axis backend: a stepper driver on step/dir/enable GPIO lines with home
 * and limit switches as inputs with edge events, through drivers/gpio/gpiod.h (libgpiod 1.6).
 *
 * DESIGN: each axis has a step thread while it moves. move_abs and home (on the bus worker)
 * set the dir line, check the switches, start the thread and return; poll reads the position
 * the thread counts, in steps, as it issues them. The thread times each step on
 * CLOCK_MONOTONIC from the trapezoidal schedule of proto.c (the axis's speed and accel;
 * home_speed when homing), 50 % duty, and waits between two edges in ppoll() on the request's
 * edge-event fd and an eventfd: a switch edge or a stop wakes it at once. A thread that wakes
 * late shifts the rest of its schedule instead of catching up, so the step rate never exceeds
 * the profile (a stepper would stall). stop signals the eventfd and joins the thread: when it
 * returns no further step comes. The switches end a run: the home switch ends homing (the
 * position becomes 0), a limit switch in the direction of motion stops it with a fault (code
 * GPST_FAULT_LIMIT_*), and a move into a limit switch that is already made is refused. The
 * state shared with the thread sits under one mutex, never held across I/O.
 *
 * A chip that vanishes (a USB expander unplugged) ends the run at the next line the thread
 * writes or the hang-up of its edge-event fd; from then on every op fails with -ENODEV and
 * says so (poll: "is gone while stepping"; idle polls read a line to notice it), and open
 * (fault.clear) requests the lines again once the chip is back, unhomed: the steps the axis
 * made meanwhile are unknown. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>

#include "common/log.h"
#include "drivers/axis/gpio/proto.h"
#include "drivers/gpio/gpiod.h"

#define NSEC_PER_SEC 1000000000LL
/* Lateness of a step beyond which the rest of the schedule shifts. */
#define SLIP_NS 200000LL

/* How a run of the step thread ended. */
enum run_end { RUN_DONE, RUN_STOPPED, RUN_HOME, RUN_LIMIT_MIN, RUN_LIMIT_MAX, RUN_IO };

struct gpst {
        const struct gpst_conf *conf; /* borrowed from the rig config */
        struct gpio_request *req;
        int idx[GPST_N_LINES]; /* index of each role in req, -1 when not wired */
        int stop_fd;           /* eventfd: stop the step thread */
        pthread_t thread;
        bool running; /* a thread was started and not joined yet (worker only) */
        /* the run of the thread, set before it starts */
        struct gpst_profile prof;
        int dir; /* +1 upwards, -1 downwards, 0 no move (no limit switch applies) */
        bool homing;
        int logged_fault;     /* the fault code poll last logged (worker only) */
        pthread_mutex_t lock; /* guards what follows */
        int64_t pos;          /* steps */
        bool moving, homed, in_position;
        int fault_code;
};

static const struct opt_desc gpst_opts[] = {
        {OPT_POSITION, OPT_GET | OPT_SET, .unit = "deg"},
        {OPT_HOME, OPT_SET},
        {OPT_STOP, OPT_SET},
};

static int64_t now_ns(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return ts.tv_sec * NSEC_PER_SEC + ts.tv_nsec;
}

/* The logical level of role l: 1 made, 0 open or not wired, or -errno. */
static int level(struct gpst *g, enum gpst_line l)
{
        return g->idx[l] < 0 ? 0 : gpio_request_get_value(g->req, (size_t)g->idx[l]);
}

static int set_line(struct gpst *g, enum gpst_line l, int v)
{
        return g->idx[l] < 0 ? 0 : gpio_request_set_value(g->req, (size_t)g->idx[l], v);
}

/* -ENODEV with the cause when the chip is gone (found while doing what), else 0. */
static int gone(struct axis *ax, const char *what)
{
        struct gpst *g = ax->priv;
        char buf[GPIO_ERR_MAX + 64];

        if (!gpio_request_lost_cause(g->req, what, buf, sizeof(buf)))
                return 0;
        return axis_set_cause(ax, SYNTHETIC_ERRNO(ENODEV), "%s", buf);
}

/* What the switches say about the run set up in g: the end they force, or RUN_DONE (go on). */
static enum run_end switches(struct gpst *g)
{
        int home = level(g, GPST_HOME), lo = level(g, GPST_LIMIT_MIN),
            hi = level(g, GPST_LIMIT_MAX);

        if (home < 0 || lo < 0 || hi < 0)
                return RUN_IO;
        if (g->homing && home)
                return RUN_HOME;
        if (g->dir < 0 && lo)
                return RUN_LIMIT_MIN;
        if (g->dir > 0 && hi)
                return RUN_LIMIT_MAX;
        return RUN_DONE;
}

/* Waits until deadline (CLOCK_MONOTONIC ns) unless a stop or a switch ends the run first. */
static enum run_end wait_until(struct gpst *g, int64_t deadline)
{
        struct pollfd p[2] = {{.fd = g->stop_fd, .events = POLLIN},
                              {.fd = gpio_request_fd(g->req), .events = POLLIN}};
        struct gpio_edge_event ev[8];
        enum run_end e;

        for (int64_t left; (left = deadline - now_ns()) > 0;) {
                struct timespec ts = {left / NSEC_PER_SEC, left % NSEC_PER_SEC};

                if (ppoll(p, 2, &ts, NULL) < 0 && errno != EINTR)
                        return RUN_IO;
                if (p[0].revents)
                        return RUN_STOPPED;
                if (!(p[1].revents & POLLIN))
                        continue;
                if (gpio_request_read_edge_events(g->req, ev, ELEMENTSOF(ev)) < 0)
                        return RUN_IO;
                if ((e = switches(g)) != RUN_DONE)
                        return e;
        }
        return RUN_DONE;
}

/* One step pulse: the rising edge (counted at once), high for half_ns, then low. */
static enum run_end step(struct gpst *g, int64_t half_ns)
{
        enum run_end e;

        if (set_line(g, GPST_STEP, 1) < 0)
                return RUN_IO;
        pthread_mutex_lock(&g->lock);
        g->pos += g->dir;
        pthread_mutex_unlock(&g->lock);
        e = wait_until(g, now_ns() + half_ns);
        return set_line(g, GPST_STEP, 0) < 0 ? RUN_IO : e;
}

/* Records how the run ended, for poll. */
static void finish(struct gpst *g, enum run_end e)
{
        static const int fault[] = {[RUN_LIMIT_MIN] = GPST_FAULT_LIMIT_MIN,
                                    [RUN_LIMIT_MAX] = GPST_FAULT_LIMIT_MAX,
                                    [RUN_IO] = GPST_FAULT_IO};

        pthread_mutex_lock(&g->lock);
        if (e == RUN_HOME) {
                g->pos = 0;
                g->homed = true;
        }
        g->in_position = e == RUN_HOME || (e == RUN_DONE && !g->homing);
        g->fault_code = e == RUN_DONE && g->homing      ? GPST_FAULT_HOME_MISSING
                        : (size_t)e < ELEMENTSOF(fault) ? fault[e]
                                                        : GPST_FAULT_NONE;
        g->moving = false;
        pthread_mutex_unlock(&g->lock);
}

/* The step thread: runs g->prof in direction g->dir until its end, a stop or a switch. */
static void *run(void *userdata)
{
        struct gpst *g = userdata;
        const struct gpst_profile *p = &g->prof;
        int64_t start = now_ns();
        enum run_end e = switches(g);

        for (long k = 1; e == RUN_DONE && k <= p->n; k++) {
                double t = gpst_step_time(p, k);
                double next =
                        k < p->n ? gpst_step_time(p, k + 1) : 2 * t - gpst_step_time(p, k - 1);
                int64_t due = start + (int64_t)(t * 1e9), late;

                e = wait_until(g, due);
                if (e != RUN_DONE)
                        break;
                late = now_ns() - due;
                if (late > SLIP_NS)
                        start += late;
                e = step(g, (int64_t)((next - t) * 0.5e9));
        }
        finish(g, e);
        return NULL;
}

/* Stops the step thread, if any, and joins it: no step comes after this returns. */
static void stop_thread(struct gpst *g)
{
        uint64_t v = 1;

        if (!g->running)
                return;
        if (write(g->stop_fd, &v, sizeof(v)) < 0)
                (void)log_warning_errno(errno, "gpio axis: cannot signal the step thread: %m");
        pthread_join(g->thread, NULL);
        if (read(g->stop_fd, &v, sizeof(v)) < 0 && errno != EAGAIN)
                (void)log_warning_errno(errno, "gpio axis: cannot clear the stop signal: %m");
        g->running = false;
}

/* Starts a run of n steps in direction dir (-1, 0 with n 0, 1) at speed deg/s (homing: until
 * the home switch). */
static int start(struct axis *ax, int dir, long n, double speed, bool homing)
{
        struct gpst *g = ax->priv;
        double spd = g->conf->steps_per_deg;
        enum run_end e;
        int r;

        stop_thread(g);
        r = gpst_profile_init(&g->prof, n, speed * spd, ax->accel * spd);
        if (r < 0)
                return axis_set_cause(ax, r, "speed %.3f deg/s is not > 0", speed);
        g->dir = dir;
        g->homing = homing;
        r = set_line(g, GPST_DIR, dir > 0);
        if (r < 0)
                return gpio_request_lost(g->req) ? gone(ax, "setting the dir line")
                                                 : axis_set_cause(ax, r, "set dir line %s: %m",
                                                                  g->conf->lines[GPST_DIR]);
        e = switches(g);
        if (e == RUN_LIMIT_MIN || e == RUN_LIMIT_MAX)
                return axis_set_cause(
                        ax, SYNTHETIC_ERRNO(ERANGE), "the %s switch is made: no move %s",
                        gpst_line_keys[e == RUN_LIMIT_MIN ? GPST_LIMIT_MIN : GPST_LIMIT_MAX],
                        dir > 0 ? "upwards" : "downwards");
        pthread_mutex_lock(&g->lock);
        g->moving = true;
        g->in_position = false;
        g->fault_code = GPST_FAULT_NONE;
        pthread_mutex_unlock(&g->lock);
        r = -pthread_create(&g->thread, NULL, run, g);
        if (r < 0) {
                finish(g, RUN_STOPPED);
                return axis_set_cause(ax, r, "cannot start the step thread: %m");
        }
        g->running = true;
        return 0;
}

static int gpst_move_abs(struct axis *ax, double deg)
{
        struct gpst *g = ax->priv;
        int64_t cur, target;
        int r;

        if (!g)
                return -ENOTCONN;
        stop_thread(g);
        pthread_mutex_lock(&g->lock);
        cur = g->pos;
        pthread_mutex_unlock(&g->lock);
        r = ax->conf->continuous
                    ? gpst_travel_steps(g->conf->steps_per_deg, cur,
                                        axis_travel(ax->conf, cur / g->conf->steps_per_deg, deg),
                                        &target)
                    : gpst_deg_to_steps(g->conf->steps_per_deg, deg, &target);
        if (r < 0)
                return axis_set_cause(ax, r, "%.3f deg is beyond the step counter", deg);
        return start(ax, (target > cur) - (target < cur), (long)llabs(target - cur), ax->speed,
                     false);
}

/* Homing travels at most this far: the whole range and some, or a turn and some. */
static double home_travel(const struct rig_axis_conf *c)
{
        return c->continuous ? 400.0 : 1.2 * (c->max_deg - c->min_deg) + 10.0;
}

static int gpst_home(struct axis *ax)
{
        struct gpst *g = ax->priv;
        double speed;

        if (!g)
                return -ENOTCONN;
        if (g->idx[GPST_HOME] < 0)
                return axis_set_cause(ax, SYNTHETIC_ERRNO(EOPNOTSUPP), "no home switch wired");
        speed = g->conf->home_speed > 0 ? g->conf->home_speed : ax->conf->max_speed / 2;
        return start(ax, g->conf->home_dir,
                     (long)ceil(home_travel(ax->conf) * g->conf->steps_per_deg), speed, true);
}

static int gpst_stop(struct axis *ax)
{
        if (!ax->priv)
                return -ENOTCONN;
        stop_thread(ax->priv);
        return gone(ax, "stopping"); /* no step comes either way */
}

static int gpst_reset(struct axis *ax)
{
        struct gpst *g = ax->priv;

        if (!g)
                return -ENOTCONN;
        pthread_mutex_lock(&g->lock);
        if (!g->moving)
                g->fault_code = GPST_FAULT_NONE;
        pthread_mutex_unlock(&g->lock);
        return gone(ax, "resetting the fault");
}

/* Logs a new fault once, in words, for the operator (poll still reports it as a code). */
static void log_fault(struct axis *ax, const struct axis_state *st)
{
        static const char *const what[] = {
                [GPST_FAULT_LIMIT_MIN] = "the limit_min switch stopped the move",
                [GPST_FAULT_LIMIT_MAX] = "the limit_max switch stopped the move",
                [GPST_FAULT_HOME_MISSING] = "homing travelled its whole range without the "
                                            "home switch",
                [GPST_FAULT_IO] = "a line could not be written while stepping",
        };
        struct gpst *g = ax->priv;

        if (st->fault_code == g->logged_fault)
                return;
        g->logged_fault = st->fault_code;
        if (st->fault_code > 0 && (size_t)st->fault_code < ELEMENTSOF(what))
                axis_log_full(ax, GN_LOG_WARNING, 0, "Fault %d: %s, at %.3f deg", st->fault_code,
                              what[st->fault_code], st->position_deg);
}

static int gpst_poll(struct axis *ax, struct axis_state *st)
{
        struct gpst *g = ax->priv;
        int64_t pos;
        int r;

        if (!g)
                return -ENOTCONN;
        pthread_mutex_lock(&g->lock);
        pos = g->pos;
        *st = (struct axis_state){.enabled = true,
                                  .homed = g->homed,
                                  .moving = g->moving,
                                  .in_position = g->in_position,
                                  .fault = g->fault_code != GPST_FAULT_NONE,
                                  .fault_code = g->fault_code};
        pthread_mutex_unlock(&g->lock);
        if (!st->moving) {
                stop_thread(g);            /* joins a thread that has ended */
                (void)level(g, GPST_STEP); /* an idle axis notices a vanished chip */
                r = gone(ax, st->fault_code != GPST_FAULT_IO ? "polling"
                             : g->homing                     ? "homing"
                                                             : "stepping");
                if (r < 0)
                        return r;
        }
        st->position_deg = gpst_steps_to_deg(g->conf->steps_per_deg, pos, ax->conf->continuous);
        log_fault(ax, st);
        return 0;
}

/* Fills the settings of the wired lines and their index in the request; returns how many. */
static size_t line_settings(struct gpst *g, struct gpio_line_settings *s)
{
        size_t n = 0;

        for (int l = 0; l < GPST_N_LINES; l++) {
                g->idx[l] = -1;
                if (!g->conf->lines[l][0])
                        continue;
                s[n] = (struct gpio_line_settings){
                        .line = g->conf->lines[l],
                        .direction = l <= GPST_ENABLE ? GPIO_OUTPUT : GPIO_INPUT,
                        .active_low = g->conf->active_low[l],
                        .edge_events = l > GPST_ENABLE,
                        .output_value = l == GPST_ENABLE,
                };
                g->idx[l] = (int)n++;
        }
        return n;
}

static void gpst_close(struct axis *ax)
{
        struct gpst *g = ax->priv;

        if (!g)
                return;
        stop_thread(g);
        (void)set_line(g, GPST_ENABLE, 0); /* de-energise the motor */
        gpio_request_release(g->req);
        if (g->stop_fd >= 0)
                close(g->stop_fd);
        pthread_mutex_destroy(&g->lock);
        free(g);
        ax->priv = NULL;
}

/* Requests the lines again once a vanished chip is back (fault.clear); the axis is no longer
 * homed: the steps it made meanwhile went unseen. */
static int reopen(struct axis *ax)
{
        struct gpst *g = ax->priv;
        char err[GPIO_ERR_MAX] = "";
        int r;

        if (!gpio_request_lost(g->req))
                return 0;
        stop_thread(g);
        r = gpio_request_reopen(&g->req, err, sizeof(err));
        if (r < 0)
                return axis_set_cause(ax, r, "%s", err);
        pthread_mutex_lock(&g->lock);
        g->homed = g->in_position = false;
        g->fault_code = GPST_FAULT_NONE;
        pthread_mutex_unlock(&g->lock);
        g->logged_fault = GPST_FAULT_NONE;
        return 0;
}

static int gpst_open(struct axis *ax)
{
        const struct gpst_conf *c = ax->conf->backend.conf;
        struct gpio_line_settings s[GPST_N_LINES];
        char err[GPIO_ERR_MAX] = "";
        struct gpst *g;
        int r;

        if (ax->priv)
                return reopen(ax);
        if (!c)
                return axis_set_cause(ax, SYNTHETIC_ERRNO(EINVAL),
                                      "no GPIO settings (not loaded from a rig file)");
        if (!(ax->conf->max_speed > 0))
                return axis_set_cause(ax, SYNTHETIC_ERRNO(EINVAL), "max_speed must be > 0");
        g = calloc(1, sizeof(*g));
        if (!g)
                return -ENOMEM;
        *g = (struct gpst){.conf = c, .stop_fd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK)};
        pthread_mutex_init(&g->lock, NULL);
        ax->priv = g;
        if (g->stop_fd < 0)
                r = axis_set_cause(ax, errno, "eventfd: %m");
        else if ((r = gpio_request_lines(c->chip, ax->conf->name, s, line_settings(g, s), &g->req,
                                         err, sizeof(err))) < 0)
                axis_set_cause(ax, r, "%s", err);
        if (r < 0)
                gpst_close(ax);
        return r;
}

const struct rig_backend gpst_backend = {
        .name = "gpio-stepper",
        .cls = RIG_CLASS_AXIS,
        .bus_types = 1u << RIG_BUS_LOCAL,
        .conf_size = sizeof(struct gpst_conf),
        .parse_conf = gpst_parse_conf,
        .ops = &gpst_ops,
};

const struct axis_ops gpst_ops = {
        .name = "gpio-stepper",
        .opts = gpst_opts,
        .n_opts = ELEMENTSOF(gpst_opts),
        .open = gpst_open,
        .close = gpst_close,
        .home = gpst_home,
        .move_abs = gpst_move_abs,
        .stop = gpst_stop,
        .reset = gpst_reset,
        .poll = gpst_poll,
};
