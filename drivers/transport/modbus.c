/* modbus.c - the modbus-rtu and modbus-tcp transports (a libmodbus context per link)
 * and the Modbus transactions drivers use, with their retry policy (see modbus.h).
 *
 * DESIGN
 * Every transaction goes through transact(): a timeout, a corrupt frame or an I/O error
 * is retried at most conf->retries times (after modbus_flush, or after closing the link
 * for I/O errors, so that the next attempt reopens it); a Modbus exception is an answer
 * and is not retried; a link that cannot be opened is not retried either (a missing,
 * forbidden or locked port does not come back within a few milliseconds). The final
 * errno is mapped to -ETIMEDOUT, -EPROTO or -EIO and its modbus_strerror() text becomes
 * the transport's cause. No single transaction lasts longer than timeout_ms x (retries +
 * 1), which bounds how long an urgent job (stop) waits behind it. */
#include <errno.h>
#include <modbus/modbus.h>
#include <string.h>

#include "common/log.h"
#include "drivers/transport/modbus.h"
#include "drivers/transport/transport.h"

enum failure_kind {
        FAIL_TIMEOUT, /* no answer: flush, retry */
        FAIL_FRAME,   /* corrupt or foreign frame: flush, retry */
        FAIL_EXCEPTION,
        FAIL_IO, /* the line or link broke: reconnect, retry */
        FAIL_ARG,
};

static int mb_timeout_ms(const struct transport *t)
{
        return t->conf->timeout_ms > 0 ? t->conf->timeout_ms : 200;
}

static modbus_t *new_context(const struct rig_bus_conf *c)
{
        if (c->type == RIG_BUS_MODBUS_TCP)
                return modbus_new_tcp(c->host[0] ? c->host : "127.0.0.1", c->tcp_port);
        return modbus_new_rtu(c->port, c->baud > 0 ? c->baud : 115200, c->parity ? c->parity : 'N',
                              c->data_bits > 0 ? c->data_bits : 8,
                              c->stop_bits > 0 ? c->stop_bits : 1);
}

/* Connects and, on a serial line, takes the port's lock. Returns 0 or -errno. */
static int mb_open(struct transport *t)
{
        const struct rig_bus_conf *c = t->conf;
        int ms = mb_timeout_ms(t), r;
        modbus_t *mb;

        mb = new_context(c);
        if (!mb)
                return transport_set_cause(t, -errno, "cannot set up Modbus for %s: %m",
                                           c->type == RIG_BUS_MODBUS_TCP ? c->host : c->port);
        if (modbus_set_response_timeout(mb, ms / 1000, (ms % 1000) * 1000) < 0 ||
            modbus_connect(mb) < 0) {
                r = -errno;
                modbus_free(mb);
                if (c->type == RIG_BUS_MODBUS_TCP)
                        return transport_set_cause(t, r, "cannot connect to %s:%d: %m", c->host,
                                                   c->tcp_port);
                return transport_port_error(t, r);
        }
        t->fd = modbus_get_socket(mb);
        t->priv = mb;
        r = c->type == RIG_BUS_MODBUS_RTU ? transport_lock_line(t, t->fd) : 0;
        if (r < 0) {
                modbus_close(mb);
                modbus_free(mb);
                t->priv = NULL;
        }
        return r;
}

static void mb_close(struct transport *t)
{
        modbus_t *mb = t->priv;

        if (t->conf->type == RIG_BUS_MODBUS_RTU)
                transport_unlock_line(t->fd);
        modbus_close(mb);
        modbus_free(mb);
        t->priv = NULL;
}

static void mb_flush(struct transport *t)
{
        modbus_flush(t->priv);
}

const struct transport_ops transport_modbus_rtu_ops = {
        .name = "modbus-rtu",
        .type = RIG_BUS_MODBUS_RTU,
        .open = mb_open,
        .close = mb_close,
        .flush = mb_flush,
};

const struct transport_ops transport_modbus_tcp_ops = {
        .name = "modbus-tcp",
        .type = RIG_BUS_MODBUS_TCP,
        .open = mb_open,
        .close = mb_close,
        .flush = mb_flush,
};

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

int mbus_errno(int err)
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

/* One attempt on an open link; -1 with errno set on failure, as libmodbus. */
static int do_request(modbus_t *mb, const struct mb_req *q)
{
        if (modbus_set_slave(mb, q->unit) < 0)
                return -1;
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

/* Gets the line back in step after a failed attempt. */
static void recover(struct transport *t, int err)
{
        switch (classify(err)) {
        case FAIL_TIMEOUT:
        case FAIL_FRAME:
                transport_flush(t);
                break;
        case FAIL_IO:
                transport_close(t);
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

/* The final failure: counted, its cause kept, logged at debug (the device logs it). */
static int failed(struct transport *t, const struct mb_req *q, int err)
{
        int r = mbus_errno(err);

        transport_count(&t->stats.failures);
        if (r == -ETIMEDOUT)
                transport_set_cause(t, r, "%s after %d ms", modbus_strerror(err), mb_timeout_ms(t));
        else
                transport_set_cause(t, r, "%s", modbus_strerror(err));
        return log_debug_errno(r, "bus '%s': unit %d: %s 0x%04x failed: %s", t->conf->name, q->unit,
                               mb_fn_names[q->fn], (unsigned)q->addr, t->cause);
}

static int transact(struct transport *t, const struct mb_req *q)
{
        int retries = MAX(t->conf->retries, 0), n, err, r;

        if (t->ops != &transport_modbus_rtu_ops && t->ops != &transport_modbus_tcp_ops)
                return -EOPNOTSUPP;
        transport_count(&t->stats.requests);
        for (int attempt = 1;; attempt++) {
                r = transport_open(t);
                if (r < 0) {
                        transport_count(&t->stats.failures);
                        return r; /* cause set, logged by transport_open() */
                }
                n = do_request(t->priv, q);
                if (n >= 0)
                        return n;
                err = errno;
                recover(t, err);
                if (!retryable(err) || attempt > retries)
                        return failed(t, q, err);
                transport_count(&t->stats.retries);
                if (transport_ratelimit_ok(t))
                        log_warning("bus '%s': unit %d: %s 0x%04x: %s, retry %d/%d", t->conf->name,
                                    q->unit, mb_fn_names[q->fn], (unsigned)q->addr,
                                    modbus_strerror(err), attempt, retries);
        }
}

int mbus_read_regs(struct transport *t, int unit, int addr, int n, uint16_t *dest)
{
        return transact(t, &(struct mb_req){MB_READ_REGS, unit, addr, n, .dest = dest});
}

int mbus_write_reg(struct transport *t, int unit, int addr, uint16_t value)
{
        return transact(t, &(struct mb_req){MB_WRITE_REG, unit, addr, 1, .value = value});
}

int mbus_write_regs(struct transport *t, int unit, int addr, int n, const uint16_t *src)
{
        return transact(t, &(struct mb_req){MB_WRITE_REGS, unit, addr, n, .src = src});
}

int mbus_read_coils(struct transport *t, int unit, int addr, int n, uint8_t *dest)
{
        return transact(t, &(struct mb_req){MB_READ_COILS, unit, addr, n, .bits = dest});
}

int mbus_write_coil(struct transport *t, int unit, int addr, bool on)
{
        return transact(t, &(struct mb_req){MB_WRITE_COIL, unit, addr, 1, .value = on});
}
