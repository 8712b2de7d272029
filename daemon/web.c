/* web.c - goniod's dashboard (see web.h).
 *
 * DESIGN: one httpd (common/httpd.h) on the loop, its handler answering fixed routes only.
 * Long-lived responses are httpd streams, each a struct viewer in one list: event streams
 * get the status snapshot (built once per push for all of them), picture streams the JPEG
 * parts preview.c hands over (built once per picture for all viewers of the camera). A
 * stream that still has unsent bytes is skipped: a slow client gets fewer pictures and
 * coarser status, never more memory than WEB_MAX_PENDING, and one that takes nothing for
 * the timeout is closed by httpd. Nothing here blocks; JPEG encoding runs on preview.c's
 * worker. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <systemd/sd-event.h>

#include "common/cleanup.h"
#include "common/httpd.h"
#include "common/log.h"
#include "common/sha256.h"
#include "manager.h"
#include "preview.h"
#include "tls.h"
#include "web.h"

#define BOUNDARY "gonioframe"
#define SECURITY_HEADERS                                                                           \
        "Content-Security-Policy: default-src 'self'; frame-ancestors 'none'\r\n"                  \
        "Referrer-Policy: no-referrer\r\n"

struct viewer {
        struct web *w;
        struct httpd_conn *c;
        int cam; /* a picture stream's camera; -1: an event stream */
        struct viewer *next;
};

struct web {
        struct manager *m;
        struct httpd *h;
        struct preview *pv;
        char token[SRV_TOKEN_MAX + 1];
        char cookie[GN_SHA256_HEX]; /* the token's SHA-256, what the cookie holds */
        struct viewer *viewers;
        unsigned n_pictures, n_events;
        sd_event_source *push;
        bool dirty;
        bool https; /* the cookie goes over TLS only */
        uint64_t last_push_usec;
};

/* Answers c with code and a one-line text body, with extra header lines. Returns 1 or
 * -errno. */
static int respond_text(struct httpd_conn *c, int code, const char *extra, const char *text)
{
        int r = httpd_respond(c, code, "text/plain; charset=utf-8", extra, text, strlen(text));

        return r < 0 ? r : 1;
}

/* Answers c with JSON j (taken). Returns 1 or -errno. */
static int respond_json(struct httpd_conn *c, json_t *j)
{
        _cleanup_free_ char *text = j ? json_dumps(j, JSON_COMPACT) : NULL;
        int r;

        json_decref(j);
        if (!text)
                return -ENOMEM;
        r = httpd_respond(c, 200, "application/json", SECURITY_HEADERS, text, strlen(text));
        return r < 0 ? r : 1;
}

/* The value of cookie name in c's Cookie header into buf; NULL when there is none. */
static const char *cookie_value(struct httpd_conn *c, const char *name, char *buf, size_t len)
{
        char header[1024];
        size_t nlen = strlen(name);

        if (!httpd_header(c, "Cookie", header, sizeof(header)))
                return NULL;
        for (const char *p = header; *p; p += strcspn(p, ";"), p += strspn(p, "; ")) {
                p += strspn(p, " ");
                if (strncmp(p, name, nlen) == 0 && p[nlen] == '=') {
                        snprintf(buf, len, "%.*s", (int)strcspn(p + nlen + 1, ";"), p + nlen + 1);
                        return buf;
                }
        }
        return NULL;
}

/* Refuses c with code and text. Returns 0 (answered) or -errno. */
static int deny(struct httpd_conn *c, int code, const char *extra, const char *text)
{
        int r = respond_text(c, code, extra, text);

        return r < 0 ? r : 0;
}

/* The sign-in: a right token in the query sets the cookie and sends the browser to the
 * dashboard (never to a path of the request: nothing of it is echoed). Returns 0 (answered)
 * or -errno. */
static int sign_in(struct web *w, struct httpd_conn *c, const char *token)
{
        char extra[HTTPD_EXTRA_MAX];

        if (!server_same_secret(token, w->token)) {
                log_notice("dashboard: refused a wrong token");
                return deny(c, 403, "", "403 wrong token\n");
        }
        snprintf(extra, sizeof(extra),
                 "Location: /\r\nSet-Cookie: " WEB_COOKIE "=%s; Path=/; HttpOnly; "
                 "SameSite=Strict%s\r\n",
                 w->cookie, w->https ? "; Secure" : "");
        return deny(c, 303, extra, "signed in\n");
}

/* Whether c may be served; when not, it has been answered (401, 403, or the sign-in's 303).
 * Returns 1 (authorized), 0 (answered) or -errno. */
static int authorize(struct web *w, struct httpd_conn *c, const char *query)
{
        char token[SRV_TOKEN_MAX + 2], auth[SRV_TOKEN_MAX + 16], cookie[GN_SHA256_HEX + 2];
        int r = httpd_query_param(query, "token", token, sizeof(token));

        if (r != 0)
                return r < 0 ? deny(c, 403, "", "403 wrong token\n") : sign_in(w, c, token);
        if (httpd_header(c, "Authorization", auth, sizeof(auth)))
                return strncmp(auth, "Bearer ", 7) == 0 && server_same_secret(auth + 7, w->token)
                               ? 1
                               : deny(c, 403, "", "403 wrong token\n");
        if (cookie_value(c, WEB_COOKIE, cookie, sizeof(cookie)))
                return server_same_secret(cookie, w->cookie)
                               ? 1
                               : deny(c, 403, "", "403 stale sign-in: open /?token=TOKEN again\n");
        return deny(c, 401, "WWW-Authenticate: Bearer realm=\"goniod\"\r\n",
                    "401 goniod's dashboard: open /?token=TOKEN, TOKEN the first line of "
                    "goniod's --token-file\n");
}

static void viewer_closed(struct httpd_conn *c, void *ud)
{
        struct viewer *v = ud;
        struct web *w = v->w;

        for (struct viewer **p = &w->viewers; *p; p = &(*p)->next)
                if (*p == v) {
                        *p = v->next;
                        break;
                }
        if (v->cam >= 0) {
                w->n_pictures--;
                preview_watch(w->pv, v->cam, false);
        } else if (--w->n_events == 0)
                (void)sd_event_source_set_enabled(w->push, SD_EVENT_OFF);
        free(v);
}

/* Turns c into a stream of type for camera cam (-1: events); HEAD gets the headers alone.
 * Returns 1 or -errno. */
static int open_stream(struct web *w, struct httpd_conn *c, const char *method, int cam,
                       const char *type)
{
        struct viewer *v;
        int r;

        if (strcmp(method, "HEAD") == 0)
                return httpd_respond(c, 200, type, SECURITY_HEADERS, NULL, 0) ?: 1;
        if (!(v = calloc(1, sizeof(*v))))
                return -ENOMEM;
        *v = (struct viewer){.w = w, .c = c, .cam = cam};
        r = httpd_stream(c, type, SECURITY_HEADERS, WEB_MAX_PENDING, viewer_closed, v);
        if (r < 0) {
                free(v);
                return r;
        }
        v->next = w->viewers;
        w->viewers = v;
        if (cam >= 0) {
                w->n_pictures++;
                preview_watch(w->pv, cam, true);
        } else if (w->n_events++ == 0)
                (void)sd_event_source_set_enabled(w->push, SD_EVENT_ON);
        return 1;
}

/* The snapshot an event stream gets: "event: status" with {status, session}; malloc'ed. */
static char *status_event(struct web *w, size_t *len)
{
        json_t *j = json_pack("{soso}", "status", manager_status(w->m), "session",
                              session_status(w->m->session));
        _cleanup_free_ char *text = j ? json_dumps(j, JSON_COMPACT) : NULL;
        char *out = NULL;
        int n;

        json_decref(j);
        n = text ? asprintf(&out, "event: status\ndata: %s\n\n", text) : -1;
        if (n < 0)
                return NULL;
        *len = n;
        return out;
}

/* Sends data to the streams of camera cam (-1: the event streams) that have sent all they
 * had; the others skip it. */
static void send_all(struct web *w, int cam, const char *data, size_t len)
{
        for (struct viewer *v = w->viewers, *next; v; v = next) {
                next = v->next; /* a failed send closes v */
                if (v->cam == cam && httpd_stream_pending(v->c) == 0)
                        (void)httpd_stream_send(v->c, data, len);
        }
}

static int on_push(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct web *w = userdata;
        _cleanup_free_ char *ev = NULL;
        size_t len = 0;

        (void)sd_event_source_set_time_relative(es, WEB_PUSH_USEC);
        if (!w->dirty && usec - w->last_push_usec < WEB_REFRESH_USEC)
                return 0;
        w->dirty = false;
        w->last_push_usec = usec;
        if ((ev = status_event(w, &len)))
                send_all(w, -1, ev, len);
        return 0;
}

void web_notify(struct web *w)
{
        if (w)
                w->dirty = true;
}

/* A camera's new picture: one multipart part for all its viewers. */
static void on_picture(void *ud, int cam, const uint8_t *jpeg, size_t len, int width, int height)
{
        struct web *w = ud;
        char head[160];
        int n = snprintf(head, sizeof(head),
                         "--" BOUNDARY "\r\nContent-Type: image/jpeg\r\nContent-Length: %zu\r\n"
                         "X-Width: %d\r\nX-Height: %d\r\n\r\n",
                         len, width, height);
        _cleanup_free_ char *part = malloc(n + len + 2);

        if (!part)
                return;
        memcpy(part, head, n);
        memcpy(part + n, jpeg, len);
        memcpy(part + n + len, "\r\n", 2);
        send_all(w, cam, part, n + len + 2);
}

/* /events: an event stream, its first snapshot at once. Returns 1 or -errno. */
static int open_events(struct web *w, struct httpd_conn *c, const char *method)
{
        _cleanup_free_ char *ev = NULL;
        size_t len = 0;
        int r;

        if (w->n_events >= WEB_MAX_EVENTS)
                return respond_text(c, 503, "Retry-After: 5\r\n", "503 too many event streams\n");
        r = open_stream(w, c, method, -1, "text/event-stream");
        if (r > 0 && strcmp(method, "GET") == 0 && (ev = status_event(w, &len)))
                (void)httpd_stream_send(c, ev, len);
        return r;
}

/* /preview/NAME.mjpg: camera NAME's pictures. Returns 1 or -errno. */
static int open_preview(struct web *w, struct httpd_conn *c, const char *method, const char *file)
{
        char name[RIG_NAME_MAX];
        size_t n = strlen(file);
        int cam;

        if (n <= 5 || n - 5 >= sizeof(name) || strcmp(file + n - 5, ".mjpg") != 0)
                return respond_text(c, 404, "", "404 not found\n");
        snprintf(name, sizeof(name), "%.*s", (int)(n - 5), file);
        cam = rig_camera_index(w->m->rig, name);
        if (cam < 0)
                return respond_text(c, 404, "", "404 no such camera\n");
        if (w->n_pictures >= WEB_MAX_VIEWERS)
                return respond_text(c, 503, "Retry-After: 5\r\n", "503 too many viewers\n");
        return open_stream(w, c, method, cam, "multipart/x-mixed-replace; boundary=" BOUNDARY);
}

/* A file of the page by its route ("/" is index.html). Returns 1, 0 (none) or -errno. */
static int send_asset(struct httpd_conn *c, const char *path)
{
        static const struct {
                const char *ext, *type;
        } types[] = {{".html", "text/html; charset=utf-8"},
                     {".js", "text/javascript"},
                     {".css", "text/css"},
                     {".svg", "image/svg+xml"}};
        const char *name = strcmp(path, "/") == 0 ? "index.html" : path + 1;

        for (const struct web_asset *a = web_assets; a->name; a++) {
                const char *dot = strrchr(a->name, '.'), *type = "application/octet-stream";
                int r;
                if (strcmp(a->name, name) != 0)
                        continue;
                for (size_t i = 0; dot && i < ELEMENTSOF(types); i++)
                        if (strcmp(dot, types[i].ext) == 0)
                                type = types[i].type;
                r = httpd_respond(c, 200, type, SECURITY_HEADERS, a->data, a->len);
                return r < 0 ? r : 1;
        }
        return 0;
}

static int handle(struct httpd_conn *c, const char *method, const char *path, const char *query,
                  void *ud)
{
        struct web *w = ud;
        int r = authorize(w, c, query);

        if (r <= 0)
                return r < 0 ? r : 1;
        if (strcmp(path, "/api/status") == 0)
                return respond_json(c, manager_status(w->m));
        if (strcmp(path, "/api/session") == 0)
                return respond_json(c, session_status(w->m->session));
        if (strcmp(path, "/events") == 0)
                return open_events(w, c, method);
        if (strncmp(path, "/preview/", 9) == 0)
                return open_preview(w, c, method, path + 9);
        r = send_asset(c, path);
        return r != 0 ? r : respond_text(c, 404, "", "404 not found\n");
}

/* The token's SHA-256 in hex into out. Returns 0 or -errno. */
static int token_hash(const char *token, char out[GN_SHA256_HEX])
{
        struct gn_sha256 *s = NULL;
        int r = gn_sha256_new(&s);

        if (r >= 0)
                r = gn_sha256_update(s, "gonio-dashboard:", 16);
        if (r >= 0)
                r = gn_sha256_update(s, token, strlen(token));
        if (r >= 0)
                r = gn_sha256_final(s, out);
        gn_sha256_free(s);
        return r;
}

/* The TLS of daemon/tls.h for httpd's HTTPS. */
static const struct httpd_tls web_tls = {
        .conn_new = tls_conn_new,
        .conn_free = tls_conn_free,
        .handshake = tls_handshake,
        .wants_write = tls_wants_write,
        .read = tls_read,
        .write = tls_write,
        .pending = tls_pending,
};

int web_new(struct manager *m, const char *addr, const char *token, const struct tls_creds *tls,
            unsigned fps, uint64_t timeout_usec, struct web **ret)
{
        struct web *w;
        int fd, r;

        if ((r = server_check_token(token, "HTTP listener", addr)) < 0)
                return r;
        if (!(w = calloc(1, sizeof(*w))))
                return -ENOMEM;
        w->m = m;
        snprintf(w->token, sizeof(w->token), "%s", token);
        r = token_hash(token, w->cookie);
        if (r >= 0)
                r = preview_new(m, fps ? fps : PREVIEW_DEFAULT_FPS, on_picture, w, &w->pv);
        if (r >= 0)
                r = sd_event_add_time_relative(m->event, &w->push, CLOCK_MONOTONIC, WEB_PUSH_USEC,
                                               10000, on_push, w);
        if (r >= 0)
                r = sd_event_source_set_enabled(w->push, SD_EVENT_OFF);
        if (r >= 0 && (r = fd = server_tcp_socket(addr, "HTTP listener",
                                                  tls ? NULL
                                                      : "the dashboard needs TLS (--tls-cert FILE "
                                                        "--tls-key FILE)")) >= 0)
                r = httpd_new_fd(m->event, -1, fd, &w->h);
        if (r < 0) {
                web_free(w);
                return r;
        }
        httpd_set_handler(w->h, handle, w);
        if (tls)
                httpd_set_tls(w->h, &web_tls, tls);
        w->https = tls;
        if (timeout_usec)
                httpd_set_idle(w->h, timeout_usec);
        (void)sd_event_source_set_description(w->push, "web-push");
        log_info("dashboard on %s://%s/", tls ? "https" : "http", addr);
        *ret = w;
        return 0;
}

struct web *web_free(struct web *w)
{
        if (!w)
                return NULL;
        w->h = httpd_free(w->h); /* closes the streams: viewer_closed unwatches */
        w->pv = preview_free(w->pv);
        sd_event_source_disable_unref(w->push);
        free(w);
        return NULL;
}
