/* httpd.h - a small HTTP/1.1 server on an sd-event loop: GET and HEAD of the
 * files under one directory, for `gonioctl model view` (the relighting viewer), and of what a
 * handler answers from memory or feeds as a long-lived stream (Server-Sent Events, MJPEG),
 * for goniod's dashboard (daemon/web.c). Loopback unless the caller binds elsewhere; paths are
 * confined to the root whatever the client sends (no "..", no symlink out, no device files); every
 * client is bounded (request size, idle time, open connections) so a rude or leaking client cannot
 * stop the others being served. docs/viewer.md. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>
#include <systemd/sd-event.h>

/* Connections at once. Beyond, a new connection closes one whose response is out, else the
 * oldest one still sending its request; when all are being sent files it is closed itself. */
#define HTTPD_MAX_CLIENTS 64
#define HTTPD_MAX_REQUEST 8192 /* bytes of request line and headers */
/* The idle limit: a request must arrive whole within it of the accept (else 408), a file
 * transfer that makes no progress for it is closed. */
#define HTTPD_IDLE_USEC 10000000
/* Bytes of extra header lines a handler's response may carry. */
#define HTTPD_EXTRA_MAX 768

struct httpd;
struct tls_creds;
struct tls_conn;
/* A connection whose request a handler (httpd_set_handler) answers. */
struct httpd_conn;

/* Answers a request with httpd_respond or httpd_stream, or passes it on: path is the
 * percent-decoded absolute path ("/x/y"), query what followed '?' ("" when nothing); method
 * is "GET" or "HEAD" (others get 405 before any handler). Returns 1 when it answered, 0 to
 * have the file under the root served (404 when there is no root), or -errno (500). Runs on
 * the loop. */
typedef int (*httpd_handler_fn)(struct httpd_conn *c, const char *method, const char *path,
                                const char *query, void *ud);

/* Starts serving the directory root_fd (borrowed; keep it open while h lives) on addr
 * ("127.0.0.1", "::1", "0.0.0.0", ...) and port (0: a free port, see httpd_port) on event.
 * Returns 0, -EINVAL (bad address), -EADDRINUSE, -EACCES or another -errno. */
int httpd_new(sd_event *event, int root_fd, const char *addr, uint16_t port, struct httpd **ret);

/* Like httpd_new on listen_fd, a listening stream socket (taken, made non-blocking, closed by
 * httpd_free; on failure too). root_fd < 0: no files, only what the handler answers. Returns
 * 0 or -errno. */
int httpd_new_fd(sd_event *event, int root_fd, int listen_fd, struct httpd **ret);

/* TLS for httpd: the functions of daemon/tls.h (tls_conn_new, tls_conn_free, ...), handed in
 * by the caller so that httpd does not depend on the TLS library. */
struct httpd_tls {
        int (*conn_new)(const struct tls_creds *creds, int fd, const char *peer,
                        struct tls_conn **ret);
        struct tls_conn *(*conn_free)(struct tls_conn *t);
        int (*handshake)(struct tls_conn *t);
        bool (*wants_write)(const struct tls_conn *t);
        ssize_t (*read)(struct tls_conn *t, void *buf, size_t len);
        ssize_t (*write)(struct tls_conn *t, const void *buf, size_t len);
        size_t (*pending)(const struct tls_conn *t);
};

/* Has h serve HTTPS only to the connections it accepts from now on, as a TLS server with
 * creds through fns (both borrowed: keep them while h lives). The handshake counts in the
 * time a request may take to arrive (a stalled one is closed then); a client that does not
 * start with a TLS handshake gets a plain-text 400 and is closed. */
void httpd_set_tls(struct httpd *h, const struct httpd_tls *fns, const struct tls_creds *creds);

/* Has fn(c, method, path, query, ud) answer every request first. */
void httpd_set_handler(struct httpd *h, httpd_handler_fn fn, void *ud);

/* The value of c's request header name (case-insensitive; the first one) into buf (len
 * bytes, cut to fit); NULL when there is none. */
const char *httpd_header(const struct httpd_conn *c, const char *name, char *buf, size_t len);

/* The percent-decoded value of parameter name in query (a handler's) into buf (len bytes).
 * Returns 1, 0 when absent, or -EINVAL (a bad escape, or longer than buf). */
int httpd_query_param(const char *query, const char *name, char *buf, size_t len);

/* Answers c with code, type and body (len bytes, copied; not sent for HEAD); extra is more
 * header lines, each ending in "\r\n" ("" none; at most HTTPD_EXTRA_MAX bytes). Returns 0
 * or -errno (c is then closed by the caller's return). */
int httpd_respond(struct httpd_conn *c, int code, const char *type, const char *extra,
                  const void *body, size_t len);

/* Answers c 200 with type and no length: a stream the handler feeds with httpd_stream_send
 * until either side closes it; on_close(c, ud) is called once when it is closed, whoever
 * closes it (also by httpd_free), after which c is gone. Unsent data is bounded by
 * max_pending bytes; a stream that has unsent data and takes none of it for the idle
 * limit is closed. For HEAD it answers the headers alone and on_close is never called: answer
 * HEAD with httpd_respond instead. Returns 0 or -errno (on_close is then not called). */
int httpd_stream(struct httpd_conn *c, const char *type, const char *extra, size_t max_pending,
                 void (*on_close)(struct httpd_conn *c, void *ud), void *ud);

/* Queues len bytes on stream c and sends what the socket takes. Returns 0, -ENOBUFS when
 * they would pass its max_pending (nothing queued: the caller drops them, e.g. a frame for
 * a slow viewer), or -errno when c failed (it is then closed: on_close runs before this
 * returns). */
int httpd_stream_send(struct httpd_conn *c, const void *data, size_t len);

/* Bytes queued on stream c and not yet taken by the socket. */
size_t httpd_stream_pending(const struct httpd_conn *c);

/* The port h listens on. */
uint16_t httpd_port(const struct httpd *h);

/* Sets the idle limit of h's connections (0: HTTPD_IDLE_USEC), from each connection's next
 * timer start: the time a request may take to arrive whole, the longest stall while a file
 * is sent. For tests and callers that want a shorter bound. */
void httpd_set_idle(struct httpd *h, uint64_t usec);

/* Closes the listener and every connection and frees h; NULL is a no-op. Returns NULL. */
struct httpd *httpd_free(struct httpd *h);
