/* bus.h - one worker thread per physical bus (a serial line, a TCP link, a
 * socket): it owns the bus connection and runs blocking device I/O, so the
 * daemon's event loop never blocks.
 *
 * Jobs go into a fixed-size queue; an urgent job (stop) jumps the queue. Each
 * job's result comes back on the event-loop thread through an eventfd. Drivers
 * and tests may also use a bus without an event loop (bus_new_sync) and call
 * the device ops directly on their own thread. */
#pragma once

#include <stdbool.h>

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
 * Returns 0, -EAGAIN when the queue is full, -ESHUTDOWN after bus_free began. */
int bus_submit(struct bus *b, bus_job_fn job, bus_done_fn done, void *userdata, bool urgent);

/* The bus configuration; valid for the bus's lifetime. */
const struct rig_bus_conf *bus_conf(const struct bus *b);

/* Opens the connection if needed and returns the libmodbus context of a Modbus bus,
 * with unit selected; worker thread (or sync owner) only. Returns 0 or -errno. */
int bus_modbus(struct bus *b, int unit, modbus_t **ret);

/* Closes the connection after an I/O error so that the next job reconnects. */
void bus_reset(struct bus *b);

/* Maps the errno left by a failed libmodbus call to -ETIMEDOUT, -EPROTO (exception,
 * bad CRC or frame) or -EIO, for logging with modbus_strerror(). */
int bus_modbus_errno(int err);
