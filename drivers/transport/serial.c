/* serial.c - the "serial" transport: a plain termios line (G-code controllers and other
 * line protocols) in raw mode, non-blocking, locked exclusively; reads and writes go
 * through the deadline-bounded stream helpers of transport.c. */
#include <errno.h>
#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "drivers/transport/transport.h"

static const struct {
        int baud;
        speed_t speed;
} bauds[] = {
        {1200, B1200},     {2400, B2400},     {4800, B4800},     {9600, B9600},
        {19200, B19200},   {38400, B38400},   {57600, B57600},   {115200, B115200},
        {230400, B230400}, {460800, B460800}, {921600, B921600},
};

/* Fills *tio for conf: raw, 8N1 or as configured, no flow control. VMIN 1 with O_NONBLOCK:
 * no data is EAGAIN (VMIN 0 would return 0, which the stream helpers take for a hangup).
 * Returns 0 or -EINVAL for a baud rate termios does not name. */
static int make_termios(const struct rig_bus_conf *c, struct termios *tio)
{
        static const tcflag_t sizes[] = {[5] = CS5, [6] = CS6, [7] = CS7, [8] = CS8};
        int baud = c->baud > 0 ? c->baud : 115200, bits = c->data_bits > 0 ? c->data_bits : 8;
        speed_t speed = 0;

        for (size_t i = 0; i < ELEMENTSOF(bauds); i++)
                if (bauds[i].baud == baud)
                        speed = bauds[i].speed;
        if (!speed || bits < 5 || bits > 8)
                return -EINVAL;
        cfmakeraw(tio);
        tio->c_cflag &= ~(CSIZE | PARENB | PARODD | CSTOPB | CRTSCTS);
        tio->c_cflag |= CLOCAL | CREAD | sizes[bits];
        if (c->parity == 'E' || c->parity == 'O')
                tio->c_cflag |= PARENB | (c->parity == 'O' ? PARODD : 0);
        if (c->stop_bits == 2)
                tio->c_cflag |= CSTOPB;
        tio->c_iflag &= ~(IXON | IXOFF | IXANY);
        tio->c_cc[VMIN] = 1;
        tio->c_cc[VTIME] = 0;
        cfsetispeed(tio, speed);
        cfsetospeed(tio, speed);
        return 0;
}

static int serial_open(struct transport *t)
{
        const char *port = t->conf->port;
        _cleanup_close_ int fd = -EBADF;
        struct termios tio;
        int r;

        fd = open(port, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0)
                return transport_port_error(t, errno);
        r = transport_lock_line(t, fd);
        if (r < 0)
                return r;
        if (tcgetattr(fd, &tio) < 0)
                return transport_set_cause(t, -errno, "port %s is not a serial line: %m", port);
        if (make_termios(t->conf, &tio) < 0)
                return transport_set_cause(
                        t, -EINVAL, "port %s: unsupported line settings %d %d%c%d", port,
                        t->conf->baud, t->conf->data_bits, t->conf->parity ? t->conf->parity : 'N',
                        t->conf->stop_bits);
        if (tcsetattr(fd, TCSANOW, &tio) < 0)
                return transport_set_cause(t, -errno, "cannot configure port %s: %m", port);
        (void)tcflush(fd, TCIOFLUSH);
        t->fd = TAKE_FD(fd);
        return 0;
}

static void serial_close(struct transport *t)
{
        transport_unlock_line(t->fd);
        close(t->fd);
}

static void serial_flush(struct transport *t)
{
        (void)tcflush(t->fd, TCIFLUSH);
}

const struct transport_ops transport_serial_ops = {
        .name = "serial",
        .type = RIG_BUS_SERIAL,
        .stream = true,
        .open = serial_open,
        .close = serial_close,
        .flush = serial_flush,
};
