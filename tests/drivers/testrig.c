/* testrig.c - temp-dir rig files and emulators for the driver tests (see testrig.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "common/clock.h"
#include "drivers/registry.h"
#include "drivers/transport/transport.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

/* Copies yaml to f with each "@DIR@" replaced by dir. */
static void write_expanded(FILE *f, const char *yaml, const char *dir)
{
        const char *p = yaml, *at;

        while ((at = strstr(p, "@DIR@"))) {
                fwrite(p, 1, (size_t)(at - p), f);
                fputs(dir, f);
                p = at + 5;
        }
        fputs(p, f);
}

void testrig_start(struct testrig *t, const char *yaml)
{
        char path[128], err[512];
        FILE *f;
        int r;

        memset(t, 0, sizeof(*t));
        snprintf(t->dir, sizeof(t->dir), "/tmp/gonio-drivers-XXXXXX");
        CHECK(mkdtemp(t->dir) != NULL);
        snprintf(path, sizeof(path), "%s/rig.yaml", t->dir);
        f = fopen(path, "we");
        CHECK(f != NULL);
        write_expanded(f, yaml, t->dir);
        CHECK(fclose(f) == 0);

        r = rigconf_load(path, registry_backends, &t->rc, err, sizeof(err));
        if (r < 0)
                fprintf(stderr, "%s\n", err);
        CHECK_INT(r, 0);
        CHECK_INT(sim_emu_new(t->rc, TESTRIG_TIME_SCALE, &t->emu), 0);
        for (size_t i = 0; i < t->rc->n_buses; i++) {
                struct rig_bus_conf *b = &t->rc->buses[i];

                if (b->type == RIG_BUS_MODBUS_TCP) {
                        b->tcp_port = sim_emu_tcp_port(t->emu, b->name);
                        CHECK(b->tcp_port > 0);
                }
        }
}

void testrig_stop(struct testrig *t)
{
        char path[128];

        t->emu = sim_emu_free(t->emu);
        t->rc = rigconf_free(t->rc);
        snprintf(path, sizeof(path), "%s/rig.yaml", t->dir);
        CHECK(unlink(path) == 0);
        CHECK(rmdir(t->dir) == 0); /* the emulator removed its symlinks */
}

const struct rig_bus_conf *testrig_bus(const struct testrig *t, const char *name)
{
        const struct rig_bus_conf *b = rigconf_bus(t->rc, name);

        CHECK(b != NULL);
        return b;
}

double testrig_now(void)
{
        return (double)gn_monotonic_ns() * 1e-9;
}

void testrig_sleep(double s)
{
        struct timespec ts = {.tv_sec = (time_t)s, .tv_nsec = (long)((s - (time_t)s) * 1e9)};

        while (nanosleep(&ts, &ts) < 0 && errno == EINTR)
                ;
}

struct axis *testrig_axis_open(struct testrig *t, struct bus *b, int index)
{
        struct axis *ax = NULL;

        CHECK_INT(axis_new(&t->rc->axes[index], b, &ax), 0);
        CHECK_INT(axis_open(ax), 0);
        CHECK(ax->state.enabled);
        return ax;
}

double testrig_wait_stopped(struct axis *ax, double timeout_s)
{
        double t0 = testrig_now();

        do {
                CHECK_INT(axis_poll(ax), 0);
                if (!ax->state.moving)
                        return testrig_now() - t0;
                testrig_sleep(0.002);
        } while (testrig_now() - t0 < timeout_s);
        fprintf(stderr, "axis '%s' still moving after %.1f s\n", ax->conf->name, timeout_s);
        exit(1);
}

void testrig_wait_in_position(struct axis *ax)
{
        double t0 = testrig_now();

        testrig_wait_stopped(ax, 10.0);
        while (!ax->state.in_position && testrig_now() - t0 < 10.0) {
                testrig_sleep(0.002);
                CHECK_INT(axis_poll(ax), 0);
        }
        CHECK(ax->state.in_position);
        CHECK(!ax->state.fault);
}

void testrig_check_limits(struct axis *ax, double pos, double tol)
{
        struct transport_stats before, after;

        transport_get_stats(bus_transport(ax->bus), &before);
        CHECK_INT(axis_move_abs(ax, ax->conf->max_deg + 0.5), -ERANGE);
        CHECK_INT(axis_move_abs(ax, ax->conf->min_deg - 1.0), -ERANGE);
        CHECK_INT(axis_move_abs(ax, NAN), -ERANGE);
        transport_get_stats(bus_transport(ax->bus), &after);
        CHECK_INT(after.requests, before.requests); /* refused before any I/O */
        CHECK_INT(axis_poll(ax), 0);
        CHECK_NEAR(ax->state.position_deg, pos, tol);
}

void testrig_home_all(struct axis *const *ax, int n, double tol)
{
        for (int i = 0; i < n; i++)
                CHECK_INT(axis_home(ax[i]), 0);
        for (int i = 0; i < n; i++) {
                double p;

                testrig_wait_in_position(ax[i]);
                p = ax[i]->state.position_deg;
                CHECK(ax[i]->state.homed);
                CHECK(fabs(ax[i]->conf->continuous && p > 180.0 ? p - 360.0 : p) <= tol);
        }
}
