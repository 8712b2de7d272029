/* transport.h - how a bus reaches its devices: an ops table per kind of link (Modbus
 * RTU and TCP through libmodbus, gonio-sim's frame socket, a plain serial line), so that
 * the bus worker knows nothing of any protocol.
 *
 * A transport is owned by one thread at a time (its bus worker, or the owner of a sync
 * bus). Opening is lazy and idempotent: helpers call transport_open() before each use,
 * and a transport closed after an I/O error reopens on the next use. Serial lines
 * (modbus-rtu, serial) are locked exclusively after open: a second process, or a second
 * bus of the same process, gets -EBUSY naming the port. Every failure leaves a one-line
 * cause (transport_cause()) that device classes put into their own messages.
 *
 * Stream transports (serial, sim) read and write through a bounded input buffer with a
 * deadline on every call (CLOCK_MONOTONIC, milliseconds; a deadline in the past still
 * tries once without waiting, it never means "forever"). */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "common/rigconf.h"

/* Received bytes a stream transport holds; also the longest line it returns. */
#define TRANSPORT_BUF_MAX 4096

struct transport;

struct transport_ops {
        const char *name;                 /* bus type as written in the rig file */
        enum rig_bus_type type;           /* the rig_bus_conf type served */
        bool stream;                      /* byte stream on t->fd: the read/write helpers apply */
        bool socket;                      /* t->fd is a socket: written with MSG_NOSIGNAL */
        int (*open)(struct transport *t); /* 0 or -errno, cause set */
        void (*close)(struct transport *t);
        void (*flush)(struct transport *t); /* drop input not read yet (optional) */
};

/* Traffic counters; updated by the owning thread, readable from any thread. */
struct transport_stats {
        uint64_t requests;   /* transactions attempted (retries not included) */
        uint64_t retries;    /* extra attempts after a timeout, a bad frame or an I/O error */
        uint64_t failures;   /* transactions that failed after their last attempt */
        uint64_t reconnects; /* connections opened after the first */
};

struct transport {
        const struct transport_ops *ops;
        const struct rig_bus_conf *conf; /* borrowed: the bus's copy */
        int fd;                          /* stream or locked line fd, -1 when closed */
        void *priv; /* backend state (the modbus_t of Modbus links, a G-code session) */
        void (*priv_free)(void *priv); /* frees priv in transport_free(); NULL: not owned */
        bool is_open, opened_once;
        bool open_failed; /* the last use failed to open the link: the cause names the port */
        struct transport_stats stats;
        char cause[256]; /* last failure, without the bus name */
        char in[TRANSPORT_BUF_MAX];
        size_t in_len; /* stream bytes received, not consumed */
        uint64_t rl_begin_ns;
        unsigned rl_n, rl_suppressed; /* rate limit of retry messages */
};

/* Creates the transport for conf->type (conf borrowed for the transport's lifetime).
 * Returns 0, -EOPNOTSUPP for a type without transport, -ENOMEM. Does no I/O. */
int transport_new(const struct rig_bus_conf *conf, struct transport **ret);

/* Closes and frees; NULL is a no-op. Returns NULL. */
struct transport *transport_free(struct transport *t);

/* Opens the link unless open. Returns 0 or -errno: -ENOENT (no such port), -EACCES,
 * -EBUSY (port locked by another process or bus), -ECONNREFUSED, ...; logged at error
 * level with the port's path, and not to be retried. Owning thread. */
int transport_open(struct transport *t);

/* Closes the link (releasing its lock) so that the next use reopens it. */
void transport_close(struct transport *t);

/* Drops pending input: buffered bytes and, for serial lines, the kernel's queue. */
void transport_flush(struct transport *t);

/* The last failure's cause ("Connection timed out after 200 ms"), "" when none. Valid
 * until the next call on t. */
const char *transport_cause(const struct transport *t);

/* Sets the cause (printf format); returns -abs(err). errno is err while formatting. */
int transport_set_cause(struct transport *t, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* Copies the counters into *ret. Any thread. */
void transport_get_stats(const struct transport *t, struct transport_stats *ret);

/* Adds one to a counter of t->stats (atomically). */
void transport_count(uint64_t *counter);

/* True when one more retry message may be logged (at most 10 per 5 s and transport);
 * logs how many were suppressed when a new interval begins. */
bool transport_ratelimit_ok(struct transport *t);

/* CLOCK_MONOTONIC now plus timeout_ms, in ms: a deadline for the calls below. */
int64_t transport_deadline(int timeout_ms);

/* Writes all n bytes before deadline. Returns 0, -ETIMEDOUT (some bytes may be
 * written), -EOPNOTSUPP on a non-stream transport or -errno (the link is closed). */
int transport_write_all(struct transport *t, const void *p, size_t n, int64_t deadline);

/* Reads up to delim and copies the line without it (NUL-terminated) into buf. Returns its
 * length; -ETIMEDOUT at the deadline (a partial line stays buffered for the next call);
 * -EMSGSIZE when no delim comes within len - 1 bytes (the bytes read are dropped, up to
 * and including the next delim if buffered); -ECONNRESET at end of stream; -errno. */
ssize_t transport_read_until(struct transport *t, char delim, char *buf, size_t len,
                             int64_t deadline);

/* transport_read_until(t, '\n', ...) with a trailing '\r' removed. */
ssize_t transport_read_line(struct transport *t, char *buf, size_t len, int64_t deadline);

/* Reads exactly n bytes into dst (NULL: discards them), buffered bytes first. Returns 0,
 * -ETIMEDOUT, -ECONNRESET or -errno. */
int transport_read_bytes(struct transport *t, void *dst, size_t n, int64_t deadline);

/* Takes the exclusive lock of an open serial line fd (flock LOCK_EX|LOCK_NB, and TIOCEXCL
 * where the device supports it, ptys excepted: see transport.c). Returns 0 or -EBUSY with
 * the cause "port PATH is in use by another process". */
int transport_lock_line(struct transport *t, int fd);

/* Sets the cause of a failed open(2) of the port: "port PATH is in use by another
 * process" for EBUSY (TIOCEXCL held by another process), else "cannot open port PATH: %m".
 * Returns -abs(err). */
int transport_port_error(struct transport *t, int err);

/* Releases what transport_lock_line() took (TIOCNXCL; the flock goes with the fd). */
void transport_unlock_line(int fd);

/* The transports, by bus type (transport_new() picks them). */
extern const struct transport_ops transport_modbus_rtu_ops, transport_modbus_tcp_ops,
        transport_sim_ops, transport_serial_ops, transport_local_ops;
