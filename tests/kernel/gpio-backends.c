/* gpio-backends.c - kernel lane test of the "gpio-stepper" axis and "gpio" switch backends on
 * gpio-sim's chip "gonio-gpio" (made by the lane's init). Everything is checked through
 * gpio-sim's sysfs or the kernel, never through the driver: output levels are read from
 * sim_gpioN/value, the steps are counted by a watcher thread here from the kernel's gpio_value
 * trace events of the step and dir lines (every write to a line, so no edge is missed however
 * late the thread runs; signed by dir), and the switches are worked by writing sim_gpioN/pull.
 * Cases: lamp and laser (active low, by offset) on and off; a line held twice; moves whose counted
 * steps match the driver's position; stop mid-move; a limit switch stopping a move and refusing the
 * next one into it; homing stopped by the home switch; the chip unplugged mid-move (gpio-sim's
 * configfs `live` set to 0): the move ends with -ENODEV naming the chip, the switches fail with
 * -ENODEV, reopening fails until `live` is 1 again and then drives the lines again.
 *
 * Usage: kl-gpio-backends (in the guest; exits 77 without gpio-sim's chip). */
#include <fcntl.h>
#include <glob.h>
#include <gpiod.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <sys/mount.h>
#include <time.h>

#include "common/cleanup.h"
#include "drivers/axis/axis.h"
#include "drivers/axis/gpio/proto.h"
#include "drivers/registry.h"
#include "drivers/switch/switch.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: gpio-sim\n"
        "buses:\n"
        "  - { name: io, type: local }\n"
        "axes:\n"
        "  - { name: arm, limits: [-90, 90], max_speed: 4, accel: 20,\n"
        "      gpio-stepper: { bus: io, chip: gonio-gpio, step: step, dir: dir, enable: enable,\n"
        "                      home: home, limit_min: limit, limit_max: limit_max,\n"
        "                      steps_per_deg: 10, home_speed: 3 } }\n"
        "  - { name: short, limits: [-1, 1], max_speed: 20, accel: 200,\n"
        "      gpio-stepper: { bus: io, chip: gonio-gpio, step: step, dir: dir, home: home,\n"
        "                      steps_per_deg: 10 } }\n"
        "  - { name: wrap, continuous: true, max_speed: 20, accel: 200,\n"
        "      gpio-stepper: { bus: io, chip: gonio-gpio, step: step, dir: dir,\n"
        "                      steps_per_deg: 10 } }\n"
        "  - { name: misspelt, max_speed: 4,\n"
        "      gpio-stepper: { bus: io, chip: gonio-gpio, step: stepx, dir: dir,\n"
        "                      steps_per_deg: 10 } }\n"
        "lamps:\n"
        "  - { name: lamp0, elevation: 10, gpio: { bus: io, chip: gonio-gpio, line: lamp } }\n"
        "  - { name: lamp1, elevation: 20, gpio: { bus: io, chip: gonio-gpio, line: lamp } }\n"
        "  - { name: lamp2, elevation: 30, gpio: { bus: io, chip: nochip, line: 0 } }\n"
        "laser: { name: laser, gpio: { bus: io, chip: gonio-gpio, line: 6, active_low: true } }\n";

#define STEPS_PER_DEG 10

/* gpio-sim's sysfs folder of the chip, "/sys/bus/gpio/devices/gpiochip1". */
static char sim_dir[128];
/* Offsets of the named lines on the chip. */
static struct gpiod_chip *chip;

static void sim_path(const char *line, const char *attr, char *path, size_t size)
{
        struct gpiod_line *l = gpiod_chip_find_line(chip, line);

        CHECK(l);
        snprintf(path, size, "%s/sim_gpio%u/%s", sim_dir, gpiod_line_offset(l), attr);
}

/* The level of line as gpio-sim shows it: '0' or '1'. */
static char sim_value(const char *line)
{
        char path[256], v[4] = "";
        _cleanup_fclose_ FILE *f = NULL;

        sim_path(line, "value", path, sizeof(path));
        f = fopen(path, "re");
        CHECK(f && fgets(v, sizeof(v), f));
        return v[0];
}

/* Sets the simulated pull of line: "pull-up" makes an input read 1, "pull-down" 0. */
static void sim_pull(const char *line, const char *pull)
{
        char path[256];
        _cleanup_fclose_ FILE *f = NULL;

        sim_path(line, "pull", path, sizeof(path));
        f = fopen(path, "we");
        CHECK(f && fputs(pull, f) >= 0 && fflush(f) == 0);
}

/* The step counter: a thread reading the kernel's own record of every line write, the
 * gpio_value trace events ("gpio_value: 517 set 1") of the step and dir lines. */
struct watcher {
        int pipe_fd;                  /* tracefs trace_pipe, non-blocking */
        unsigned step_gpio, dir_gpio; /* global GPIO numbers: chip base + offset */
        atomic_long count;            /* rising edges of step, +1 with dir high, -1 with dir low */
        atomic_bool quit;
        pthread_t thread;
};

#define TRACEFS "/sys/kernel/tracing"

/* Writes value to the tracefs file name. */
static void trace_write(const char *name, const char *value)
{
        char path[128];
        _cleanup_fclose_ FILE *f = NULL;

        snprintf(path, sizeof(path), TRACEFS "/%s", name);
        f = fopen(path, "we");
        CHECK(f && fputs(value, f) >= 0 && fflush(f) == 0);
}

/* Counts one trace line; *step and *dir hold the last levels written. */
static void count_event(struct watcher *w, const char *line, int *step, int *dir)
{
        const char *p = strstr(line, "gpio_value: ");
        unsigned gpio;
        char op[4];
        int v;

        if (!p || sscanf(p, "gpio_value: %u %3s %d", &gpio, op, &v) != 3 || strcmp(op, "set"))
                return;
        if (gpio == w->dir_gpio)
                *dir = v;
        if (gpio == w->step_gpio) {
                if (v == 1 && *step == 0)
                        atomic_fetch_add(&w->count, *dir ? 1 : -1);
                *step = v;
        }
}

static void *watch(void *userdata)
{
        struct watcher *w = userdata;
        struct pollfd p = {.fd = w->pipe_fd, .events = POLLIN};
        int step = sim_value("step") == '1', dir = sim_value("dir") == '1';
        char buf[8192], line[512];
        size_t len = 0;

        while (!atomic_load(&w->quit)) {
                ssize_t n;

                if (poll(&p, 1, 20) <= 0 || (n = read(w->pipe_fd, buf, sizeof(buf))) <= 0)
                        continue;
                for (ssize_t i = 0; i < n; i++) {
                        if (buf[i] != '\n') {
                                if (len < sizeof(line) - 1)
                                        line[len++] = buf[i];
                                continue;
                        }
                        line[len] = '\0';
                        count_event(w, line, &step, &dir);
                        len = 0;
                }
        }
        return NULL;
}

/* The global number of line: the base of gpio-sim's chip in /sys/class/gpio plus its offset. */
static unsigned gpio_number(const char *line)
{
        struct gpiod_line *l = gpiod_chip_find_line(chip, line);
        glob_t g = {};
        unsigned base = 0;
        bool found = false;

        CHECK(l);
        CHECK_INT(glob("/sys/class/gpio/gpiochip*", 0, NULL, &g), 0);
        for (size_t i = 0; i < g.gl_pathc && !found; i++) {
                char path[256], label[64] = "";
                _cleanup_fclose_ FILE *f = NULL;

                snprintf(path, sizeof(path), "%s/label", g.gl_pathv[i]);
                f = fopen(path, "re");
                if (!f || !fgets(label, sizeof(label), f) || strcmp(label, "gonio-gpio\n"))
                        continue;
                found = sscanf(g.gl_pathv[i], "/sys/class/gpio/gpiochip%u", &base) == 1;
        }
        globfree(&g);
        CHECK(found);
        return base + gpiod_line_offset(l);
}

static void watcher_start(struct watcher *w)
{
        char filter[64];

        if (access(TRACEFS "/trace_pipe", F_OK) < 0)
                CHECK_INT(mount("tracefs", TRACEFS, "tracefs", 0, NULL), 0);
        w->step_gpio = gpio_number("step");
        w->dir_gpio = gpio_number("dir");
        snprintf(filter, sizeof(filter), "gpio == %u || gpio == %u", w->step_gpio, w->dir_gpio);
        trace_write("events/gpio/gpio_value/filter", filter);
        trace_write("events/gpio/gpio_value/enable", "1");
        trace_write("trace", "");
        w->pipe_fd = open(TRACEFS "/trace_pipe", O_RDONLY | O_NONBLOCK | O_CLOEXEC);
        CHECK(w->pipe_fd >= 0);
        atomic_init(&w->count, 0);
        atomic_init(&w->quit, false);
        CHECK_INT(pthread_create(&w->thread, NULL, watch, w), 0);
}

static double now(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return (double)ts.tv_sec + ts.tv_nsec / 1e9;
}

static void sleep_s(double s)
{
        struct timespec ts = {(time_t)s, (long)((s - (time_t)s) * 1e9)};

        nanosleep(&ts, NULL);
}

/* Polls ax until it stops moving (at most timeout_s); returns the seconds it took. */
static double wait_stopped(struct axis *ax, double timeout_s)
{
        double t0 = now();

        do {
                CHECK_INT(axis_poll(ax), 0);
                if (!ax->state.moving)
                        return now() - t0;
                sleep_s(0.005);
        } while (now() - t0 < timeout_s);
        fprintf(stderr, "axis still moving after %.1f s\n", timeout_s);
        exit(1);
}

/* Waits until the watcher has counted to count (either sign), at most 10 s. */
static void wait_count(struct watcher *w, long count)
{
        double t0 = now();

        while (atomic_load(&w->count) != count) {
                CHECK(now() - t0 < 10.0);
                sleep_s(0.001);
        }
}

/* The watcher's count once it has read every trace event written so far (no change for
 * 100 ms): it reads the trace a little after the lines change. */
static long settled_count(struct watcher *w)
{
        double t0 = now();
        long c;

        do {
                CHECK(now() - t0 < 5.0); /* still stepping */
                c = atomic_load(&w->count);
                sleep_s(0.1);
        } while (atomic_load(&w->count) != c);
        return c;
}

/* The driver's position in steps, from its last poll. */
static long driver_steps(const struct axis *ax)
{
        return lround(ax->state.position_deg * STEPS_PER_DEG);
}

/* No step comes any more, and the watcher agrees with the driver. */
static void check_at_rest(struct axis *ax, struct watcher *w, long offset)
{
        long c = settled_count(w);

        sleep_s(0.2);
        CHECK_INT(atomic_load(&w->count), c);
        CHECK_INT(axis_poll(ax), 0);
        CHECK(!ax->state.moving);
        CHECK_INT(driver_steps(ax), c - offset);
        CHECK(sim_value("step") == '0');
}

static void test_switches(struct rig_config *rc, struct bus *b)
{
        struct sw *lamp0 = NULL, *lamp1 = NULL, *lamp2 = NULL, *laser = NULL;

        CHECK_INT(sw_new(&rc->lamps[0], b, &lamp0), 0);
        CHECK_INT(sw_new(&rc->lamps[1], b, &lamp1), 0);
        CHECK_INT(sw_new(&rc->lasers[0], b, &laser), 0);
        CHECK_INT(sw_open(lamp0), 0);
        CHECK_INT(sw_open(laser), 0);
        CHECK(sim_value("lamp") == '0');
        CHECK(sim_value("laser") == '1'); /* active low: off is high */
        for (int i = 0; i < 3; i++) {
                CHECK_INT(sw_set(lamp0, true), 0);
                CHECK(lamp0->on && sim_value("lamp") == '1');
                CHECK_INT(sw_set(laser, true), 0);
                CHECK(laser->on && sim_value("laser") == '0');
                CHECK_INT(sw_set(lamp0, false), 0);
                CHECK(!lamp0->on && sim_value("lamp") == '0');
                CHECK_INT(sw_set(laser, false), 0);
                CHECK(!laser->on && sim_value("laser") == '1');
        }
        /* a second switch on the lamp's line: the kernel refuses, the message names it */
        CHECK_INT(sw_open(lamp1), -EBUSY);
        CHECK_STR_CONTAINS(lamp1->last_error, "line lamp of gpiochip");
        CHECK_STR_CONTAINS(lamp1->last_error, "busy");
        /* no such chip */
        CHECK_INT(sw_new(&rc->lamps[2], b, &lamp2), 0);
        CHECK_INT(sw_open(lamp2), -ENOENT);
        CHECK_STR_CONTAINS(lamp2->last_error, "cannot open GPIO chip 'nochip'");
        sw_free(lamp0);
        sw_free(lamp1);
        sw_free(lamp2);
        sw_free(laser);
        printf("switches: lamp and active-low laser levels read back through gpio-sim\n");
}

/* Moves to deg and waits; the counted steps must match: the watcher counts from offset.
 * Returns the seconds from the start of the move to its end. */
static double move(struct axis *ax, struct watcher *w, double deg, long offset)
{
        double t;

        CHECK_INT(axis_move_abs(ax, deg), 0);
        t = wait_stopped(ax, 20.0);
        CHECK(ax->state.in_position && !ax->state.fault);
        CHECK_NEAR(ax->state.position_deg, deg, 1e-9);
        check_at_rest(ax, w, offset);
        printf("move to %.1f deg: %ld steps counted on gpio-sim, %.2f s\n", deg,
               atomic_load(&w->count), t);
        return t;
}

static void test_moves(struct axis *ax, struct watcher *w)
{
        struct gpst_profile p;
        double t;

        CHECK(sim_value("enable") == '1');
        move(ax, w, 5.0, 0);
        CHECK_INT(atomic_load(&w->count), 50);
        CHECK(sim_value("dir") == '1');
        /* the profile's duration, not faster: 30 steps down at 40 steps/s, 200 steps/s^2 */
        CHECK_INT(gpst_profile_init(&p, 30, 40, 200), 0);
        t = move(ax, w, 2.0, 0);
        CHECK(t >= p.total - 0.01 && t < p.total + 1.0);
        CHECK_INT(atomic_load(&w->count), 20);
        CHECK(sim_value("dir") == '0');

        /* stop mid-move: no step after stop returns */
        CHECK_INT(axis_move_abs(ax, 60.0), 0);
        wait_count(w, 60);
        CHECK_INT(axis_stop(ax), 0);
        CHECK_INT(axis_poll(ax), 0);
        CHECK(!ax->state.moving && !ax->state.in_position && !ax->state.fault);
        CHECK(atomic_load(&w->count) < 600);
        check_at_rest(ax, w, 0);
        printf("stop mid-move at %ld steps\n", atomic_load(&w->count));
}

static void test_limit(struct axis *ax, struct watcher *w)
{
        long c;

        CHECK_INT(axis_move_abs(ax, 80.0), 0);
        wait_count(w, atomic_load(&w->count) + 10);
        sim_pull("limit_max", "pull-up");
        c = atomic_load(&w->count);
        wait_stopped(ax, 1.0);
        /* stopped at the edge, not at the target: within a step (and one the watcher may not
         * have read yet when c was taken) */
        CHECK(settled_count(w) <= c + 2);
        CHECK(ax->state.fault && !ax->state.in_position);
        CHECK_INT(ax->state.fault_code, GPST_FAULT_LIMIT_MAX);
        CHECK_STR_CONTAINS(ax->last_error, "Fault 2: the limit_max switch stopped the move");
        check_at_rest(ax, w, 0);
        /* further up is refused; down is allowed */
        CHECK_INT(axis_move_abs(ax, 85.0), -ERANGE);
        CHECK_STR_CONTAINS(ax->last_error, "limit_max switch is made");
        CHECK_INT(axis_move_abs(ax, ax->state.position_deg), 0); /* going nowhere is fine */
        wait_stopped(ax, 1.0);
        CHECK(ax->state.in_position);
        sim_pull("limit_max", "pull-down");
        CHECK_INT(axis_reset(ax), 0);
        CHECK_INT(axis_poll(ax), 0);
        CHECK(!ax->state.fault);
        printf("limit_max stopped the move at %ld steps\n", atomic_load(&w->count));
}

static void test_home(struct axis *ax, struct watcher *w)
{
        long start = atomic_load(&w->count), c;

        CHECK(!ax->state.homed);
        CHECK_INT(axis_home(ax), 0);
        wait_count(w, start - 20); /* moving down, towards the switch */
        sim_pull("home", "pull-up");
        c = atomic_load(&w->count);
        wait_stopped(ax, 1.0);
        CHECK(settled_count(w) >= c - 2); /* as for the limit switch */
        CHECK(ax->state.homed && ax->state.in_position && !ax->state.fault);
        CHECK_NEAR(ax->state.position_deg, 0.0, 0);
        c = atomic_load(&w->count);
        check_at_rest(ax, w, c);
        sim_pull("home", "pull-down");
        move(ax, w, 3.0, c);
        CHECK_INT(atomic_load(&w->count) - c, 30);
        printf("homing stopped by the home switch after %ld steps\n", start - c);
}

/* Homing that never meets the switch ends after the whole range and some, with a fault; an
 * axis whose line does not exist fails to open, naming it. */
static void test_home_missing(struct rig_config *rc, struct bus *b, struct watcher *w)
{
        struct axis *ax = NULL, *bad = NULL;
        long c = atomic_load(&w->count);

        CHECK_INT(axis_new(&rc->axes[1], b, &ax), 0);
        CHECK_INT(axis_open(ax), 0);
        CHECK_INT(axis_home(ax), 0);
        wait_stopped(ax, 5.0);
        CHECK(ax->state.fault && !ax->state.homed && !ax->state.in_position);
        CHECK_INT(ax->state.fault_code, GPST_FAULT_HOME_MISSING);
        CHECK_STR_CONTAINS(ax->last_error, "without the home switch");
        CHECK_INT(settled_count(w) - c, -124); /* (1.2 x 2 deg + 10 deg) x 10 steps/deg */
        axis_free(ax);
        CHECK_INT(axis_new(&rc->axes[3], b, &bad), 0);
        CHECK_INT(axis_open(bad), -ENOENT);
        CHECK_STR_CONTAINS(bad->last_error, "no line named 'stepx' on gpiochip");
        axis_free(bad);
        printf("homing without the switch ended after %ld steps\n", c - atomic_load(&w->count));
}

/* A continuous axis goes the shortest way round: 0 -> 359 is one degree down, 359 -> 1 two up. */
static void test_wrap(struct rig_config *rc, struct bus *b, struct watcher *w)
{
        struct axis *ax = NULL;
        long c = atomic_load(&w->count);

        CHECK_INT(axis_new(&rc->axes[2], b, &ax), 0);
        CHECK_INT(axis_open(ax), 0);
        CHECK_INT(axis_move_abs(ax, 359.0), 0);
        wait_stopped(ax, 5.0);
        CHECK(ax->state.in_position);
        CHECK_NEAR(ax->state.position_deg, 359.0, 1e-9);
        CHECK_INT(settled_count(w) - c, -10);
        CHECK_INT(axis_move_abs(ax, 1.0), 0);
        wait_stopped(ax, 5.0);
        CHECK_NEAR(ax->state.position_deg, 1.0, 1e-9);
        CHECK_INT(settled_count(w) - c, 10);
        axis_free(ax);
        printf("continuous axis: the shortest way round across 0 deg\n");
}

/* Finds gpio-sim's chip, or exits 77. */
static void find_chip(void)
{
        if (chip)
                gpiod_chip_close(chip);
        chip = gpiod_chip_open_lookup("gonio-gpio");
        if (!chip) {
                fprintf(stderr, "no gpio-sim chip 'gonio-gpio' (run in the kernel lane)\n");
                exit(TEST_SKIP);
        }
        snprintf(sim_dir, sizeof(sim_dir), "/sys/bus/gpio/devices/%s", gpiod_chip_name(chip));
        for (const char *l = "home\0limit\0limit_max\0"; *l; l += strlen(l) + 1)
                sim_pull(l, "pull-down");
}

/* Unplugs (0) or plugs back (1) gpio-sim's chip: its configfs device's `live`. */
#define SIM_LIVE "/sys/kernel/config/gpio-sim/gonio/live"

static void sim_live(const char *v)
{
        _cleanup_fclose_ FILE *f = fopen(SIM_LIVE, "we");

        CHECK(f && fputs(v, f) >= 0 && fflush(f) == 0);
}

/* At exit, a failed check included: the chip plugged in again for the lane's next test. */
static void plug_back(void)
{
        _cleanup_fclose_ FILE *f = fopen(SIM_LIVE, "we");

        if (f)
                fputs("1", f);
}

/* Polls ax until it fails, at most timeout_s; returns the error and the seconds it took. */
static int wait_failed(struct axis *ax, double timeout_s, double *took)
{
        double t0 = now();
        int r;

        while ((r = axis_poll(ax)) == 0 && now() - t0 < timeout_s)
                sleep_s(0.005);
        *took = now() - t0;
        return r;
}

/* The chip vanishes mid-move and comes back (perhaps as another gpiochipN): every op fails
 * with -ENODEV naming it until then, open (what fault.clear calls) reopens it by its label. */
static void test_unplug(struct rig_config *rc, struct bus *b)
{
        struct axis *ax = NULL;
        struct sw *lamp = NULL;
        double took;

        CHECK_INT(axis_new(&rc->axes[0], b, &ax), 0);
        CHECK_INT(sw_new(&rc->lamps[0], b, &lamp), 0);
        CHECK_INT(axis_open(ax), 0);
        CHECK_INT(sw_open(lamp), 0);
        CHECK_INT(sw_set(lamp, true), 0);
        CHECK_INT(atexit(plug_back), 0);
        CHECK_INT(axis_move_abs(ax, 60.0), 0);
        for (double t0 = now(); ax->state.position_deg < 1.0; sleep_s(0.01)) {
                CHECK(now() - t0 < 5.0);
                CHECK_INT(axis_poll(ax), 0);
        }
        sim_live("0");
        CHECK_INT(wait_failed(ax, 1.0, &took), -ENODEV);
        CHECK_STR_CONTAINS(ax->last_error, "axis 'arm'");
        CHECK_STR_CONTAINS(ax->last_error, "GPIO chip 'gonio-gpio' (gpiochip");
        CHECK_STR_CONTAINS(ax->last_error, "is gone (unplugged?) while stepping");
        CHECK_INT(axis_move_abs(ax, 0.0), -ENODEV);
        CHECK_INT(axis_stop(ax), -ENODEV);
        CHECK_INT(sw_set(lamp, false), -ENODEV);
        CHECK_STR_CONTAINS(lamp->last_error, "switch 'lamp0'");
        CHECK_STR_CONTAINS(lamp->last_error, "is gone (unplugged?) while writing line lamp");
        CHECK_INT(sw_open(lamp), -ENODEV);
        CHECK_STR_CONTAINS(lamp->last_error, "GPIO chip 'gonio-gpio' is still gone");
        CHECK_INT(axis_open(ax), -ENODEV);
        printf("unplugged mid-move: the move ended with -ENODEV in %.3f s\n", took);

        sim_live("1");
        find_chip();
        CHECK_INT(sw_open(lamp), 0);
        CHECK(!lamp->on && sim_value("lamp") == '0');
        CHECK_INT(sw_set(lamp, true), 0);
        CHECK(sim_value("lamp") == '1');
        CHECK_INT(axis_open(ax), 0);
        CHECK(!ax->state.homed && !ax->state.fault && sim_value("enable") == '1');
        CHECK_INT(axis_move_abs(ax, ax->state.position_deg + 0.5), 0);
        wait_stopped(ax, 5.0);
        CHECK(ax->state.in_position && sim_value("dir") == '1' && sim_value("step") == '0');
        axis_free(ax);
        sw_free(lamp);
        CHECK(sim_value("enable") == '0' && sim_value("lamp") == '0');
        printf("plugged back as %s: lines driven again, the axis unhomed\n", sim_dir);
}

int main(void)
{
        char path[128] = "/tmp/gonio-gpio-rig.yaml", err[512];
        struct rig_config *rc = NULL;
        struct watcher w = {};
        struct bus *b = NULL;
        struct axis *ax = NULL;
        FILE *f;

        find_chip();
        f = fopen(path, "we");
        CHECK(f && fputs(rig_yaml, f) >= 0 && fclose(f) == 0);
        if (rigconf_load(path, registry_backends, &rc, err, sizeof(err)) < 0)
                fprintf(stderr, "%s\n", err), exit(1);
        CHECK_INT(bus_new_sync(rigconf_bus(rc, "io"), &b), 0);
        test_switches(rc, b);
        watcher_start(&w);
        CHECK_INT(axis_new(&rc->axes[0], b, &ax), 0);
        CHECK_INT(axis_open(ax), 0);
        test_moves(ax, &w);
        test_limit(ax, &w);
        test_home(ax, &w);
        axis_free(ax);
        CHECK(sim_value("enable") == '0');
        test_home_missing(rc, b, &w);
        test_wrap(rc, b, &w);
        atomic_store(&w.quit, true);
        pthread_join(w.thread, NULL);
        close(w.pipe_fd);
        trace_write("events/gpio/gpio_value/enable", "0");
        test_unplug(rc, b);
        unlink(path);
        bus_free(b);
        rigconf_free(rc);
        gpiod_chip_close(chip);
        return 0;
}
