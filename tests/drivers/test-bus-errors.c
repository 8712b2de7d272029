/* test-bus-errors.c - what an operator is told when a bus fails, against gonio-sim's
 * emulators on real ptys: a missing port fails at once with -ENOENT naming its path, no
 * retries; a port held by another bus (or process) fails with -EBUSY naming the port;
 * a timeout or an exception names device, unit, operation and register, and every such
 * message is kept, whole, in the device's last_error. */
#include <errno.h>
#include <stdio.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "drivers/axis/axis.h"
#include "drivers/switch/switch.h"
#include "drivers/transport/transport.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-errors\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: '@DIR@/drives',\n"
        "      timeout_ms: 100, retries: 2 }\n"
        "  - { name: relays, type: modbus-rtu, port: '@DIR@/relays',\n"
        "      timeout_ms: 100, retries: 1 }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 }, continuous: true }\n"
        "lamps:\n"
        "  - { name: lamp0, modbus-coil: { bus: relays, unit: 10, coil: 0 },\n"
        "      elevation: 10 }\n";

/* Opens the turntable on a new sync bus for conf; returns axis_open()'s result. */
static int open_tt(struct testrig *t, const struct rig_bus_conf *conf, struct bus **b,
                   struct axis **ax)
{
        CHECK_INT(bus_new_sync(conf, b), 0);
        CHECK_INT(axis_new(&t->rc->axes[0], *b, ax), 0);
        return axis_open(*ax);
}

static void close_tt(struct bus **b, struct axis **ax)
{
        *ax = axis_free(*ax);
        *b = bus_free(*b);
}

/* A port the process may not open: -EACCES naming the path. As root, checked in a child
 * that drops to nobody (root opens anything). */
static void test_permission(struct testrig *t, struct rig_bus_conf *c)
{
        struct axis *ax = NULL;
        struct bus *b = NULL;
        int status;
        pid_t pid;

        FILE *f = fopen(c->port, "w");
        CHECK(f && fclose(f) == 0 && chmod(c->port, 0) == 0);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                if (geteuid() == 0 && (setgid(65534) < 0 || setuid(65534) < 0))
                        _exit(2);
                CHECK_INT(open_tt(t, c, &b, &ax), -EACCES);
                CHECK_STR_CONTAINS(ax->last_error, c->port);
                CHECK_STR_CONTAINS(ax->last_error, "Permission denied");
                _exit(0);
        }
        CHECK(waitpid(pid, &status, 0) == pid);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
        CHECK(unlink(c->port) == 0);
}

static void test_missing_port(struct testrig *t)
{
        struct rig_bus_conf c = *testrig_bus(t, "drives");
        struct transport_stats st;
        struct axis *ax = NULL;
        struct bus *b = NULL;
        char expect[512];
        double t0;

        snprintf(c.port, sizeof(c.port), "%s/ttyUSB9", t->dir);
        t0 = testrig_now();
        CHECK_INT(open_tt(t, &c, &b, &ax), -ENOENT);
        CHECK(testrig_now() - t0 < 0.05); /* no timeout, no retry */
        transport_get_stats(bus_transport(b), &st);
        CHECK_INT(st.retries, 0);
        snprintf(expect, sizeof(expect),
                 "axis 'turntable' [modbus@ttyUSB9#1]: Failed to open: cannot open port %s: No "
                 "such file or directory",
                 c.port);
        CHECK_STR(ax->last_error, expect);
        close_tt(&b, &ax);

        test_permission(t, &c);
}

/* Bug 5: two masters on one RS-485 line. The second bus is refused, at once. */
static void test_port_lock(struct testrig *t)
{
        const struct rig_bus_conf *c = testrig_bus(t, "drives");
        struct axis *a1 = NULL, *a2 = NULL;
        struct bus *b1 = NULL, *b2 = NULL;
        struct transport_stats st;
        char expect[512];

        CHECK_INT(open_tt(t, c, &b1, &a1), 0);
        CHECK_INT(open_tt(t, c, &b2, &a2), -EBUSY);
        transport_get_stats(bus_transport(b2), &st);
        CHECK_INT(st.retries, 0);
        snprintf(expect, sizeof(expect), "port %s is in use by another process", c->port);
        CHECK_STR_CONTAINS(a2->last_error, expect);
        CHECK_INT(axis_poll(a1), 0); /* the first master keeps its line */
        close_tt(&b1, &a1);
        CHECK_INT(axis_open(a2), 0); /* the lock went with the first bus */
        close_tt(&b2, &a2);
}

static void test_timeout_names_register(struct testrig *t)
{
        struct rig_modbus_profile p;
        struct axis *ax = NULL;
        struct bus *b = NULL;
        char expect[512];

        rigconf_default_profile(&p);
        CHECK_INT(open_tt(t, testrig_bus(t, "drives"), &b, &ax), 0);
        CHECK_INT(sim_emu_inject(t->emu, "drives", 1, SIM_FAULT_TIMEOUT), 0);
        CHECK_INT(axis_poll(ax), -ETIMEDOUT);
        snprintf(expect, sizeof(expect),
                 "axis 'turntable' [modbus@drives#1]: Failed to read the drive state: read "
                 "status and position (reg 0x%04x): Connection timed out after 100 ms",
                 MIN(MIN(p.reg_status, p.reg_fault), p.reg_position));
        CHECK_STR(ax->last_error, expect);

        CHECK_INT(sim_emu_inject(t->emu, "drives", 1, SIM_FAULT_EXCEPTION), 0);
        CHECK_INT(axis_home(ax), -EPROTO);
        snprintf(expect, sizeof(expect),
                 "axis 'turntable' [modbus@drives#1]: Failed to start homing: write command "
                 "(reg 0x%04x): Slave device or server failure",
                 p.reg_command);
        CHECK_STR(ax->last_error, expect);
        CHECK_INT(sim_emu_inject(t->emu, "drives", 1, SIM_FAULT_NONE), 0);
        close_tt(&b, &ax);
}

static void test_switch_cause(struct testrig *t)
{
        struct bus *b = NULL;
        struct sw *s = NULL;

        CHECK_INT(bus_new_sync(testrig_bus(t, "relays"), &b), 0);
        CHECK_INT(sw_new(&t->rc->lamps[0], b, &s), 0);
        CHECK_INT(sw_open(s), 0);
        CHECK_STR(s->last_error, "");
        CHECK_INT(sim_emu_inject(t->emu, "relays", 10, SIM_FAULT_TIMEOUT), 0);
        CHECK_INT(sw_set(s, true), -ETIMEDOUT);
        CHECK_STR(s->last_error, "switch 'lamp0' [modbus-coil@relays#10]: Failed to switch on: "
                                 "write coil 0: Connection timed out after 100 ms");
        CHECK_INT(sim_emu_inject(t->emu, "relays", 10, SIM_FAULT_NONE), 0);
        s = sw_free(s);
        b = bus_free(b);
}

int main(void)
{
        struct testrig t;

        testrig_start(&t, rig_yaml);
        test_missing_port(&t);
        test_port_lock(&t);
        test_timeout_names_register(&t);
        test_switch_cause(&t);
        testrig_stop(&t);
        return 0;
}
