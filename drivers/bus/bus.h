/* bus.h - one worker thread per physical bus (a serial line, a TCP link, a
 * socket): it owns the bus connection and runs blocking device I/O, so the
 * daemon's event loop never blocks.
 *
 * Jobs go into a fixed-size queue; an urgent job (stop) jumps the queue. Each
 * job's result comes back on the event-loop thread through an eventfd. Drivers
 * and tests may also use a bus without an event loop (bus_new_sync) and call
 * the device ops directly on their own thread. */
#pragma once

#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "common/rigconf.h"

typedef struct sd_event sd_event;
typedef struct _modbus modbus_t;

#define BUS_QUEUE_MAX 64

struct bus;

/* Runs on the bus worker; returns >= 0 or -errno. */
typedef int (*bus_job_fn)(struct bus *b, void *userdata);
/* Runs on the event-loop thread with the job's result. */
typedef void (*bus_done_fn)(struct bus *b, int result, void *userdata);

/* Creates a bus with a worker thread whose results are dispatched on event.
 * The connection is opened lazily by the first job. Returns 0 or -errno. */
int bus_new(sd_event *event, const struct rig_bus_conf *conf, struct bus **ret);

/* Creates a bus without a worker: the caller runs device ops on its own thread. */
int bus_new_sync(const struct rig_bus_conf *conf, struct bus **ret);

/* Stops the worker (after the running job), closes the connection. NULL is a no-op. */
struct bus *bus_free(struct bus *b);

/* Queues job; done (may be NULL) is called on the loop thread. urgent jobs go first.
 * Returns 0, -EAGAIN when the queue is full, -ESHUTDOWN after bus_free began.
 * Every queued job gets one done call: jobs dropped by bus_free() get -ECANCELED. With
 * event NULL done runs on the worker; on a sync bus job and done run inline. */
int bus_submit(struct bus *b, bus_job_fn job, bus_done_fn done, void *userdata, bool urgent);

/* The bus configuration; valid for the bus's lifetime. */
const struct rig_bus_conf *bus_conf(const struct bus *b);

/* Opens the connection if needed and returns the libmodbus context of a Modbus bus,
 * with unit selected; worker thread (or sync owner) only. Returns 0, -EOPNOTSUPP for a
 * sim bus, or -errno. */
int bus_modbus(struct bus *b, int unit, modbus_t **ret);

/* Closes the connection after an I/O error so that the next job reconnects. */
void bus_reset(struct bus *b);

/* Maps the errno left by a failed libmodbus call to -ETIMEDOUT, -EPROTO (exception,
 * bad CRC or frame) or -EIO, for logging with modbus_strerror(). */
int bus_modbus_errno(int err);

/* Counters of a bus's Modbus traffic; updated on the worker, readable from any thread. */
struct bus_stats {
        uint64_t requests;   /* transactions attempted (retries not included) */
        uint64_t retries;    /* extra attempts after a timeout, a bad frame or an I/O error */
        uint64_t failures;   /* transactions that failed after their last attempt */
        uint64_t reconnects; /* connections opened after the first */
};

/* Copies the counters of b into *ret. Any thread. */
void bus_get_stats(const struct bus *b, struct bus_stats *ret);

/* Modbus transactions with the bus's retry policy: up to conf->retries extra attempts
 * after a timeout or a corrupt reply (flushed first) or an I/O error (reconnected first),
 * each counted and logged (rate-limited); exceptions are not retried. Return >= 0, or
 * -ETIMEDOUT/-EPROTO/-EIO logged with modbus_strerror(). Worker (or sync owner) only. */
int bus_read_regs(struct bus *b, int unit, int addr, int n, uint16_t *dest);       /* FC03 */
int bus_write_reg(struct bus *b, int unit, int addr, uint16_t value);              /* FC06 */
int bus_write_regs(struct bus *b, int unit, int addr, int n, const uint16_t *src); /* FC16 */
int bus_read_coils(struct bus *b, int unit, int addr, int n, uint8_t *dest);       /* FC01 */
int bus_write_coil(struct bus *b, int unit, int addr, bool on);                    /* FC05 */

/* Logs "KIND 'NAME' [BACKEND@PORT#UNIT]: message" (PORT: last component of the bus's
 * port, or host:port for TCP; "#UNIT" left out when unit < 0) for the device class
 * wrappers. errno is err while formatting, for %m. Returns -abs(err). Any thread. */
int bus_log_dev(const struct bus *b, int level, int err, const char *kind, const char *name,
                const char *backend, int unit, const char *fmt, va_list ap);
