/* httpd.h - a small static-file HTTP/1.1 server on an sd-event loop: GET and HEAD of the
 * files under one directory, for `gonioctl model view` (the relighting viewer) and goniod's
 * dashboard. Loopback unless the caller binds elsewhere; paths are confined to the root
 * whatever the client sends (no "..", no symlink out, no device files); every client is
 * bounded (request size, idle time, open connections) so a rude or leaking client cannot
 * stop the others being served. docs/viewer.md. */
#pragma once

#include <stdint.h>
#include <systemd/sd-event.h>

/* Connections at once. Beyond, a new connection closes one whose response is out, else the
 * oldest one still sending its request; when all are being sent files it is closed itself. */
#define HTTPD_MAX_CLIENTS 64
#define HTTPD_MAX_REQUEST 8192 /* bytes of request line and headers */
/* The idle limit: a request must arrive whole within it of the accept (else 408), a file
 * transfer that makes no progress for it is closed. */
#define HTTPD_IDLE_USEC 10000000

struct httpd;

/* Starts serving the directory root_fd (borrowed; keep it open while h lives) on addr
 * ("127.0.0.1", "::1", "0.0.0.0", ...) and port (0: a free port, see httpd_port) on event.
 * Returns 0, -EINVAL (bad address), -EADDRINUSE, -EACCES or another -errno. */
int httpd_new(sd_event *event, int root_fd, const char *addr, uint16_t port, struct httpd **ret);

/* The port h listens on. */
uint16_t httpd_port(const struct httpd *h);

/* Sets the idle limit of h's connections (0: HTTPD_IDLE_USEC), from each connection's next
 * timer start: the time a request may take to arrive whole, the longest stall while a file
 * is sent. For tests and callers that want a shorter bound. */
void httpd_set_idle(struct httpd *h, uint64_t usec);

/* Closes the listener and every connection and frees h; NULL is a no-op. Returns NULL. */
struct httpd *httpd_free(struct httpd *h);
