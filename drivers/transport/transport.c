/* transport.c - what every transport shares: lookup by bus type, lazy open, the cause
 * of the last failure, counters, the retry-message rate limit, the exclusive lock of
 * serial lines, and the deadline-bounded reads and writes of stream transports. */
#include <errno.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <linux/major.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/transport/transport.h"

#define RATELIMIT_BURST       10
#define RATELIMIT_INTERVAL_NS (5 * 1000000000ULL)

static const struct transport_ops *const transports[] = {
        &transport_modbus_rtu_ops, &transport_modbus_tcp_ops, &transport_sim_ops,
        &transport_serial_ops,     &transport_local_ops,
};

int transport_new(const struct rig_bus_conf *conf, struct transport **ret)
{
        const struct transport_ops *ops = NULL;
        struct transport *t;

        for (size_t i = 0; i < ELEMENTSOF(transports); i++)
                if (transports[i]->type == conf->type)
                        ops = transports[i];
        if (!ops)
                return -EOPNOTSUPP;
        t = calloc(1, sizeof(*t));
        if (!t)
                return -ENOMEM;
        *t = (struct transport){.ops = ops, .conf = conf, .fd = -1};
        *ret = t;
        return 0;
}

struct transport *transport_free(struct transport *t)
{
        if (!t)
                return NULL;
        transport_close(t);
        if (t->priv_free)
                t->priv_free(t->priv);
        free(t);
        return NULL;
}

int transport_open(struct transport *t)
{
        int r;

        if (t->is_open)
                return 0;
        t->cause[0] = '\0';
        r = t->ops->open(t);
        t->open_failed = r < 0;
        if (r < 0)
                return log_error_errno(r, "bus '%s': %s", t->conf->name, t->cause);
        if (t->opened_once)
                transport_count(&t->stats.reconnects);
        t->opened_once = true;
        t->is_open = true;
        t->in_len = 0;
        return 0;
}

void transport_close(struct transport *t)
{
        if (!t->is_open)
                return;
        t->ops->close(t);
        t->is_open = false;
        t->fd = -1;
        t->in_len = 0;
}

void transport_flush(struct transport *t)
{
        t->in_len = 0;
        if (t->is_open && t->ops->flush)
                t->ops->flush(t);
}

const char *transport_cause(const struct transport *t)
{
        return t->cause;
}

int transport_set_cause(struct transport *t, int err, const char *fmt, ...)
{
        int saved = errno;
        va_list ap;

        errno = err < 0 ? -err : err;
        va_start(ap, fmt);
        vsnprintf(t->cause, sizeof(t->cause), fmt, ap);
        va_end(ap);
        errno = saved;
        return err < 0 ? err : -err;
}

void transport_get_stats(const struct transport *t, struct transport_stats *ret)
{
        ret->requests = __atomic_load_n(&t->stats.requests, __ATOMIC_RELAXED);
        ret->retries = __atomic_load_n(&t->stats.retries, __ATOMIC_RELAXED);
        ret->failures = __atomic_load_n(&t->stats.failures, __ATOMIC_RELAXED);
        ret->reconnects = __atomic_load_n(&t->stats.reconnects, __ATOMIC_RELAXED);
}

void transport_count(uint64_t *counter)
{
        __atomic_fetch_add(counter, 1, __ATOMIC_RELAXED);
}

bool transport_ratelimit_ok(struct transport *t)
{
        uint64_t now = gn_monotonic_ns();

        if (t->rl_n == 0 || now - t->rl_begin_ns >= RATELIMIT_INTERVAL_NS) {
                if (t->rl_suppressed > 0)
                        log_warning("bus '%s': %u retry messages suppressed", t->conf->name,
                                    t->rl_suppressed);
                t->rl_begin_ns = now;
                t->rl_n = t->rl_suppressed = 0;
        }
        if (t->rl_n < RATELIMIT_BURST) {
                t->rl_n++;
                return true;
        }
        t->rl_suppressed++;
        return false;
}

int transport_port_error(struct transport *t, int err)
{
        err = err < 0 ? err : -err;
        if (err == -EBUSY)
                return transport_set_cause(t, err, "port %s is in use by another process",
                                           t->conf->port);
        return transport_set_cause(t, err, "cannot open port %s: %m", t->conf->port);
}

/* True for the slave side of a Unix98 pseudo-terminal (gonio-sim's emulated lines). */
static bool is_pty_slave(int fd)
{
        struct stat st;

        return fstat(fd, &st) == 0 && S_ISCHR(st.st_mode) &&
               major(st.st_rdev) >= UNIX98_PTY_SLAVE_MAJOR &&
               major(st.st_rdev) < UNIX98_PTY_SLAVE_MAJOR + UNIX98_PTY_MAJOR_COUNT;
}

int transport_lock_line(struct transport *t, int fd)
{
        if (flock(fd, LOCK_EX | LOCK_NB) < 0)
                return transport_port_error(t, errno == EWOULDBLOCK ? EBUSY : errno);
        /* BEWARE: TIOCEXCL outlives a crashed holder while anyone keeps the tty open, and
         * gonio-sim keeps its pty slaves open: a restarted goniod would be locked out of
         * its own line. The flock dies with its process, so ptys get only that. Devices
         * without TIOCEXCL fail it harmlessly. */
        if (!is_pty_slave(fd))
                (void)ioctl(fd, TIOCEXCL);
        return 0;
}

void transport_unlock_line(int fd)
{
        (void)ioctl(fd, TIOCNXCL);
}

int64_t transport_deadline(int timeout_ms)
{
        return (int64_t)(gn_monotonic_ns() / 1000000) + timeout_ms;
}

/* Waits for events on fd until deadline. Returns 0 or -ETIMEDOUT/-errno. */
static int wait_fd(int fd, short events, int64_t deadline)
{
        struct pollfd p = {.fd = fd, .events = events};

        for (;;) {
                int64_t left = deadline - (int64_t)(gn_monotonic_ns() / 1000000);
                if (left <= 0)
                        return -ETIMEDOUT;
                int r = poll(&p, 1, (int)MIN(left, (int64_t)INT32_MAX));
                if (r > 0)
                        return 0;
                if (r < 0 && errno != EINTR)
                        return -errno;
        }
}

/* A stream transport, opened. Returns 0 or -errno. */
static int stream_ready(struct transport *t)
{
        if (!t->ops->stream)
                return -EOPNOTSUPP;
        return transport_open(t);
}

/* Keeps the cause of a failed read or write; closes the link unless it only timed out
 * (then the bytes received so far stay buffered). Returns r. */
static int broken(struct transport *t, int r, const char *what)
{
        transport_set_cause(t, r, "%s %s: %m", what, t->conf->port);
        if (r != -ETIMEDOUT)
                transport_close(t);
        return r;
}

int transport_write_all(struct transport *t, const void *p, size_t n, int64_t deadline)
{
        const char *c = p;
        int r = stream_ready(t);

        if (r < 0)
                return r;
        while (n > 0) {
                ssize_t k = t->ops->socket ? send(t->fd, c, n, MSG_NOSIGNAL) : write(t->fd, c, n);
                if (k > 0) {
                        c += k;
                        n -= (size_t)k;
                        continue;
                }
                r = k < 0 && errno == EAGAIN  ? wait_fd(t->fd, POLLOUT, deadline)
                    : k < 0 && errno == EINTR ? 0
                                              : (k < 0 ? -errno : -EIO);
                if (r < 0)
                        return broken(t, r, "write to");
        }
        return 0;
}

/* Reads what the link has (at most n bytes) into p, waiting until deadline. Returns
 * the count, -ECONNRESET at end of stream, -ETIMEDOUT or -errno. */
static ssize_t read_some(struct transport *t, void *p, size_t n, int64_t deadline)
{
        for (;;) {
                ssize_t k = read(t->fd, p, n);
                if (k > 0)
                        return k;
                if (k == 0)
                        return -ECONNRESET;
                if (errno == EINTR)
                        continue;
                if (errno != EAGAIN)
                        return -errno;
                int r = wait_fd(t->fd, POLLIN, deadline);
                if (r < 0)
                        return r;
        }
}

/* Appends what the link has to t->in. Returns the count or -errno. */
static ssize_t fill(struct transport *t, int64_t deadline)
{
        ssize_t k = read_some(t, t->in + t->in_len, sizeof(t->in) - t->in_len, deadline);

        if (k > 0)
                t->in_len += (size_t)k;
        return k;
}

static void consume(struct transport *t, size_t n)
{
        memmove(t->in, t->in + n, t->in_len - n);
        t->in_len -= n;
}

/* Drops a line too long for the caller: through its delim when buffered, else all. */
static ssize_t too_long(struct transport *t, char delim, size_t max)
{
        char *end = memchr(t->in, delim, t->in_len);

        consume(t, end ? (size_t)(end - t->in) + 1 : t->in_len);
        return transport_set_cause(t, -EMSGSIZE, "line longer than %zu bytes", max);
}

ssize_t transport_read_until(struct transport *t, char delim, char *buf, size_t len,
                             int64_t deadline)
{
        size_t max = MIN(len, sizeof(t->in)) - 1;
        int r = len > 0 ? stream_ready(t) : -EINVAL;

        if (r < 0)
                return r;
        for (;;) {
                char *end = memchr(t->in, delim, t->in_len);
                if (end && (size_t)(end - t->in) <= max) {
                        size_t n = (size_t)(end - t->in);
                        memcpy(buf, t->in, n);
                        buf[n] = '\0';
                        consume(t, n + 1);
                        return (ssize_t)n;
                }
                if (end || t->in_len > max)
                        return too_long(t, delim, max);
                ssize_t k = fill(t, deadline);
                if (k < 0)
                        return broken(t, (int)k, "read from");
        }
}

ssize_t transport_read_line(struct transport *t, char *buf, size_t len, int64_t deadline)
{
        ssize_t n = transport_read_until(t, '\n', buf, len, deadline);

        if (n > 0 && buf[n - 1] == '\r')
                buf[--n] = '\0';
        return n;
}

int transport_read_bytes(struct transport *t, void *dst, size_t n, int64_t deadline)
{
        uint8_t *d = dst;
        int r = stream_ready(t);

        if (r < 0)
                return r;
        while (n > 0) {
                size_t k = MIN(n, t->in_len);
                ssize_t got = (ssize_t)k;
                if (k > 0) {
                        if (d)
                                memcpy(d, t->in, k);
                        consume(t, k);
                } else if (d) /* large payloads go straight to their buffer */
                        got = read_some(t, d, n, deadline);
                else
                        got = read_some(t, t->in, MIN(n, sizeof(t->in)), deadline);
                if (got < 0)
                        return broken(t, (int)got, "read from");
                if (d)
                        d += got;
                n -= (size_t)got;
        }
        return 0;
}
