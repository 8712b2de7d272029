/* bus.c - a physical bus (RS-485 line, TCP link, gonio-sim socket) with its worker
 * thread and its libmodbus connection, and the Modbus transactions drivers use.
 *
 * DESIGN
 * Threads: a bus made by bus_new() owns one workq (common/workq.h): the worker runs the
 * jobs queued by bus_submit() one at a time, and owns the libmodbus context; no other
 * thread touches it. Results come back to the loop thread through the workq's eventfd.
 * A bus made by bus_new_sync() has no worker: its owner's thread does all of that and
 * bus_submit() runs job and done inline.
 *
 * Queue: BUS_QUEUE_MAX jobs in flight; a full queue gives -EAGAIN to the caller. Urgent
 * jobs (stop) run before any queued job and have reserved slots, but never interrupt
 * the running one: no single transaction lasts longer than timeout_ms x (retries + 1).
 *
 * Errors: every transaction goes through transact(): a timeout, a corrupt frame or an
 * I/O error is retried at most conf->retries times (after modbus_flush, or after closing
 * the connection for I/O errors); a Modbus exception is an answer and is not retried.
 * The final errno is mapped to -ETIMEDOUT, -EPROTO or -EIO and logged with
 * modbus_strerror(). After an I/O error the connection is closed, so the next attempt
 * reconnects; after a timeout or a corrupt frame the line is flushed (a late reply must
 * not be taken for the next one). Counters are kept in struct bus_stats. */
#include <errno.h>
#include <modbus/modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "common/clock.h"
#include "common/log.h"
#include "common/workq.h"
#include "drivers/bus/bus.h"

#define RATELIMIT_BURST       10
#define RATELIMIT_INTERVAL_NS (5 * 1000000000ULL)

enum failure_kind {
        FAIL_TIMEOUT, /* no answer: flush, retry */
        FAIL_FRAME,   /* corrupt or foreign frame: flush, retry */
        FAIL_EXCEPTION,
        FAIL_IO, /* the line or link broke: reconnect, retry */
        FAIL_ARG,
};

struct ratelimit {
        uint64_t begin_ns;
        unsigned n, suppressed;
};

struct bus {
        struct rig_bus_conf conf;
        struct workq *q; /* NULL for a sync bus */
        modbus_t *mb;
        bool connected_once;
        struct bus_stats stats;
        struct ratelimit rl;
};

struct bus_job {
        struct bus *bus;
        bus_job_fn fn;
        bus_done_fn done;
        void *userdata;
};

static int new_common(const struct rig_bus_conf *conf, struct bus **ret)
{
        struct bus *b;

        if (!conf || !ret)
                return -EINVAL;
        b = calloc(1, sizeof(*b));
        if (!b)
                return -ENOMEM;
        b->conf = *conf;
        *ret = b;
        return 0;
}

int bus_new_sync(const struct rig_bus_conf *conf, struct bus **ret)
{
        return new_common(conf, ret);
}

int bus_new(sd_event *event, const struct rig_bus_conf *conf, struct bus **ret)
{
        struct bus *b;
        int r;

        r = new_common(conf, &b);
        if (r < 0)
                return r;
        r = workq_new(event, conf->name, BUS_QUEUE_MAX, &b->q);
        if (r < 0) {
                free(b);
                return log_error_errno(r, "bus '%s': Failed to start worker: %m", conf->name);
        }
        *ret = b;
        return 0;
}

struct bus *bus_free(struct bus *b)
{
        if (!b)
                return NULL;
        b->q = workq_free(b->q);
        bus_reset(b);
        free(b);
        return NULL;
}

static int run_job(void *userdata)
{
        struct bus_job *j = userdata;

        return j->fn(j->bus, j->userdata);
}

static void job_done(int result, void *userdata)
{
        struct bus_job *j = userdata;

        if (j->done)
                j->done(j->bus, result, j->userdata);
        free(j);
}

int bus_submit(struct bus *b, bus_job_fn job, bus_done_fn done, void *userdata, bool urgent)
{
        struct bus_job *j;
        int r;

        if (!b || !job)
                return -EINVAL;
        if (!b->q) {
                r = job(b, userdata);
                if (done)
                        done(b, r, userdata);
                return 0;
        }
        j = malloc(sizeof(*j));
        if (!j)
                return -ENOMEM;
        *j = (struct bus_job){.bus = b, .fn = job, .done = done, .userdata = userdata};
        r = workq_push(b->q, run_job, job_done, j, urgent);
        if (r < 0)
                free(j);
        return r;
}

const struct rig_bus_conf *bus_conf(const struct bus *b)
{
        return &b->conf;
}

void bus_get_stats(const struct bus *b, struct bus_stats *ret)
{
        ret->requests = __atomic_load_n(&b->stats.requests, __ATOMIC_RELAXED);
        ret->retries = __atomic_load_n(&b->stats.retries, __ATOMIC_RELAXED);
        ret->failures = __atomic_load_n(&b->stats.failures, __ATOMIC_RELAXED);
        ret->reconnects = __atomic_load_n(&b->stats.reconnects, __ATOMIC_RELAXED);
}

static void count(uint64_t *counter)
{
        __atomic_fetch_add(counter, 1, __ATOMIC_RELAXED);
}

void bus_reset(struct bus *b)
{
        if (!b->mb)
                return;
        modbus_close(b->mb);
        modbus_free(b->mb);
        b->mb = NULL;
}

static enum failure_kind classify(int err)
{
        if (err == ETIMEDOUT)
                return FAIL_TIMEOUT;
        if (err == EMBBADCRC || err == EMBBADDATA || err == EMBBADSLAVE)
                return FAIL_FRAME;
        if (err >= MODBUS_ENOBASE && err <= EMBBADSLAVE)
                return err == EMBMDATA ? FAIL_ARG : FAIL_EXCEPTION;
        return err == EINVAL ? FAIL_ARG : FAIL_IO;
}

int bus_modbus_errno(int err)
{
        switch (classify(err < 0 ? -err : err)) {
        case FAIL_TIMEOUT:
                return -ETIMEDOUT;
        case FAIL_FRAME:
        case FAIL_EXCEPTION:
                return -EPROTO;
        default:
                return -EIO;
        }
}

static modbus_t *new_context(const struct rig_bus_conf *c)
{
        if (c->type == RIG_BUS_MODBUS_TCP)
                return modbus_new_tcp(c->host[0] ? c->host : "127.0.0.1", c->tcp_port);
        return modbus_new_rtu(c->port, c->baud > 0 ? c->baud : 115200, c->parity ? c->parity : 'N',
                              c->data_bits > 0 ? c->data_bits : 8,
                              c->stop_bits > 0 ? c->stop_bits : 1);
}

/* Opens the libmodbus connection; returns 0 or -errno from bus_modbus_errno(). */
static int connect_bus(struct bus *b)
{
        int ms = b->conf.timeout_ms > 0 ? b->conf.timeout_ms : 200;
        modbus_t *mb;
        int err;

        mb = new_context(&b->conf);
        if (!mb)
                return log_error_errno(errno,
                                       "bus '%s': Failed to create Modbus context for %s: %m",
                                       b->conf.name, b->conf.port);
        if (modbus_set_response_timeout(mb, ms / 1000, (ms % 1000) * 1000) < 0 ||
            modbus_connect(mb) < 0) {
                err = errno;
                modbus_free(mb);
                log_debug("bus '%s': Failed to connect to %s: %s", b->conf.name,
                          b->conf.type == RIG_BUS_MODBUS_TCP ? b->conf.host : b->conf.port,
                          modbus_strerror(err));
                errno = err;
                return -1;
        }
        if (b->connected_once)
                count(&b->stats.reconnects);
        b->connected_once = true;
        b->mb = mb;
        return 0;
}

/* Like bus_modbus() but returns -1 with errno set, for transact(). */
static int get_context(struct bus *b, int unit, modbus_t **ret)
{
        if (b->conf.type == RIG_BUS_SIM) {
                errno = EINVAL;
                return -1;
        }
        if (!b->mb && connect_bus(b) < 0)
                return -1;
        if (modbus_set_slave(b->mb, unit) < 0)
                return -1;
        *ret = b->mb;
        return 0;
}

int bus_modbus(struct bus *b, int unit, modbus_t **ret)
{
        if (b->conf.type == RIG_BUS_SIM)
                return -EOPNOTSUPP;
        if (get_context(b, unit, ret) < 0)
                return log_warning_errno(bus_modbus_errno(errno), "bus '%s': unit %d: %s",
                                         b->conf.name, unit, modbus_strerror(errno));
        return 0;
}

enum mb_fn { MB_READ_REGS, MB_WRITE_REG, MB_WRITE_REGS, MB_READ_COILS, MB_WRITE_COIL };

struct mb_req {
        enum mb_fn fn;
        int unit, addr, n;
        uint16_t *dest;
        const uint16_t *src;
        uint8_t *bits;
        int value;
};

static const char *const mb_fn_names[] = {
        [MB_READ_REGS] = "read registers",   [MB_WRITE_REG] = "write register",
        [MB_WRITE_REGS] = "write registers", [MB_READ_COILS] = "read coils",
        [MB_WRITE_COIL] = "write coil",
};

static int do_request(modbus_t *mb, const struct mb_req *q)
{
        switch (q->fn) {
        case MB_READ_REGS:
                return modbus_read_registers(mb, q->addr, q->n, q->dest);
        case MB_WRITE_REG:
                return modbus_write_register(mb, q->addr, q->value);
        case MB_WRITE_REGS:
                return modbus_write_registers(mb, q->addr, q->n, q->src);
        case MB_READ_COILS:
                return modbus_read_bits(mb, q->addr, q->n, q->bits);
        case MB_WRITE_COIL:
                return modbus_write_bit(mb, q->addr, q->value);
        }
        errno = EINVAL;
        return -1;
}

/* At most RATELIMIT_BURST retry messages per interval and bus; reports what it hid. */
static bool ratelimit_ok(struct bus *b)
{
        struct ratelimit *rl = &b->rl;
        uint64_t now = gn_monotonic_ns();

        if (rl->n == 0 || now - rl->begin_ns >= RATELIMIT_INTERVAL_NS) {
                if (rl->suppressed > 0)
                        log_warning("bus '%s': %u retry messages suppressed", b->conf.name,
                                    rl->suppressed);
                *rl = (struct ratelimit){.begin_ns = now};
        }
        if (rl->n < RATELIMIT_BURST) {
                rl->n++;
                return true;
        }
        rl->suppressed++;
        return false;
}

/* Gets the line back in step after a failed attempt. */
static void recover(struct bus *b, int err)
{
        switch (classify(err)) {
        case FAIL_TIMEOUT:
        case FAIL_FRAME:
                if (b->mb)
                        modbus_flush(b->mb);
                break;
        case FAIL_IO:
                bus_reset(b);
                break;
        default:
                break;
        }
}

static bool retryable(int err)
{
        enum failure_kind k = classify(err);

        return k == FAIL_TIMEOUT || k == FAIL_FRAME || k == FAIL_IO;
}

static int transact(struct bus *b, const struct mb_req *q)
{
        int retries = MAX(b->conf.retries, 0);
        modbus_t *mb = NULL;
        int n, err;

        count(&b->stats.requests);
        for (int attempt = 1;; attempt++) {
                n = get_context(b, q->unit, &mb) < 0 ? -1 : do_request(mb, q);
                if (n >= 0)
                        return n;
                err = errno;
                recover(b, err);
                if (!retryable(err) || attempt > retries)
                        break;
                count(&b->stats.retries);
                if (ratelimit_ok(b))
                        log_warning("bus '%s': unit %d: %s 0x%04x: %s, retry %d/%d", b->conf.name,
                                    q->unit, mb_fn_names[q->fn], (unsigned)q->addr,
                                    modbus_strerror(err), attempt, retries);
        }
        count(&b->stats.failures);
        return gn_log_full_errno(GN_LOG_NOTICE, bus_modbus_errno(err),
                                 "bus '%s': unit %d: %s 0x%04x failed: %s", b->conf.name, q->unit,
                                 mb_fn_names[q->fn], (unsigned)q->addr, modbus_strerror(err));
}

int bus_read_regs(struct bus *b, int unit, int addr, int n, uint16_t *dest)
{
        return transact(b, &(struct mb_req){MB_READ_REGS, unit, addr, n, .dest = dest});
}

int bus_write_reg(struct bus *b, int unit, int addr, uint16_t value)
{
        return transact(b, &(struct mb_req){MB_WRITE_REG, unit, addr, 1, .value = value});
}

int bus_write_regs(struct bus *b, int unit, int addr, int n, const uint16_t *src)
{
        return transact(b, &(struct mb_req){MB_WRITE_REGS, unit, addr, n, .src = src});
}

int bus_read_coils(struct bus *b, int unit, int addr, int n, uint8_t *dest)
{
        return transact(b, &(struct mb_req){MB_READ_COILS, unit, addr, n, .bits = dest});
}

int bus_write_coil(struct bus *b, int unit, int addr, bool on)
{
        return transact(b, &(struct mb_req){MB_WRITE_COIL, unit, addr, 1, .value = on});
}

/* "PORT#UNIT": the port's last path component (host:port for TCP), unit left out if < 0. */
static void where(const struct bus *b, int unit, char *buf, size_t len)
{
        const struct rig_bus_conf *c = &b->conf;
        const char *slash = strrchr(c->port, '/');
        int k;

        if (c->type == RIG_BUS_MODBUS_TCP)
                k = snprintf(buf, len, "%s:%d", c->host, c->tcp_port);
        else
                k = snprintf(buf, len, "%s", slash ? slash + 1 : c->port);
        if (unit >= 0 && k >= 0 && (size_t)k < len)
                snprintf(buf + k, len - k, "#%d", unit);
}

int bus_log_dev(const struct bus *b, int level, int err, const char *kind, const char *name,
                const char *backend, int unit, const char *fmt, va_list ap)
{
        char loc[RIG_PATH_MAX + 16], msg[1024];
        int saved = errno;

        where(b, unit, loc, sizeof(loc));
        errno = err < 0 ? -err : err;
        vsnprintf(msg, sizeof(msg), fmt, ap);
        errno = saved;
        return gn_log_full_errno(level, err, "%s '%s' [%s@%s]: %s", kind, name, backend, loc, msg);
}
