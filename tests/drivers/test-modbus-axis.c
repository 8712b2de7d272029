/* test-modbus-axis.c - the "modbus" axis driver against gonio-sim's emulated drives,
 * over a real pty (RTU) and loopback TCP through libmodbus: open, home, move timing,
 * a speed of its own, soft limits, shortest way round, stop mid-move (also as an urgent job on a
 * bus worker with an sd-event loop), and injected faults: timeout, bad CRC, exception, stall, and a
 * move that ends short of its target without a fault. */
#include <errno.h>
#include <math.h>
#include <semaphore.h>
#include <systemd/sd-event.h>

#include "drivers/axis/axis.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"
#include "tests/drivers/testrig.h"
#include "tests/test.h"

static const char rig_yaml[] =
        "rig: test-axes\n"
        "buses:\n"
        "  - { name: drives, type: modbus-rtu, port: '@DIR@/drives',\n"
        "      timeout_ms: 100, retries: 2 }\n"
        "  - { name: net, type: modbus-tcp, host: 127.0.0.1, tcp_port: 0,\n"
        "      timeout_ms: 200, retries: 1 }\n"
        "axes:\n"
        "  - { name: turntable, modbus: { bus: drives, unit: 1 },\n"
        "      continuous: true, max_speed: 90, accel: 180, settle_ms: 20 }\n"
        "  - { name: camera_arm, modbus: { bus: drives, unit: 3 },\n"
        "      limits: [-170, 170], max_speed: 10, accel: 20, settle_ms: 20 }\n"
        "  - { name: remote, modbus: { bus: net, unit: 5 },\n"
        "      continuous: true, max_speed: 90, accel: 180 }\n";

/* Emulated-time tolerance of positions at rest, degrees. */
#define POS_TOL 0.002

struct fixture {
        struct testrig rig;
        struct bus *drives, *net;
        struct axis *tt, *arm, *remote;
};

static struct axis *open_axis(struct fixture *f, struct bus *b, int index)
{
        return testrig_axis_open(&f->rig, b, index);
}

static int32_t raw_position(struct axis *ax)
{
        const struct mbax_conf *c = ax->conf->backend.conf;
        uint16_t regs[2];

        CHECK_INT(
                mbus_read_regs(bus_transport(ax->bus), c->unit, c->profile->reg_position, 2, regs),
                2);
        return mbax_get_i32(c->word_swap, regs);
}

static void test_home(struct fixture *f)
{
        testrig_home_all((struct axis *[]){f->tt, f->arm}, 2, POS_TOL);
}

/* 0 -> 150 deg at 10 deg/s, 20 deg/s^2: 15.5 s of emulated time, 0.775 s real. */
static void test_move_timing(struct fixture *f)
{
        double expect = axis_move_time(150.0, 10.0, 20.0) / TESTRIG_TIME_SCALE, took;

        CHECK_NEAR(expect, 0.775, 1e-9);
        CHECK_INT(axis_move_abs(f->arm, 150.0), 0);
        took = testrig_wait_stopped(f->arm, 10.0);
        fprintf(stderr, "move 150 deg: %.3f s, model %.3f s\n", took, expect);
        CHECK(took >= 0.85 * expect); /* cannot beat the profile */
        CHECK(took <= expect + 3.0);  /* generous: loaded machines */
        testrig_wait_in_position(f->arm);
        CHECK_NEAR(f->arm->state.position_deg, 150.0, POS_TOL);
}

/* A speed for the following moves: the drive's speed register, and a move that takes the
 * profile at that speed; 0 restores max_speed, above it is refused. */
static void test_set_speed(struct fixture *f)
{
        const struct mbax_conf *c = f->arm->conf->backend.conf;
        double expect = axis_move_time(50.0, 5.0, 20.0) / TESTRIG_TIME_SCALE, took;
        uint16_t reg;

        CHECK_INT(axis_set_rates(f->arm, 20.0, 0), -ERANGE);
        CHECK_INT(axis_set_rates(f->arm, 5.0, 0), 0);
        CHECK_INT(
                mbus_read_regs(bus_transport(f->arm->bus), c->unit, c->profile->reg_speed, 1, &reg),
                1);
        CHECK_INT(reg, 50);
        CHECK_INT(axis_move_abs(f->arm, 100.0), 0);
        took = testrig_wait_stopped(f->arm, 10.0);
        fprintf(stderr, "move 50 deg at 5 deg/s: %.3f s, model %.3f s\n", took, expect);
        CHECK(took >= 0.85 * expect); /* at 10 deg/s it would take 0.54 of this */
        testrig_wait_in_position(f->arm);
        CHECK_INT(axis_set_rates(f->arm, 0, 0), 0);
        CHECK_INT(
                mbus_read_regs(bus_transport(f->arm->bus), c->unit, c->profile->reg_speed, 1, &reg),
                1);
        CHECK_INT(reg, 100); /* max_speed 10 deg/s */
        CHECK_INT(axis_move_abs(f->arm, 150.0), 0);
        testrig_wait_in_position(f->arm);
}

static void test_soft_limits(struct fixture *f)
{
        testrig_check_limits(f->arm, 150.0, POS_TOL);
}

/* 0 -> 350 goes back 10 deg (raw -10000), then 350 -> 10 forward 20 deg (raw +10000). */
static void test_shortest_way(struct fixture *f)
{
        CHECK_INT(axis_move_abs(f->tt, 350.0), 0);
        testrig_wait_in_position(f->tt);
        CHECK_NEAR(f->tt->state.position_deg, 350.0, POS_TOL);
        CHECK_NEAR(raw_position(f->tt), -10000, 2);

        CHECK_INT(axis_move_abs(f->tt, 370.0), 0); /* = 10 deg */
        do {
                double p = f->tt->state.position_deg;

                CHECK(p >= 350.0 - POS_TOL || p <= 10.0 + POS_TOL); /* never the long way */
                testrig_sleep(0.002);
                CHECK_INT(axis_poll(f->tt), 0);
        } while (f->tt->state.moving);
        testrig_wait_in_position(f->tt);
        CHECK_NEAR(f->tt->state.position_deg, 10.0, POS_TOL);
        CHECK_NEAR(raw_position(f->tt), 10000, 2);
}

/* 150 -> -150 takes 1.525 s real; stop after 0.3 s leaves the arm in between, at rest. */
static void test_stop_mid_move(struct fixture *f)
{
        double p;

        CHECK_INT(axis_move_abs(f->arm, -150.0), 0);
        testrig_sleep(0.3);
        CHECK_INT(axis_stop(f->arm), 0);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK(!f->arm->state.moving);
        p = f->arm->state.position_deg;
        fprintf(stderr, "stopped at %.3f deg\n", p);
        CHECK(p < 150.0 - 1.0 && p > -140.0);
        testrig_sleep(0.1);
        CHECK_INT(axis_poll(f->arm), 0);
        CHECK_NEAR(f->arm->state.position_deg, p, POS_TOL); /* stays put */
}

/* The unit stops answering: -ETIMEDOUT after exactly retries extra attempts. */
static void test_timeout(struct fixture *f)
{
        const struct rig_bus_conf *c = bus_conf(f->drives);
        struct transport_stats before, after;
        double t0, took;

        transport_get_stats(bus_transport(f->drives), &before);
        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_TIMEOUT), 0);
        t0 = testrig_now();
        CHECK_INT(axis_poll(f->tt), -ETIMEDOUT);
        took = testrig_now() - t0;
        transport_get_stats(bus_transport(f->drives), &after);
        CHECK_INT(after.retries - before.retries, c->retries);
        CHECK_INT(after.failures - before.failures, 1);
        CHECK(took >= 0.9 * (c->retries + 1) * c->timeout_ms / 1000.0);
        CHECK(took < 5.0);
        CHECK_INT(axis_poll(f->arm), 0); /* other units on the line still answer */

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_NONE), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK_NEAR(f->tt->state.position_deg, 10.0, POS_TOL);
}

/* Corrupt CRCs are retried, then reported as -EPROTO; exceptions are not retried. */
static void test_crc_and_exception(struct fixture *f)
{
        const struct rig_bus_conf *c = bus_conf(f->drives);
        struct transport_stats s0, s1, s2;

        transport_get_stats(bus_transport(f->drives), &s0);
        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_CRC), 0);
        CHECK_INT(axis_poll(f->tt), -EPROTO);
        transport_get_stats(bus_transport(f->drives), &s1);
        CHECK_INT(s1.retries - s0.retries, c->retries);

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_EXCEPTION), 0);
        CHECK_INT(axis_poll(f->tt), -EPROTO);
        CHECK_INT(axis_move_abs(f->tt, 20.0), -EPROTO);
        transport_get_stats(bus_transport(f->drives), &s2);
        CHECK_INT(s2.retries, s1.retries);
        CHECK_INT(s2.failures - s1.failures, 2);

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_NONE), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK_NEAR(f->tt->state.position_deg, 10.0, POS_TOL); /* the refused move never ran */
}

/* A stall mid-move latches fault 1; moves are refused (-EPROTO) until reset. */
static void test_stall(struct fixture *f)
{
        double p;

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_STALL), 0); /* armed */
        CHECK_INT(axis_move_abs(f->tt, 100.0), 0);
        testrig_wait_stopped(f->tt, 10.0);
        CHECK(f->tt->state.fault);
        CHECK_INT(f->tt->state.fault_code, MBAX_FAULT_STALL);
        CHECK(!f->tt->state.in_position);
        p = f->tt->state.position_deg;
        CHECK(p > 10.0 + 1.0 && p < 100.0 - 1.0);

        CHECK_INT(axis_move_abs(f->tt, 100.0), -EPROTO); /* exception 0x04 */
        CHECK_INT(axis_reset(f->tt), 0);
        CHECK_INT(axis_poll(f->tt), 0);
        CHECK(!f->tt->state.fault);
        CHECK_INT(axis_move_abs(f->tt, 100.0), 0);
        testrig_wait_in_position(f->tt);
        CHECK_NEAR(f->tt->state.position_deg, 100.0, POS_TOL);
}

/* A drive that ends a move short of its target without a fault: the state says so from
 * the drive's own in-position flag (moving clear, in_position clear), never from the
 * position being "close enough"; the next move is normal. */
static void test_short(struct fixture *f)
{
        double t0;

        CHECK_INT(sim_emu_inject(f->rig.emu, "drives", 1, SIM_FAULT_SHORT), 0); /* armed */
        CHECK_INT(axis_move_abs(f->tt, 150.0), 0);
        testrig_wait_stopped(f->tt, 10.0);
        t0 = testrig_now();
        do { /* longer than any settle time: the flag never comes */
                CHECK_INT(axis_poll(f->tt), 0);
                CHECK(!f->tt->state.moving);
                CHECK(!f->tt->state.in_position);
                CHECK(!f->tt->state.fault);
                CHECK_INT(f->tt->state.fault_code, 0);
                testrig_sleep(0.01);
        } while (testrig_now() - t0 < 0.3);
        CHECK_NEAR(f->tt->state.position_deg, 147.0, 0.01); /* 3 deg short */

        CHECK_INT(axis_move_abs(f->tt, 150.0), 0);
        testrig_wait_in_position(f->tt);
        CHECK_NEAR(f->tt->state.position_deg, 150.0, POS_TOL);
}

static void test_tcp(struct fixture *f)
{
        CHECK_INT(axis_move_abs(f->remote, -45.0), 0);
        testrig_wait_in_position(f->remote);
        CHECK_NEAR(f->remote->state.position_deg, 315.0, POS_TOL);
}

static void run_sync(struct fixture *f)
{
        CHECK_INT(bus_new_sync(testrig_bus(&f->rig, "drives"), &f->drives), 0);
        CHECK_INT(bus_new_sync(testrig_bus(&f->rig, "net"), &f->net), 0);
        f->tt = open_axis(f, f->drives, 0);
        f->arm = open_axis(f, f->drives, 1);
        f->remote = open_axis(f, f->net, 2);

        test_home(f);
        test_move_timing(f);
        test_set_speed(f);
        test_soft_limits(f);
        test_shortest_way(f);
        test_stop_mid_move(f);
        test_timeout(f);
        test_crc_and_exception(f);
        test_stall(f);
        test_short(f);
        test_tcp(f);

        f->tt = axis_free(f->tt);
        f->arm = axis_free(f->arm);
        f->remote = axis_free(f->remote);
        f->drives = bus_free(f->drives);
        f->net = bus_free(f->net);
}

/* ---- the same drive through a bus worker and an sd-event loop ---- */

struct loop_test {
        sd_event *event;
        struct axis *arm;
        sem_t busy;
        int order[8], results[8], n;
};

struct loop_job {
        struct loop_test *lt;
        int id;
};

static int job_open(struct bus *b, void *userdata)
{
        struct loop_job *j = userdata;

        return axis_open(j->lt->arm);
}

/* Keeps the worker busy while the next jobs queue up. */
static int job_busy(struct bus *b, void *userdata)
{
        struct loop_job *j = userdata;

        sem_post(&j->lt->busy);
        testrig_sleep(0.1);
        return 0;
}

static int job_move(struct bus *b, void *userdata)
{
        struct loop_job *j = userdata;

        return axis_move_abs(j->lt->arm, -150.0);
}

static int job_poll(struct bus *b, void *userdata)
{
        struct loop_job *j = userdata;

        return axis_poll(j->lt->arm);
}

static int job_stop(struct bus *b, void *userdata)
{
        struct loop_job *j = userdata;

        return axis_stop(j->lt->arm);
}

static void job_done(struct bus *b, int result, void *userdata)
{
        struct loop_job *j = userdata;
        struct loop_test *lt = j->lt;

        lt->order[lt->n] = j->id;
        lt->results[lt->n++] = result;
}

/* Submits job and checks the submission. */
static void submit(struct bus *b, bus_job_fn fn, struct loop_job *j, bool urgent)
{
        CHECK_INT(bus_submit(b, fn, job_done, j, urgent), 0);
}

/* Runs the loop until n completions arrived (at most 10 s). */
static void run_until(struct loop_test *lt, int n)
{
        double t0 = testrig_now();

        while (lt->n < n) {
                CHECK(testrig_now() - t0 < 10.0);
                CHECK(sd_event_run(lt->event, 100 * 1000) >= 0);
        }
}

/* A long move, then while the worker is busy two polls and an urgent stop are queued:
 * the stop overtakes the polls, so both see the arm at rest short of the target. */
static void run_worker(struct fixture *f)
{
        struct loop_test lt = {};
        struct loop_job jobs[6];
        struct bus *b = NULL;

        for (int i = 0; i < 6; i++)
                jobs[i] = (struct loop_job){&lt, i};
        sem_init(&lt.busy, 0, 0);
        CHECK_INT(sd_event_new(&lt.event), 0);
        CHECK_INT(bus_new(lt.event, testrig_bus(&f->rig, "drives"), &b), 0);
        CHECK_INT(axis_new(&f->rig.rc->axes[1], b, &lt.arm), 0);

        submit(b, job_open, &jobs[0], false);
        submit(b, job_move, &jobs[1], false);
        run_until(&lt, 2);
        CHECK_INT(lt.results[0], 0);
        CHECK_INT(lt.results[1], 0);
        testrig_sleep(0.3);
        submit(b, job_busy, &jobs[2], false);
        sem_wait(&lt.busy);
        submit(b, job_poll, &jobs[3], false);
        submit(b, job_poll, &jobs[4], false);
        submit(b, job_stop, &jobs[5], true);
        run_until(&lt, 6);
        CHECK_INT(lt.order[2], 2);
        CHECK_INT(lt.order[3], 5); /* the urgent stop overtook both polls */
        CHECK_INT(lt.order[4], 3);
        CHECK_INT(lt.order[5], 4);
        for (int i = 2; i < 6; i++)
                CHECK_INT(lt.results[i], 0);
        CHECK(!lt.arm->state.moving);
        CHECK(lt.arm->state.position_deg > -150.0 + 1.0);

        lt.arm = axis_free(lt.arm);
        CHECK(bus_free(b) == NULL);
        sd_event_unref(lt.event);
        sem_destroy(&lt.busy);
}

int main(void)
{
        struct fixture f = {};

        testrig_start(&f.rig, rig_yaml);
        run_sync(&f);
        run_worker(&f);
        testrig_stop(&f.rig);
        return 0;
}
