/* test-modbus-emu.c - the Modbus emulators of gonio-sim, through a plain libmodbus
 * client on the pty (RTU) or on loopback (TCP): register reads and writes, several
 * units on one bus, the timing of a move against the motion model, homing, stop,
 * the client-side error of every injected fault, a stall and a move that ends short,
 * and the pose of a rig whose only axis is found by its role. */
#include <errno.h>
#include <math.h>
#include <string.h>
#include <unistd.h>

#include <modbus/modbus.h>

#include "common/cleanup.h"
#include "sim/drive.h"
#include "sim/modbus_emu.h"
#include "sim/motion.h"
#include "tests/sim/simtest.h"

#define TIME_SCALE 4.0 /* emulated seconds per real second */

static double position_deg(modbus_t *mb, int unit)
{
        uint16_t v[2];

        CHECK(modbus_set_slave(mb, unit) == 0);
        CHECK(modbus_read_registers(mb, SIMTEST_R_POS, 2, v) == 2);
        return (int32_t)((uint32_t)v[0] << 16 | v[1]) / 1000.0;
}

static double wrapped_distance(double a, double b)
{
        return fabs(remainder(a - b, 360.0));
}

static void test_reads_and_units(struct sim_emu *e, modbus_t *mb)
{
        uint8_t coils[8];
        struct gn_pose st;

        CHECK(simtest_reg(mb, 1, SIMTEST_R_STATUS) & 1); /* enabled */
        CHECK(!(simtest_reg(mb, 1, SIMTEST_R_STATUS) & SIMTEST_ST_HOMED));
        CHECK(simtest_reg(mb, 1, SIMTEST_R_FAULT) == 0);
        CHECK(position_deg(mb, 1) == 0.0); /* counts from power-on */
        CHECK(simtest_reg(mb, 1, SIMTEST_R_SPEED) == 900);
        CHECK(simtest_reg(mb, 2, SIMTEST_R_SPEED) == 450);
        CHECK(simtest_reg(mb, 3, SIMTEST_R_SPEED) == 300);

        /* The relay module at unit 10 on its own bus. */
        modbus_t *rl = simtest_modbus(getenv("GONIO_SIM_DIR"), "relays");
        CHECK(modbus_set_slave(rl, 10) == 0);
        CHECK(modbus_write_bit(rl, 1, 1) == 1);
        CHECK(modbus_write_bit(rl, 7, 1) == 1);
        CHECK(modbus_read_bits(rl, 0, 8, coils) == 8);
        CHECK(!coils[0] && coils[1] && coils[7]);
        sim_emu_snapshot(e, &st);
        CHECK(st.lamps == 2 && st.lasers);
        CHECK(modbus_read_bits(rl, 8, 1, coils) == -1 && errno == EMBXILADD);
        modbus_close(rl);
        modbus_free(rl);

        /* No device at unit 5: silence, like a real bus. */
        CHECK(modbus_set_slave(mb, 5) == 0);
        uint16_t v;
        CHECK(modbus_read_registers(mb, SIMTEST_R_STATUS, 1, &v) == -1 && errno == ETIMEDOUT);
        /* Out-of-map register and unknown command. */
        CHECK(modbus_set_slave(mb, 1) == 0);
        CHECK(modbus_read_registers(mb, 0x100, 1, &v) == -1 && errno == EMBXILADD);
        CHECK(modbus_write_register(mb, SIMTEST_R_COMMAND, 99) == -1 && errno == EMBXILVAL);
}

static void test_home(struct sim_emu *e, modbus_t *mb)
{
        struct gn_pose st;

        CHECK(simtest_command(mb, 1, 0.0, SIMTEST_CMD_HOME) == 1);
        /* at most half a turn at 90 deg/s, 180 deg/s^2, plus settle */
        simtest_wait_status(mb, 1, SIMTEST_ST_HOMED | SIMTEST_ST_INPOS,
                            SIMTEST_ST_HOMED | SIMTEST_ST_INPOS, 3.0);
        CHECK(fabs(position_deg(mb, 1)) < 1e-9);
        CHECK(simtest_reg(mb, 1, SIMTEST_R_STATUS) & (1 << 5)); /* on the home switch */
        sim_emu_snapshot(e, &st);
        CHECK(wrapped_distance(st.deg[GN_ROLE_TURNTABLE], 0.0) < 1e-6);
}

/* A 90 deg move: its duration and an intermediate position against the model, with the
 * unknown start time bracketed by the command's round trip. */
static void test_move_timing(struct sim_emu *e, modbus_t *mb)
{
        struct motion m;
        struct gn_pose st;

        CHECK(motion_plan(&m, 0.0, 0.0, 90.0, 90.0, 180.0) == 0);
        double c0 = simtest_now();
        CHECK(simtest_command(mb, 1, 90.0, SIMTEST_CMD_MOVE) == 1);
        double c1 = simtest_now();
        CHECK(simtest_reg(mb, 1, SIMTEST_R_STATUS) & SIMTEST_ST_MOVING);

        usleep((useconds_t)(m.t_total / TIME_SCALE * 0.4 * 1e6));
        double r0 = simtest_now();
        double pos = position_deg(mb, 1);
        double r1 = simtest_now();
        double lo = motion_position(&m, (r0 - c1) * TIME_SCALE);
        double hi = motion_position(&m, (r1 - c0) * TIME_SCALE);
        CHECK(pos >= lo - 1e-3 && pos <= hi + 1e-3);
        CHECK(pos > 0.0 && pos < 90.0);

        simtest_wait_status(mb, 1, SIMTEST_ST_MOVING | SIMTEST_ST_INPOS, SIMTEST_ST_INPOS, 5.0);
        double took = simtest_now() - c0;
        double expect = (m.t_total + 0.050) / TIME_SCALE; /* profile + settle_ms */
        CHECK(took >= expect - 0.02);
        CHECK(took <= expect + 0.5);
        CHECK_NEAR(position_deg(mb, 1), 90.0, 1e-9);
        sim_emu_snapshot(e, &st);
        CHECK_NEAR(st.deg[GN_ROLE_TURNTABLE], 90.0, 1e-6);
}

static void test_stop(modbus_t *mb)
{
        CHECK(simtest_command(mb, 1, 0.0, SIMTEST_CMD_MOVE) == 1);
        usleep(100000);
        CHECK(modbus_write_register(mb, SIMTEST_R_COMMAND, SIMTEST_CMD_STOP) == 1);
        double at = position_deg(mb, 1);
        CHECK(at > 0.0 && at < 90.0);
        usleep(100000);
        CHECK(position_deg(mb, 1) == at);
        CHECK(!(simtest_reg(mb, 1, SIMTEST_R_STATUS) & (SIMTEST_ST_MOVING | SIMTEST_ST_INPOS)));
}

/* Each communication fault gives its libmodbus error; the other units keep answering. */
static void test_comm_faults(struct sim_emu *e, modbus_t *mb)
{
        uint16_t v;
        static const struct {
                enum sim_fault fault;
                int err;
        } cases[] = {
                {SIM_FAULT_TIMEOUT, ETIMEDOUT},
                {SIM_FAULT_CRC, EMBBADCRC},
                {SIM_FAULT_EXCEPTION, EMBXSFAIL},
        };

        for (size_t i = 0; i < ELEMENTSOF(cases); i++) {
                CHECK(sim_emu_inject(e, "drives", 2, cases[i].fault) == 0);
                CHECK(modbus_set_slave(mb, 2) == 0);
                errno = 0;
                CHECK(modbus_read_registers(mb, SIMTEST_R_STATUS, 1, &v) == -1);
                CHECK(errno == cases[i].err);
                CHECK(simtest_reg(mb, 3, SIMTEST_R_SPEED) == 300);
                CHECK(sim_emu_inject(e, "drives", 2, SIM_FAULT_NONE) == 0);
                CHECK(simtest_reg(mb, 2, SIMTEST_R_SPEED) == 450);
        }
        CHECK(sim_emu_inject(e, "drives", 9, SIM_FAULT_TIMEOUT) == -ENOENT);
        CHECK(sim_emu_inject(e, "nosuchbus", 1, SIM_FAULT_TIMEOUT) == -ENOENT);
        CHECK(sim_emu_inject(e, "relays", 10, SIM_FAULT_STALL) == -EINVAL);
}

/* A stall stops the axis half-way and latches fault 1 until reset. */
static void test_stall(struct sim_emu *e, modbus_t *mb)
{
        double from = position_deg(mb, 3);

        CHECK(sim_emu_inject(e, "drives", 3, SIM_FAULT_STALL) == 0);
        CHECK(simtest_command(mb, 3, from + 20.0, SIMTEST_CMD_MOVE) == 1);
        simtest_wait_status(mb, 3, SIMTEST_ST_FAULT | SIMTEST_ST_MOVING, SIMTEST_ST_FAULT, 5.0);
        CHECK(simtest_reg(mb, 3, SIMTEST_R_FAULT) == 1);
        CHECK_NEAR(position_deg(mb, 3), from + 10.0, 1e-3);
        CHECK(simtest_command(mb, 3, from, SIMTEST_CMD_MOVE) == -1 && errno == EMBXSFAIL);
        CHECK(modbus_write_register(mb, SIMTEST_R_COMMAND, SIMTEST_CMD_RESET) == 1);
        CHECK(simtest_reg(mb, 3, SIMTEST_R_FAULT) == 0);
        CHECK(simtest_command(mb, 3, from, SIMTEST_CMD_MOVE) == 1);
        simtest_wait_status(mb, 3, SIMTEST_ST_MOVING | SIMTEST_ST_INPOS, SIMTEST_ST_INPOS, 5.0);
        CHECK_NEAR(position_deg(mb, 3), from, 1e-9);
}

/* Waits until unit has stopped moving, then past its settle time; returns the status. */
static uint16_t wait_stopped(modbus_t *mb, int unit)
{
        simtest_wait_status(mb, unit, SIMTEST_ST_MOVING, 0, 5.0);
        usleep((useconds_t)(0.2 / TIME_SCALE * 1e6)); /* twice settle_ms */
        return simtest_reg(mb, unit, SIMTEST_R_STATUS);
}

/* A short stop ends the move SIM_DRIVE_SHORT_DEG before its target: not moving, not in
 * position, no fault; injected at rest (the next move) and into a running move. The next
 * move completes. */
static void test_short(struct sim_emu *e, modbus_t *mb)
{
        double from = position_deg(mb, 3);

        CHECK(sim_emu_inject(e, "drives", 3, SIM_FAULT_SHORT) == 0);
        CHECK(simtest_command(mb, 3, from + 20.0, SIMTEST_CMD_MOVE) == 1);
        uint16_t st = wait_stopped(mb, 3);
        CHECK(!(st & (SIMTEST_ST_MOVING | SIMTEST_ST_INPOS | SIMTEST_ST_FAULT)));
        CHECK(simtest_reg(mb, 3, SIMTEST_R_FAULT) == 0);
        CHECK_NEAR(position_deg(mb, 3), from + 20.0 - SIM_DRIVE_SHORT_DEG, 1e-3);

        CHECK(simtest_command(mb, 3, from, SIMTEST_CMD_MOVE) == 1);
        CHECK(sim_emu_inject(e, "drives", 3, SIM_FAULT_SHORT) == 0);
        st = wait_stopped(mb, 3);
        CHECK(!(st & (SIMTEST_ST_MOVING | SIMTEST_ST_INPOS | SIMTEST_ST_FAULT)));
        CHECK_NEAR(position_deg(mb, 3), from + SIM_DRIVE_SHORT_DEG, 1e-3);

        CHECK(simtest_command(mb, 3, from, SIMTEST_CMD_MOVE) == 1);
        simtest_wait_status(mb, 3, SIMTEST_ST_MOVING | SIMTEST_ST_INPOS, SIMTEST_ST_INPOS, 5.0);
        CHECK_NEAR(position_deg(mb, 3), from, 1e-9);
}

static void test_rtu(void)
{
        char dir[64], link[300];
        struct rig_config *rc = simtest_rig(dir, false);
        struct sim_emu *e = NULL;

        CHECK(sim_emu_new(rc, TIME_SCALE, &e) == 0);
        snprintf(link, sizeof link, "%s/drives", dir);
        char target[256];
        ssize_t n = readlink(link, target, sizeof target - 1);
        CHECK(n > 0);
        target[n] = '\0';
        CHECK(strcmp(target, sim_emu_pty(e, "drives")) == 0);
        CHECK(sim_emu_tcp_port(e, "drives") == -ENOENT);

        modbus_t *mb = simtest_modbus(dir, "drives");
        test_reads_and_units(e, mb);
        test_home(e, mb);
        test_move_timing(e, mb);
        test_stop(mb);
        test_comm_faults(e, mb);
        test_stall(e, mb);
        test_short(e, mb);
        modbus_close(mb);
        modbus_free(mb);

        sim_emu_free(e);
        CHECK(access(link, F_OK) < 0 && errno == ENOENT); /* symlink removed */
        rigconf_free(rc);
        simtest_rmdir(dir);
}

/* The same drives on Modbus TCP: every unit answers on one connection; a corrupted
 * reply (TCP has no CRC: a wrong transaction id) is refused by the client. */
static void test_tcp(void)
{
        char dir[64];
        struct rig_config *rc = simtest_rig(dir, true);
        struct sim_emu *e = NULL;
        uint16_t v;

        CHECK(sim_emu_new(rc, TIME_SCALE, &e) == 0);
        int port = sim_emu_tcp_port(e, "drives");
        CHECK(port > 0);
        CHECK(sim_emu_pty(e, "drives") == NULL);
        modbus_t *mb = modbus_new_tcp("127.0.0.1", port);
        CHECK(mb && modbus_connect(mb) == 0);
        CHECK(modbus_set_response_timeout(mb, 0, 300000) == 0);
        CHECK(simtest_reg(mb, 1, SIMTEST_R_SPEED) == 900);
        CHECK(simtest_reg(mb, 3, SIMTEST_R_SPEED) == 300);
        CHECK(sim_emu_inject(e, "drives", 1, SIM_FAULT_CRC) == 0);
        CHECK(modbus_set_slave(mb, 1) == 0);
        CHECK(modbus_read_registers(mb, SIMTEST_R_SPEED, 1, &v) == -1);
        CHECK(sim_emu_inject(e, "drives", 1, SIM_FAULT_NONE) == 0);
        CHECK(simtest_reg(mb, 1, SIMTEST_R_SPEED) == 900);
        modbus_close(mb);
        modbus_free(mb);
        sim_emu_free(e);
        rigconf_free(rc);
        simtest_rmdir(dir);
}

/* A rig with only a turntable, named "tt" with role turntable: the pose maps the drive by
 * its role, the missing arms are NAN, and the renderer takes such a pose. */
static void test_roles(void)
{
        static const char rig[] =
                "rig: tt-only\n"
                "buses:\n"
                "  - { name: drives, type: modbus-rtu, port: \"${GONIO_SIM_DIR}/drives\" }\n"
                "  - { name: frames, type: sim, port: \"${GONIO_SIM_DIR}/frames.sock\" }\n"
                "axes:\n"
                "  - { name: tt, role: turntable, modbus: { bus: drives, unit: 4 },\n"
                "      continuous: true, max_speed: 90, accel: 180 }\n"
                "cameras:\n"
                "  - { name: cam0, sim: { bus: frames }, elevation: 20, distance: 500,\n"
                "      target: [0, 0, 30], width: 64, height: 48, fx: 100, fy: 100,\n"
                "      cx: 31.5, cy: 23.5 }\n";
        char dir[64];
        struct rig_config *rc = simtest_rig_text(dir, rig);
        struct sim_emu *e = NULL;
        struct sim_scene *scene = NULL;
        struct gn_frame f = {0};
        struct gn_pose st;

        CHECK(sim_emu_new(rc, TIME_SCALE, &e) == 0);
        modbus_t *mb = simtest_modbus(dir, "drives");
        sim_emu_snapshot(e, &st);
        double from = st.deg[GN_ROLE_TURNTABLE];
        CHECK(simtest_command(mb, 4, 90.0, SIMTEST_CMD_MOVE) == 1);
        simtest_wait_status(mb, 4, SIMTEST_ST_MOVING | SIMTEST_ST_INPOS, SIMTEST_ST_INPOS, 5.0);
        sim_emu_snapshot(e, &st);
        CHECK(gn_pose_has(&st, GN_ROLE_TURNTABLE));
        CHECK(!gn_pose_has(&st, GN_ROLE_LIGHT_ARM) && !gn_pose_has(&st, GN_ROLE_CAMERA_ARM));
        CHECK(wrapped_distance(st.deg[GN_ROLE_TURNTABLE], from + 90.0) < 1e-6);
        CHECK(st.lamps == 0 && !st.lasers);

        char err[256] = "";
        CHECK(sim_scene_new(rc, &scene, err, sizeof err) == 0);
        CHECK(sim_render(scene, &st, 0, &(struct sim_expose){0}, 0, &f, 0, NULL) == 0);
        CHECK(f.width == 64 && f.height == 48);
        gn_frame_free_data(&f);
        sim_scene_free(scene);
        modbus_close(mb);
        modbus_free(mb);
        sim_emu_free(e);
        rigconf_free(rc);
        simtest_rmdir(dir);
}

int main(void)
{
        test_rtu();
        test_tcp();
        test_roles();
        return 0;
}
