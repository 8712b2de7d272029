/* conn.h - gonioctl's connection to goniod: connect, one request at a time, replies
 * matched by id, notifications handed to a callback, every wait bounded by a deadline.
 *
 * Deadlines are absolute CLOCK_MONOTONIC milliseconds (conn_now_ms() + timeout);
 * CONN_NO_DEADLINE waits without limit (only `watch` uses it). Single-threaded. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include <jansson.h>

#define CONN_NO_DEADLINE INT64_MAX

struct conn;

/* An error response as the server sent it. */
struct conn_error {
        int code;          /* JSON-RPC code (enum proto_code) */
        char message[512]; /* error.message, or what went wrong locally */
};

/* Called for each notification; params is borrowed (object, or NULL when absent). */
typedef void (*conn_notify_fn)(const char *method, json_t *params, void *userdata);

/* The monotonic clock in milliseconds. */
int64_t conn_now_ms(void);

/* Connects to the Unix stream socket at path before deadline. Returns 0 and a new
 * connection in *ret (conn_free it), -ENAMETOOLONG, -ETIMEDOUT, or the connect errno
 * (-ENOENT, -ECONNREFUSED, -EACCES, ...). */
int conn_open(const char *path, int64_t deadline, struct conn **ret);

/* Connects to goniod over TCP at addr ("HOST:PORT", HOST a name or an address, "[V6]:PORT")
 * before deadline: over TLS when tls or ca_file, the server's certificate checked against
 * ca_file's CAs (PEM; NULL: the system's trust store) and HOST. Returns 0 and *ret, or
 * -EINVAL (addr), -EHOSTUNREACH (HOST has no address), -ETIMEDOUT, the connect errno
 * (-ECONNREFUSED...), -errno of reading ca_file, -EKEYREJECTED (the server's certificate is
 * not trusted or does not name HOST), -EPROTO / -ECONNRESET (TLS failed: a server without
 * TLS); err->message says why for the file and TLS. */
int conn_open_tcp(const char *addr, bool tls, const char *ca_file, int64_t deadline,
                  struct conn **ret, struct conn_error *err);

/* Closes the socket and frees c. NULL is a no-op. Returns NULL. */
struct conn *conn_free(struct conn *c);

/* For _cleanup_(conn_freep). */
static inline void conn_freep(struct conn **c)
{
        conn_free(*c);
}

/* Sends method with params (stolen, may be NULL) and waits for its reply before deadline,
 * passing notifications that arrive meanwhile to fn (may be NULL). Returns 0 with a new
 * reference to the result in *result; -EREMOTEIO when the server answered with an error
 * (in *err); -ETIMEDOUT; -EINTR when intr_fd (ignored if negative) became readable;
 * -ECONNRESET when the server closed the connection; -EPROTO or -EMSGSIZE for a malformed
 * or over-long reply, or a reply that does not answer this request (proto_answers: another
 * id, or null outside the documented unreadable-request errors); -ENOMEM. Local failures
 * also fill err->message. After -ETIMEDOUT or -EINTR the request stays pending in goniod;
 * later calls skip its one reply. */
int conn_call(struct conn *c, const char *method, json_t *params, int64_t deadline, int intr_fd,
              conn_notify_fn fn, void *userdata, json_t **result, struct conn_error *err);

/* Waits for the next notification before deadline and passes it to fn. Returns 1 after a
 * notification; -EINTR when intr_fd (ignored if negative) became readable; -ETIMEDOUT;
 * -ECONNRESET; -EPROTO / -EMSGSIZE for malformed input or any reply, since no request is
 * outstanding (err->message says why). */
int conn_wait_notification(struct conn *c, int64_t deadline, int intr_fd, conn_notify_fn fn,
                           void *userdata, struct conn_error *err);
