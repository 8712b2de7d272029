/* test-modbus-coil.c - the "modbus-coil" switch driver against gonio-sim's emulated
 * relay module over a real pty: set with read-back (checked against the emulator's own
 * state), lamp warm-up, the cached state left alone on timeouts and exceptions, and
 * switching through a bus worker with completions on an sd-event loop. */
#include <errno.h>
#include <systemd/sd-event.h>

#include "drivers/switch/switch.h"
#include "drivers/transport/transport.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-relays\n"
        "buses:\n"
        "  - { name: relays, type: modbus-rtu, port: '@DIR@/relays',\n"
        "      timeout_ms: 100, retries: 1 }\n"
        "lamps:\n"
        "  - { name: lamp0, elevation: 10, warmup_ms: 150,\n"
        "      modbus-coil: { bus: relays, unit: 10, coil: 0 } }\n"
        "  - { name: lamp1, elevation: 45, modbus-coil: { bus: relays, unit: 10, coil: 1 } }\n"
        "laser: { name: laser, modbus-coil: { bus: relays, unit: 10, coil: 7 } }\n";

struct fixture {
        struct testrig rig;
        struct bus *bus;
        struct sw *lamp0, *lamp1, *laser;
};

static struct sw *open_switch(struct bus *b, const struct rig_switch_conf *c)
{
        struct sw *s = NULL;

        CHECK_INT(sw_new(c, b, &s), 0);
        CHECK_INT(sw_open(s), 0);
        CHECK(!s->on); /* relays power up off */
        return s;
}

/* The emulator's own view of the coils, as lamp0 lamp1 laser bits. */
static int emu_coils(struct fixture *f)
{
        struct gn_pose st;

        sim_emu_snapshot(f->rig.emu, &st);
        return (int)(st.lamps & 3) | st.lasers << 2;
}

static void test_set_readback(struct fixture *f)
{
        bool on = false;
        double t0, took;

        t0 = testrig_now();
        CHECK_INT(sw_set(f->lamp0, true), 0);
        took = testrig_now() - t0;
        CHECK(took >= 0.15); /* warm-up of lamp0 is part of switching it on */
        CHECK(f->lamp0->on);
        CHECK_INT(emu_coils(f), 1);
        CHECK_INT(sw_set(f->laser, true), 0);
        CHECK_INT(emu_coils(f), 5);
        CHECK_INT(sw_get(f->laser, &on), 0);
        CHECK(on);
        CHECK_INT(sw_get(f->lamp1, &on), 0);
        CHECK(!on);

        t0 = testrig_now();
        CHECK_INT(sw_set(f->lamp0, false), 0);
        CHECK(testrig_now() - t0 < 0.15); /* no warm-up when switching off */
        CHECK(!f->lamp0->on);
        CHECK_INT(emu_coils(f), 4);
        CHECK_INT(sw_set(f->laser, false), 0);
        CHECK_INT(emu_coils(f), 0);
}

/* A failed write leaves the cached state as the device last confirmed it. */
static void test_faults(struct fixture *f)
{
        struct transport_stats before, after;

        transport_get_stats(bus_transport(f->bus), &before);
        CHECK_INT(sim_emu_inject(f->rig.emu, "relays", 10, SIM_FAULT_TIMEOUT), 0);
        CHECK_INT(sw_set(f->lamp1, true), -ETIMEDOUT);
        CHECK(!f->lamp1->on);
        transport_get_stats(bus_transport(f->bus), &after);
        CHECK_INT(after.retries - before.retries, 1);

        CHECK_INT(sim_emu_inject(f->rig.emu, "relays", 10, SIM_FAULT_EXCEPTION), 0);
        CHECK_INT(sw_set(f->lamp1, true), -EPROTO);
        CHECK(!f->lamp1->on);
        CHECK_INT(emu_coils(f), 0);

        CHECK_INT(sim_emu_inject(f->rig.emu, "relays", 10, SIM_FAULT_NONE), 0);
        CHECK_INT(sw_set(f->lamp1, true), 0);
        CHECK(f->lamp1->on);
        CHECK_INT(emu_coils(f), 2);
}

struct loop_set {
        struct sw *s;
        bool on;
        int result, n_done;
};

static int job_set(struct bus *b, void *userdata)
{
        struct loop_set *ls = userdata;

        return sw_set(ls->s, ls->on);
}

static void job_done(struct bus *b, int result, void *userdata)
{
        struct loop_set *ls = userdata;

        ls->result = result;
        ls->n_done++;
}

/* Switches the laser on through a bus worker; the result arrives on the loop. */
static void test_worker(struct fixture *f)
{
        sd_event *event = NULL;
        struct bus *b = NULL;
        struct loop_set ls = {.on = true, .result = -1};
        double t0 = testrig_now();

        CHECK_INT(sd_event_new(&event), 0);
        CHECK_INT(bus_new(event, testrig_bus(&f->rig, "relays"), &b), 0);
        CHECK_INT(sw_new(&f->rig.rc->lasers[0], b, &ls.s), 0);
        CHECK_INT(bus_submit(b, job_set, job_done, &ls, false), 0);
        while (ls.n_done == 0) {
                CHECK(testrig_now() - t0 < 10.0);
                CHECK(sd_event_run(event, 100 * 1000) >= 0);
        }
        CHECK_INT(ls.result, 0);
        CHECK(ls.s->on);
        CHECK_INT(emu_coils(f), 2 | 4);

        ls.s = sw_free(ls.s);
        CHECK(bus_free(b) == NULL);
        sd_event_unref(event);
}

int main(void)
{
        struct fixture f = {};

        testrig_start(&f.rig, rig_yaml);
        CHECK_INT(bus_new_sync(testrig_bus(&f.rig, "relays"), &f.bus), 0);
        f.lamp0 = open_switch(f.bus, &f.rig.rc->lamps[0]);
        f.lamp1 = open_switch(f.bus, &f.rig.rc->lamps[1]);
        f.laser = open_switch(f.bus, &f.rig.rc->lasers[0]);

        test_set_readback(&f);
        test_faults(&f);

        f.lamp0 = sw_free(f.lamp0);
        f.lamp1 = sw_free(f.lamp1);
        f.laser = sw_free(f.laser);
        f.bus = bus_free(f.bus);
        test_worker(&f);
        testrig_stop(&f.rig);
        return 0;
}
