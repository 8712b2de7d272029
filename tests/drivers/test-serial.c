/* test-serial.c - the serial transport against a real pty pair (the test holds the
 * master, the transport opens the slave path like any serial port): writes and reads
 * with deadlines (-ETIMEDOUT at the deadline, a partial line kept for the next read),
 * lines longer than the caller's buffer (-EMSGSIZE, the line dropped, the next one
 * fine), flush, a write that cannot drain, a missing port (-ENOENT naming the path,
 * at once), and the exclusive lock of the port (-EBUSY naming the port). */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/clock.h"
#include "drivers/bus/bus.h"
#include "drivers/transport/transport.h"
#include "tests/test.h"

struct pty {
        int master;
        struct rig_bus_conf conf;
};

static void pty_open(struct pty *p)
{
        struct termios tio;

        p->master = posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
        CHECK(p->master >= 0);
        CHECK(grantpt(p->master) == 0 && unlockpt(p->master) == 0);
        CHECK(tcgetattr(p->master, &tio) == 0);
        cfmakeraw(&tio);
        CHECK(tcsetattr(p->master, TCSANOW, &tio) == 0);
        p->conf = (struct rig_bus_conf){.name = "gcode",
                                        .type = RIG_BUS_SERIAL,
                                        .baud = 115200,
                                        .parity = 'N',
                                        .data_bits = 8,
                                        .stop_bits = 1,
                                        .timeout_ms = 200};
        CHECK(ptsname_r(p->master, p->conf.port, sizeof(p->conf.port)) == 0);
}

static double now_s(void)
{
        return (double)gn_monotonic_ns() * 1e-9;
}

static void master_write(struct pty *p, const char *s)
{
        CHECK(write(p->master, s, strlen(s)) == (ssize_t)strlen(s));
}

/* Reads n bytes the transport wrote from the master side. */
static void master_expect(struct pty *p, const char *s)
{
        char buf[256];
        size_t n = strlen(s), got = 0;

        while (got < n) {
                struct pollfd pf = {.fd = p->master, .events = POLLIN};
                CHECK(poll(&pf, 1, 2000) == 1);
                ssize_t k = read(p->master, buf + got, n - got);
                CHECK(k > 0);
                got += (size_t)k;
        }
        CHECK(memcmp(buf, s, n) == 0);
}

static void test_lines(struct transport *t, struct pty *p)
{
        char line[64];

        CHECK_INT(transport_write_all(t, "G0 X10\n", 7, transport_deadline(200)), 0);
        master_expect(p, "G0 X10\n");
        master_write(p, "ok\r\nerror:2\n<Idle|MPos:1.000>");
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), 2);
        CHECK_STR(line, "ok");
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), 7);
        CHECK_STR(line, "error:2");
        CHECK_INT(transport_read_until(t, '>', line, sizeof(line), transport_deadline(200)), 16);
        CHECK_STR(line, "<Idle|MPos:1.000");
}

/* A partial line times out at the deadline and is completed by the next read. */
static void test_deadline(struct transport *t, struct pty *p)
{
        char line[64];
        double t0, took;

        master_write(p, "o");
        t0 = now_s();
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(150)), -ETIMEDOUT);
        took = now_s() - t0;
        fprintf(stderr, "read timed out after %.3f s\n", took);
        CHECK(took >= 0.14 && took < 1.0);
        CHECK_STR_CONTAINS(transport_cause(t), "Connection timed out");
        CHECK(t->is_open); /* a timeout keeps the line */

        t0 = now_s();
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(-5)), -ETIMEDOUT);
        CHECK(now_s() - t0 < 0.05); /* a past deadline does not wait */

        master_write(p, "k\n");
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), 2);
        CHECK_STR(line, "ok");
}

static void test_long_lines(struct transport *t, struct pty *p)
{
        char line[16], big[TRANSPORT_BUF_MAX + 100];

        master_write(p, "0123456789abcdefXYZ\nok\n"); /* 19 bytes > 15 */
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), -EMSGSIZE);
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), 2);
        CHECK_STR(line, "ok");

        /* longer than the transport's own buffer, no newline in sight */
        memset(big, 'x', sizeof(big) - 1);
        big[sizeof(big) - 1] = '\0';
        master_write(p, big);
        CHECK_INT(transport_read_line(t, big, sizeof(big), transport_deadline(500)), -EMSGSIZE);
        transport_flush(t);
}

static void test_flush(struct transport *t, struct pty *p)
{
        char line[16];

        master_write(p, "stale reply\n");
        usleep(20000);
        transport_flush(t);
        master_write(p, "ok\n");
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), 2);
        CHECK_STR(line, "ok");
}

/* Nobody reads the master: the pty's queue fills and the write gives up at the deadline. */
static void test_write_deadline(struct transport *t)
{
        static char chunk[1 << 20];
        double t0 = now_s(), took;

        memset(chunk, 'G', sizeof(chunk));
        CHECK_INT(transport_write_all(t, chunk, sizeof(chunk), transport_deadline(150)),
                  -ETIMEDOUT);
        took = now_s() - t0;
        fprintf(stderr, "write timed out after %.3f s\n", took);
        CHECK(took >= 0.14 && took < 1.0);
}

/* While the port is held, another process is refused too (by the flock: ptys get no
 * TIOCEXCL), also an unprivileged one (as root the child drops to nobody); and it can
 * still open(2) the pty: no TIOCEXCL that a crashed goniod would leave behind. */
static void test_lock_other_process(struct pty *p)
{
        struct transport *t = NULL;
        int status;
        pid_t pid;

        if (geteuid() == 0)
                CHECK(chown(p->conf.port, 65534, -1) == 0);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                if (geteuid() == 0 && (setgid(65534) < 0 || setuid(65534) < 0))
                        _exit(2);
                int fd = open(p->conf.port, O_RDWR | O_NOCTTY | O_CLOEXEC);
                CHECK(fd >= 0);
                close(fd);
                CHECK_INT(transport_new(&p->conf, &t), 0);
                CHECK_INT(transport_open(t), -EBUSY);
                CHECK_STR_CONTAINS(transport_cause(t), "is in use by another process");
                _exit(0);
        }
        CHECK(waitpid(pid, &status, 0) == pid);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

/* A second bus on the same port is refused with -EBUSY, at once, naming the port; the
 * lock goes with the first bus. */
static void test_lock(struct pty *p)
{
        struct bus *a = NULL, *b = NULL;
        struct transport_stats st;
        char line[16];

        CHECK_INT(bus_new_sync(&p->conf, &a), 0);
        CHECK_INT(bus_new_sync(&p->conf, &b), 0);
        CHECK_INT(transport_open(bus_transport(a)), 0);
        CHECK_INT(transport_open(bus_transport(b)), -EBUSY);
        CHECK_STR_CONTAINS(transport_cause(bus_transport(b)), p->conf.port);
        CHECK_STR_CONTAINS(transport_cause(bus_transport(b)), "is in use by another process");
        CHECK_INT(transport_read_line(bus_transport(b), line, sizeof(line), transport_deadline(50)),
                  -EBUSY);
        transport_get_stats(bus_transport(b), &st);
        CHECK_INT(st.retries, 0);
        test_lock_other_process(p);
        a = bus_free(a);
        CHECK_INT(transport_open(bus_transport(b)), 0);
        b = bus_free(b);
}

static void test_missing_port(void)
{
        struct rig_bus_conf c = {.name = "gcode",
                                 .type = RIG_BUS_SERIAL,
                                 .timeout_ms = 200,
                                 .port = "/dev/gonio-no-such-port"};
        struct transport *t = NULL;
        char line[16];
        double t0 = now_s();

        CHECK_INT(transport_new(&c, &t), 0);
        CHECK_INT(transport_read_line(t, line, sizeof(line), transport_deadline(200)), -ENOENT);
        CHECK(now_s() - t0 < 0.1);
        CHECK_STR_CONTAINS(transport_cause(t), "/dev/gonio-no-such-port");

        /* a regular file is not a serial line */
        snprintf(c.port, sizeof(c.port), "/proc/self/status");
        t = transport_free(t);
        CHECK_INT(transport_new(&c, &t), 0);
        CHECK_INT(transport_open(t), -ENOTTY);
        CHECK_STR_CONTAINS(transport_cause(t), "is not a serial line");
        t = transport_free(t);
}

int main(void)
{
        struct transport *t = NULL;
        struct pty p;

        pty_open(&p);
        CHECK_INT(transport_new(&p.conf, &t), 0);
        CHECK_INT(transport_open(t), 0);
        test_lines(t, &p);
        test_deadline(t, &p);
        test_long_lines(t, &p);
        test_flush(t, &p);
        test_write_deadline(t);
        t = transport_free(t);
        tcflush(p.master, TCIOFLUSH);

        test_lock(&p);
        test_missing_port();
        close(p.master);
        return 0;
}
