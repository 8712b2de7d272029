/* web.h - goniod's dashboard: a small web page with the rig's status, the session's progress
 * and a live picture of each camera, served over HTTP/1.1 (common/httpd.h) on goniod's loop,
 * under the rules of its TCP listener: the token of --token-file required, loopback only
 * without TLS, HTTPS only with it (goniod's credentials) (docs/goniod.md, "Dashboard").
 *
 * Routes, all GET (or HEAD), nothing else served (no files from client paths):
 *   /                    the page (built in: daemon/web/)
 *   /api/status          what the control protocol's status method answers (manager_status)
 *   /api/session         what session.status answers (session_status)
 *   /events              Server-Sent Events: "status" events of {status, session}, pushed
 *                        when the daemon notifies its clients of a change, at most every
 *                        WEB_PUSH_USEC, and every WEB_REFRESH_USEC anyway (the ETA moves)
 *   /preview/CAMERA.mjpg multipart/x-mixed-replace JPEG pictures of the camera
 *                        (daemon/preview.h); a viewer still sending the last picture gets
 *                        no new one (dropped), so it never holds anything back
 * Access: GET /?token=T answers 303 to / with a cookie (HttpOnly, SameSite=Strict) holding
 * the token's SHA-256; "Authorization: Bearer T" works without it. No credentials: 401; wrong
 * ones: 403. */
#pragma once

#include <stddef.h>
#include <stdint.h>

struct manager;
struct tls_creds;
struct web;

/* One file of the page, built into goniod (webassets.c, scripts/embed-assets). */
struct web_asset {
        const char *name;
        const unsigned char *data;
        size_t len;
};

/* The page's files; a NULL name ends the list. */
extern const struct web_asset web_assets[];

#define WEB_MAX_VIEWERS  16            /* picture streams at once; beyond, 503 */
#define WEB_MAX_EVENTS   16            /* event streams at once; beyond, 503 */
#define WEB_PUSH_USEC    250000        /* status pushed at most this often */
#define WEB_REFRESH_USEC 2000000       /* and at least this often */
#define WEB_MAX_PENDING  (512u * 1024) /* unsent bytes of one stream */
#define WEB_COOKIE       "gonio_session"

/* Serves the dashboard of m on addr ("HOST:PORT": server_tcp_socket) for clients that give
 * token (SRV_TOKEN_MIN to SRV_TOKEN_MAX characters), over HTTPS only with tls (server
 * credentials, borrowed: keep them while the web lives), else over HTTP on loopback only;
 * pictures at fps a second at most (0: PREVIEW_DEFAULT_FPS); timeout_usec bounds the time a
 * request (its TLS handshake included) may take to arrive and a stalled response (0:
 * HTTPD_IDLE_USEC). Returns 0, -EINVAL (address or token), -EPERM (not loopback without
 * TLS) or -errno, logged. */
int web_new(struct manager *m, const char *addr, const char *token, const struct tls_creds *tls,
            unsigned fps, uint64_t timeout_usec, struct web **ret);

/* Closes every connection and the listener, stops the pictures. NULL is a no-op; returns
 * NULL. */
struct web *web_free(struct web *w);

/* The daemon notified its clients of a change: the status is to be pushed. NULL is a no-op. */
void web_notify(struct web *w);
