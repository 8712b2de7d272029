/* gpio-sim.c - kernel lane self-test: gpio-sim's named lines through libgpiod 1.6's C API, each
 * result checked by something other than libgpiod: an output set by libgpiod reads back through
 * gpio-sim's sysfs "value" attribute, and a pull change written to gpio-sim's sysfs "pull"
 * attribute of an input produces the matching edge event in libgpiod. The seed of gonio's GPIO
 * axis and switch backends and of their tests.
 *
 * Usage: kl-gpio-sim (the lane's init creates the chip "gonio-gpio" with the lines used here). */
#include <gpiod.h>
#include <time.h>

#include "common/cleanup.h"
#include "tests/test.h"

static const char *const line_names[] = {"step", "dir", "enable", "home", "limit", "lamp", "laser"};

/* Path of gpio-sim's attribute attr ("value", "pull") for line. */
static void sim_attr_path(struct gpiod_line *line, const char *attr, char *path, size_t size)
{
        snprintf(path, size, "/sys/bus/gpio/devices/%s/sim_gpio%u/%s",
                 gpiod_chip_name(gpiod_line_get_chip(line)), gpiod_line_offset(line), attr);
}

static int sim_read(struct gpiod_line *line, const char *attr, char *buf, size_t size)
{
        char path[256];
        _cleanup_fclose_ FILE *f = NULL;

        sim_attr_path(line, attr, path, sizeof(path));
        f = fopen(path, "re");
        if (!f || !fgets(buf, (int)size, f))
                return -errno;
        buf[strcspn(buf, "\n")] = '\0';
        return 0;
}

static int sim_write(struct gpiod_line *line, const char *attr, const char *value)
{
        char path[256];
        _cleanup_fclose_ FILE *f = NULL;

        sim_attr_path(line, attr, path, sizeof(path));
        f = fopen(path, "we");
        if (!f || fputs(value, f) < 0 || fflush(f) != 0)
                return -errno;
        return 0;
}

static void check_output(const char *name)
{
        struct gpiod_line *line = gpiod_line_find(name);
        char v[16];

        CHECK(line);
        CHECK_INT(gpiod_line_request_output(line, "kl-gpio-sim", 0), 0);
        CHECK_INT(sim_read(line, "value", v, sizeof(v)), 0);
        CHECK_STR(v, "0");
        for (int i = 0; i < 3; i++) {
                CHECK_INT(gpiod_line_set_value(line, 1), 0);
                CHECK_INT(sim_read(line, "value", v, sizeof(v)), 0);
                CHECK_STR(v, "1");
                CHECK_INT(gpiod_line_set_value(line, 0), 0);
                CHECK_INT(sim_read(line, "value", v, sizeof(v)), 0);
                CHECK_STR(v, "0");
        }
        gpiod_line_close_chip(line);
        printf("%s: output read back through gpio-sim\n", name);
}

/* Changes the simulated pull of line and expects one edge event of type within 2 s. */
static void expect_edge(struct gpiod_line *line, const char *pull, int type)
{
        struct timespec timeout = {.tv_sec = 2};
        struct gpiod_line_event ev;

        CHECK_INT(sim_write(line, "pull", pull), 0);
        CHECK_INT(gpiod_line_event_wait(line, &timeout), 1);
        CHECK_INT(gpiod_line_event_read(line, &ev), 0);
        CHECK_INT(ev.event_type, type);
        CHECK_INT(gpiod_line_get_value(line), type == GPIOD_LINE_EVENT_RISING_EDGE);
}

static void check_input(const char *name)
{
        struct gpiod_line *line = gpiod_line_find(name);
        struct timespec none = {0};

        CHECK(line);
        CHECK_INT(sim_write(line, "pull", "pull-down"), 0);
        CHECK_INT(gpiod_line_request_both_edges_events(line, "kl-gpio-sim"), 0);
        CHECK_INT(gpiod_line_get_value(line), 0);
        expect_edge(line, "pull-up", GPIOD_LINE_EVENT_RISING_EDGE);
        expect_edge(line, "pull-down", GPIOD_LINE_EVENT_FALLING_EDGE);
        CHECK_INT(gpiod_line_event_wait(line, &none), 0);
        gpiod_line_close_chip(line);
        printf("%s: edge events on simulated pull changes\n", name);
}

int main(void)
{
        for (size_t i = 0; i < sizeof(line_names) / sizeof(line_names[0]); i++) {
                struct gpiod_line *line = gpiod_line_find(line_names[i]);

                CHECK(line);
                CHECK_STR(gpiod_chip_label(gpiod_line_get_chip(line)), "gonio-gpio");
                gpiod_line_close_chip(line);
        }
        check_output("lamp");
        check_output("step");
        check_input("home");
        check_input("limit");
        return 0;
}
