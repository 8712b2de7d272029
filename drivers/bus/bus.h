/* bus.h - one worker thread per physical bus (a serial line, a TCP link, a
 * socket): it owns the bus's transport and runs blocking device I/O, so the
 * daemon's event loop never blocks. The bus knows nothing of protocols: Modbus,
 * the gonio-sim frame socket and plain serial lines are transports.
 *
 * Jobs go into a fixed-size queue; an urgent job (stop) jumps the queue. Each
 * job's result comes back on the event-loop thread through an eventfd. Drivers
 * and tests may also use a bus without an event loop (bus_new_sync) and call
 * the device ops directly on their own thread. */
#pragma once

#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>

#include "common/rigconf.h"

typedef struct sd_event sd_event;

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

/* The bus's transport (drivers/transport/transport.h), opened lazily by its helpers;
 * valid for the bus's lifetime, used on the worker (or by the sync owner) only. */
struct transport *bus_transport(const struct bus *b);

/* Size of a device's last_error and cause buffers (struct axis, sw, cam). */
#define DEV_ERROR_MAX 256

/* Where a device message comes from and where it is kept, for bus_log_dev(). */
struct bus_dev_ref {
        const char *kind, *name, *backend; /* "axis", "turntable", "modbus" */
        const struct rig_addr *addr;       /* the device's address, "#1"; NULL or no key: none */
        char *last_error;                  /* NULL or a buffer of last_error_len bytes */
        size_t last_error_len;
};

/* Logs "KIND 'NAME' [BACKEND@PORT#ADDR]: message" (PORT: last component of the bus's
 * port, host:port for TCP, the bus's name for a local bus; ADDR: the address's value, "#ADDR" left
 * out without one) for the device class wrappers; a message at warning level or worse is also
 * copied, whole, into dev->last_error. errno is err while formatting, for %m. Returns -abs(err).
 * Thread of the device's ops. */
int bus_log_dev(const struct bus *b, const struct bus_dev_ref *dev, int level, int err,
                const char *fmt, va_list ap);

/* Formats a backend's cause of failure into buf (len bytes) without logging; %m prints
 * err. Returns -abs(err). For axis_set_cause() and its siblings. */
int bus_dev_cause(char *buf, size_t len, int err, const char *fmt, va_list ap);
