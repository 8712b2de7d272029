/* test-gcode-emu.c - transcripts of gonio-sim's G-code controllers against the command set
 * the Horus 0.2 and GRBL 1.1 firmwares document (docs/gcode.md): bytes written to the pty as
 * a terminal would, replies compared byte for byte, including when "ok" comes (Horus: at the
 * end of a move; GRBL: as soon as the move is queued), realtime bytes, resets with and
 * without motion, alarms, errors, lasers and the light sensor, and the injected faults. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include "sim/gcode_emu.h"
#include "sim/modbus_emu.h"
#include "sim/motion.h"
#include "tests/sim/simtest.h"

#define TIME_SCALE 4.0
#define QUIET_S    0.08 /* no more bytes for this long: the reply is complete */

static const char rig_yaml[] =
        "rig: gcode\n"
        "buses:\n"
        "  - { name: ciclop, type: serial, port: \"${GONIO_SIM_DIR}/ciclop\" }\n"
        "  - { name: cnc, type: serial, port: \"${GONIO_SIM_DIR}/cnc\" }\n"
        "axes:\n"
        "  - { name: turntable, continuous: true, max_speed: 90, accel: 180,\n"
        "      gcode: { bus: ciclop, flavor: horus, axis: X } }\n"
        /* limits the emulator ignores, that put the power-on position 50..85 deg from the
         * home switch (sim/drive.c), so that homing lasts long enough to be seen */
        "  - { name: camera_arm, max_speed: 90, accel: 180, limits: [100, 170],\n"
        "      gcode: { bus: cnc, flavor: grbl, axis: X, steps_per_deg: 100 } }\n"
        "lasers:\n"
        "  - { name: left, gcode-laser: { bus: ciclop, tool: 1 } }\n"
        "  - { name: right, gcode-laser: { bus: ciclop, tool: 2 } }\n";

/* Real seconds a move of dist degrees takes at 90 deg/s, 180 deg/s^2. */
static double move_s(double dist)
{
        return motion_duration(dist, 90.0, 180.0) / TIME_SCALE;
}

static int open_port(const char *dir, const char *bus)
{
        char path[128];
        struct termios tio;
        int fd;

        snprintf(path, sizeof(path), "%s/%s", dir, bus);
        fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK);
        CHECK(fd >= 0);
        CHECK(tcgetattr(fd, &tio) == 0);
        cfmakeraw(&tio);
        CHECK(tcsetattr(fd, TCSANOW, &tio) == 0);
        CHECK(tcflush(fd, TCIOFLUSH) == 0);
        return fd;
}

static void send_str(int fd, const char *s)
{
        CHECK((size_t)write(fd, s, strlen(s)) == strlen(s));
}

/* Reads what comes within limit_s, until QUIET_S passes without a byte. */
static void read_reply(int fd, double limit_s, char *buf, size_t len)
{
        double end = simtest_now() + limit_s, last = 0;
        size_t n = 0;

        buf[0] = '\0';
        while (simtest_now() < end && !(n > 0 && simtest_now() - last > QUIET_S)) {
                struct pollfd p = {.fd = fd, .events = POLLIN};
                if (poll(&p, 1, 10) <= 0)
                        continue;
                ssize_t k = read(fd, buf + n, len - n - 1);
                if (k > 0) {
                        n += (size_t)k;
                        buf[n] = '\0';
                        last = simtest_now();
                }
        }
}

/* Sends req and checks the whole reply is want, byte for byte. */
static void transcript(int fd, const char *req, const char *want)
{
        char got[1024];

        send_str(fd, req);
        read_reply(fd, 0.5, got, sizeof(got));
        CHECK_STR(got, want);
}

/* Sends req and returns the real seconds until the reply, which must be want. */
static double timed(int fd, const char *req, const char *want, double limit_s)
{
        double t0 = simtest_now();
        char got[256];

        send_str(fd, req);
        read_reply(fd, limit_s, got, sizeof(got));
        CHECK_STR(got, want);
        return simtest_now() - t0 - QUIET_S;
}

/* The emulated lasers that are on, by rig-file index. */
static uint32_t lasers(struct sim_emu *e)
{
        struct gn_pose st;

        sim_emu_snapshot(e, &st);
        return st.lasers;
}

static void test_horus_basics(struct sim_emu *e, int fd)
{
        transcript(fd, "\x18", "\r\nHorus 0.2 ['$' for help]\r\n");
        transcript(fd, "?", "<Idle,MPos:0.000,0.000,0.000,WPos:0.000,0.000,0.000>\r\n");
        transcript(fd, "G1 X90\n", "error: Undefined feed rate\r\n");
        transcript(fd, "\n", ""); /* an empty line gets no answer */
        transcript(fd, "M71 T1\n", "ok\r\n");
        CHECK_INT(lasers(e), 1); /* tool 1: the rig's laser with tool 1, left */
        transcript(fd, "M71 T2\n", "ok\r\n");
        CHECK_INT(lasers(e), 3);
        transcript(fd, "M50 T1\n", "780\r\nok\r\n"); /* two lasers lit the sensor */
        transcript(fd, "m70t1\n", "ok\r\n");
        CHECK_INT(lasers(e), 2); /* tool 2 alone: right */
        transcript(fd, "M70 T2\n", "ok\r\n");
        CHECK_INT(lasers(e), 0);
        transcript(fd, "M50 T1\n", "180\r\nok\r\n");
        transcript(fd, "M17\n", "ok\r\n");
        transcript(fd, "Y10\n", "error: Unsupported command\r\n");
        transcript(fd, "G1 X1 X2 F60\n", "error: Invalid gcode ID:25\r\n");
        transcript(fd, "G1.5\n", "error: Invalid gcode ID:23\r\n");
        transcript(fd, "G1 X-\n", "error: Bad number format\r\n");
        transcript(fd, "1\n", "error: Expected command letter\r\n");
        transcript(fd, "M71 T-1\n", "error: Value < 0\r\n");
        transcript(fd, "$H\n", "error: Setting disabled\r\n");
        transcript(fd, "$X\n", "ok\r\n");
}

/* Horus answers a move when it has ended, and reads no line before. */
static void test_horus_move(int fd)
{
        char got[256];
        double t;

        send_str(fd, "G1 X90 (turn) F5400\n");
        usleep(100000);
        send_str(fd, "?");
        read_reply(fd, 0.5, got, sizeof(got));
        CHECK(strncmp(got, "<Run,MPos:", 10) == 0 && !strstr(got, "ok"));
        t = timed(fd, "M18\n", "ok\r\nok\r\n", 2.0); /* the move's ok, then M18's */
        CHECK(t > 0 && t < move_s(90) + 0.5);
        transcript(fd, "?", "<Idle,MPos:90.000,0.000,0.000,WPos:90.000,0.000,0.000>\r\n");
        t = timed(fd, "G1 X0\n", "ok\r\n", 2.0);
        CHECK(t > move_s(90) * 0.8 && t < move_s(90) + 0.5);
        transcript(fd, "G1 X45\n", "ok\r\n");
        transcript(fd, "G50\n", "ok\r\n");
        transcript(fd, "?", "<Idle,MPos:0.000,0.000,0.000,WPos:0.000,0.000,0.000>\r\n");
        /* positions count whole steps of 1/8.889 deg */
        transcript(fd, "G1 X1\n", "ok\r\n");
        transcript(fd, "?", "<Idle,MPos:1.012,0.000,0.000,WPos:1.012,0.000,0.000>\r\n");
}

static void test_horus_reset(struct sim_emu *e, int fd)
{
        transcript(fd, "M71 T1\n", "ok\r\n");
        send_str(fd, "G1 X300\n");
        usleep(100000);
        /* the killed line is still answered, then the board restarts locked, lasers off */
        transcript(fd, "\x18",
                   "ALARM: Abort during cycle\r\nok\r\n\r\nHorus 0.2 ['$' for help]\r\n"
                   "['$H'|'$X' to unlock]\r\n");
        CHECK_INT(lasers(e), 0);
        transcript(fd, "G1 X0 F600\n", "error: Alarm lock\r\n");
        transcript(fd, "$X\n", "[Caution: Unlocked]\r\nok\r\n");
        transcript(fd, "G1 X0\n", "error: Undefined feed rate\r\n"); /* reset forgot F */
        transcript(fd, "\x18", "\r\nHorus 0.2 ['$' for help]\r\n");  /* at rest: no alarm */
}

static void test_grbl(int fd)
{
        char got[256];
        double t;

        transcript(fd, "\x18", "\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n");
        transcript(fd, "?", "<Alarm|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>\r\n");
        transcript(fd, "?", "<Alarm|MPos:0.000,0.000,0.000|FS:0,0|Ov:100,100,100>\r\n");
        transcript(fd, "?", "<Alarm|MPos:0.000,0.000,0.000|FS:0,0>\r\n");
        transcript(fd, "G1 X10 F600\n", "error:9\r\n");
        send_str(fd, "$H\n");
        read_reply(fd, 0.05, got, sizeof(got));
        CHECK_STR(got, ""); /* answered when homing has ended */
        send_str(fd, "?");
        read_reply(fd, 0.5, got, sizeof(got));
        CHECK(strncmp(got, "<Home|MPos:", 11) == 0);
        timed(fd, "", "ok\r\n", 3.0);
        transcript(fd, "?", "<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n");
        /* a move is answered as soon as it is queued; the status says when it has ended */
        t = timed(fd, "G1 X90 F1800\n", "ok\r\n", 1.0); /* 30 deg/s: 0.9 s */
        CHECK(t < move_s(90) / 3);
        send_str(fd, "?");
        read_reply(fd, 0.5, got, sizeof(got));
        CHECK(strncmp(got, "<Run|MPos:", 10) == 0);
        transcript(fd, "!", "");
        send_str(fd, "?");
        read_reply(fd, 0.5, got, sizeof(got));
        CHECK(strncmp(got, "<Hold:0|MPos:", 13) == 0);
        transcript(fd, "~", "");
        usleep((useconds_t)(motion_duration(90, 30, 180) / TIME_SCALE * 1e6) + 300000);
        transcript(fd, "?", "<Idle|MPos:90.000,0.000,0.000|FS:0,0>\r\n");
        /* three blocks queued at once, each answered at once */
        transcript(fd, "G1 X10 F6000\nG1 X20\nG0 X30\n", "ok\r\nok\r\nok\r\n");
        usleep((useconds_t)(move_s(60) * 1e6) + 300000);
        /* feed hold, then reset: no alarm, position kept */
        transcript(fd, "G1 X80\n", "ok\r\n");
        transcript(fd, "!", "");
        transcript(fd, "\x18", "\r\nGrbl 1.1h ['$' for help]\r\n");
        /* reset mid-move: alarm 3, locked */
        transcript(fd, "G1 X0 F5400\n", "ok\r\n");
        transcript(fd, "\x18",
                   "ALARM:3\r\n\r\nGrbl 1.1h ['$' for help]\r\n"
                   "[MSG:'$H'|'$X' to unlock]\r\n");
        transcript(fd, "$X\n", "[MSG:Caution: Unlocked]\r\nok\r\n");
        transcript(fd, "\n", "ok\r\n"); /* GRBL 1.1 answers an empty line */
        transcript(fd, "G1 X1\n", "error:22\r\n");
        transcript(fd, "M3 S100\n", "error:20\r\n");
        transcript(fd, "$I\n", "error:3\r\n");
}

static void test_faults(struct sim_emu *e, int fd)
{
        char got[256];
        double t;

        CHECK_INT(sim_emu_inject(e, "ciclop", 0, SIM_FAULT_TIMEOUT), 0);
        transcript(fd, "?", "");
        transcript(fd, "\x18", "");
        CHECK_INT(sim_emu_inject(e, "ciclop", 0, SIM_FAULT_LATE), 0);
        t = timed(fd, "M17\n", "ok\r\n", 2.0);
        CHECK(t >= SIM_GCODE_LATE_MS / 1000.0 - 0.05);
        CHECK_INT(sim_emu_inject(e, "ciclop", 0, SIM_FAULT_ERROR), 0);
        transcript(fd, "M17\n", "error: Unsupported command\r\n");
        transcript(fd, "\n", "");
        send_str(fd, "?"); /* realtime bytes still work */
        read_reply(fd, 0.5, got, sizeof(got));
        CHECK(strncmp(got, "<Idle,MPos:", 11) == 0);
        CHECK_INT(sim_emu_inject(e, "ciclop", 0, SIM_FAULT_NONE), 0);
        transcript(fd, "M17\n", "ok\r\n");
        CHECK_INT(sim_emu_inject(e, "ciclop", 0, SIM_FAULT_STALL), -EINVAL);
        CHECK_INT(sim_emu_inject(e, "nowhere", 0, SIM_FAULT_TIMEOUT), -ENOENT);
}

int main(void)
{
        char dir[64];
        struct rig_config *rc = simtest_rig_text(dir, rig_yaml);
        struct sim_emu *e = NULL;

        CHECK_INT(sim_emu_new(rc, TIME_SCALE, &e), 0);
        CHECK(sim_emu_pty(e, "ciclop") != NULL);
        int horus = open_port(dir, "ciclop"), grbl = open_port(dir, "cnc");
        test_horus_basics(e, horus);
        test_horus_move(horus);
        test_horus_reset(e, horus);
        test_grbl(grbl);
        test_faults(e, horus);
        close(horus);
        close(grbl);
        sim_emu_free(e);
        rigconf_free(rc);
        simtest_rmdir(dir);
        return 0;
}
