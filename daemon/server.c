/* server.c - JSON-RPC 2.0 control server on a Unix stream socket, on sd-event.
 *
 * DESIGN: every client has a line reader (proto_lines, bounded) and an output
 * buffer. Output is written as far as the socket takes it; the rest waits for
 * EPOLLOUT. A client whose unsent output passes SRV_MAX_OUTPUT is disconnected,
 * so a stalled client cannot grow the daemon's memory. Requests hold a
 * reference on their client, so a deferred answer to a client that has gone is
 * dropped safely. Nothing here blocks.
 *
 * One daemon per socket: "<path>.lock" is flock'ed for the server's lifetime and
 * a connect() probe refuses a path something still serves; only a stale socket
 * is removed, and on exit the path is unlinked only if it is still our socket.
 * Sockets passed by systemd (socket activation) are used as they are: no lock, no
 * unlink, systemd owns them.
 *
 * Listeners have a role: a connection accepted on an admin listener may call every
 * method, one accepted on an operator listener every method but the admin ones
 * (struct srv_method.admin), which it is refused with -EPERM naming the admin socket.
 *
 * Connections: accepted in a loop (SOMAXCONN backlog) up to max_clients. When
 * the table is full a new connection evicts the oldest client that never said
 * hello, else the hello'd client idle longest past idle_usec with no request
 * pending; each evicted client is told why. When nobody can be evicted the new
 * connection gets one error line and is closed, so an operator is never locked
 * out by connections that do nothing. A spare descriptor lets the server
 * refuse a connection even when the process is out of descriptors. */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <systemd/sd-daemon.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "common/log.h"
#include "protocol/proto.h"
#include "server.h"
#include "tls.h"

#define SRV_MAX_OUTPUT   (16u * PROTO_MAX_LINE) /* 1 MiB: a client's unsent output */
#define SRV_FD_RESERVE   64    /* descriptors left for devices, datasets and the loop */
#define SRV_ACCEPT_BATCH 1024  /* per wake-up, so a connection flood cannot starve clients */
#define MAX_BAD_TOKENS   3     /* wrong tokens before a TCP connection is closed */
#define MAX_PLAIN_DRAIN  65536 /* bytes read of a client without TLS on a TLS listener */

struct client {
        struct server *server;
        unsigned ref;
        int fd;
        struct tls_conn *tls; /* NULL: a plain connection */
        sd_event_source *io;
        struct proto_lines in;
        char *out;
        size_t out_len, out_cap;
        bool hello;         /* answered a successful hello */
        enum srv_role role; /* of the listener it came on */
        const char *token;  /* the listener's: hello must give it first, NULL: none */
        int bad_tokens;
        uint64_t number;      /* srv_req_client */
        uint64_t last_active; /* CLOCK_MONOTONIC usec of its last request, or of accept */
        struct client *next;  /* the list is newest first */
};

/* A listening socket and the role of the connections it accepts. */
struct listener {
        struct server *server;
        int fd, lock_fd; /* lock_fd: "<path>.lock", for the sockets we bound */
        enum srv_role role;
        char path[sizeof(((struct sockaddr_un *)0)->sun_path)];
        char token[128];             /* TCP: what hello must give, "" none */
        const struct tls_creds *tls; /* TCP with TLS: goniod's credentials, else NULL */
        bool bound;                  /* path is the socket we bound, identified by dev/ino */
        dev_t dev;
        ino_t ino;
        sd_event_source *src;
};

struct server {
        sd_event *event;
        int spare_fd;
        struct listener listeners[SRV_MAX_LISTENERS];
        unsigned n_listeners;
        bool started;
        const struct srv_method *methods;
        void *userdata;
        struct client *clients;
        unsigned n_clients, max_clients, budget; /* budget: what RLIMIT_NOFILE allows */
        uint64_t idle_usec;
        uint64_t log_quiet_until; /* log_drop */
        unsigned log_skipped;
        uint64_t last_number;
        void (*on_close)(uint64_t client, void *ud);
        void *on_close_ud;
};

struct srv_req {
        struct client *client;
        json_t *id;
        const char *method;
        char errmsg[512];
};

static int safe_close(int fd)
{
        if (fd >= 0)
                close(fd);
        return -EBADF;
}

static uint64_t loop_now(struct server *s)
{
        uint64_t t = 0;

        (void)sd_event_now(s->event, CLOCK_MONOTONIC, &t);
        return t;
}

static struct client *client_unref(struct client *c)
{
        if (c && --c->ref == 0) {
                proto_lines_done(&c->in);
                free(c->out);
                free(c);
        }
        return NULL;
}

static void client_close(struct client *c)
{
        struct server *s = c->server;

        if (c->fd < 0)
                return;
        c->io = sd_event_source_disable_unref(c->io);
        c->tls = tls_conn_free(c->tls);
        close(c->fd);
        c->fd = -EBADF;
        for (struct client **p = &s->clients; *p; p = &(*p)->next)
                if (*p == c) {
                        *p = c->next;
                        break;
                }
        s->n_clients--;
        log_debug("client %p disconnected", (void *)c);
        if (s->on_close)
                s->on_close(c->number, s->on_close_ud);
        client_unref(c);
}

/* Writes what c's transport takes of buf. Returns the bytes taken, -EAGAIN or -errno. */
static ssize_t client_write(struct client *c, const char *buf, size_t len)
{
        ssize_t n;

        if (c->tls)
                return tls_write(c->tls, buf, len);
        n = send(c->fd, buf, len, MSG_NOSIGNAL | MSG_DONTWAIT);
        return n < 0 ? -errno : n;
}

static int client_flush(struct client *c)
{
        if (c->tls && !tls_ready(c->tls))
                return 0; /* output waits for the end of the handshake */
        while (c->out_len > 0) {
                ssize_t n = client_write(c, c->out, c->out_len);

                if (n == -EINTR)
                        continue;
                if (n == -EAGAIN)
                        break;
                if (n < 0)
                        return (int)n;
                memmove(c->out, c->out + n, c->out_len - n);
                c->out_len -= n;
        }
        return sd_event_source_set_io_events(c->io, EPOLLIN | (c->out_len ? EPOLLOUT : 0));
}

/* Queues len bytes of text (whole lines) to c; disconnects c if it cannot keep up. */
static void client_send_text(struct client *c, const char *text, size_t len)
{
        if (c->fd < 0)
                return;
        if (c->out_len + len > SRV_MAX_OUTPUT) {
                log_warning("client %p does not read what it is sent (%zu bytes unread), "
                            "disconnecting it",
                            (void *)c, c->out_len);
                client_close(c);
                return;
        }
        if (c->out_len + len > c->out_cap) {
                size_t cap = MAX(c->out_cap * 2, c->out_len + len);
                char *p = realloc(c->out, cap);
                if (!p) {
                        client_close(c);
                        return;
                }
                c->out = p;
                c->out_cap = cap;
        }
        memcpy(c->out + c->out_len, text, len);
        c->out_len += len;
        if (client_flush(c) < 0)
                client_close(c);
}

/* Queues one message (not stolen) to c; disconnects c if it cannot keep up. */
static void client_send(struct client *c, const json_t *msg)
{
        _cleanup_free_ char *text = NULL;
        size_t len;

        if (c->fd >= 0 && (text = proto_dump(msg, &len)))
                client_send_text(c, text, len);
}

static void req_free(struct srv_req *req)
{
        json_decref(req->id);
        client_unref(req->client);
        free(req);
}

void srv_reply(struct srv_req *req, json_t *result)
{
        json_t *msg;

        if (strcmp(req->method, "hello") == 0)
                req->client->hello = true; /* see pick_victim */
        if (!req->id) {                    /* a notification: no answer */
                json_decref(result);
                req_free(req);
                return;
        }
        msg = proto_result(req->id, result ? result : json_object());
        if (msg)
                client_send(req->client, msg);
        json_decref(msg);
        req_free(req);
}

/* Sends an error response for id to c (id may be NULL for json null). */
static void send_error(struct client *c, json_t *id, int code, const char *message)
{
        json_t *msg = proto_error(id ? id : json_null(), code, message, NULL);

        if (msg)
                client_send(c, msg);
        json_decref(msg);
}

static void fail_v(struct srv_req *req, int err, json_t *data, const char *fmt, va_list ap)
{
        char msg[512];

        vsnprintf(msg, sizeof(msg), fmt, ap);
        if (req->id) {
                json_t *reply = proto_error_errno(req->id, err, msg);
                if (reply && data)
                        json_object_update(json_object_get(json_object_get(reply, "error"), "data"),
                                           data);
                if (reply)
                        client_send(req->client, reply);
                json_decref(reply);
        }
        json_decref(data);
        req_free(req);
}

void srv_fail(struct srv_req *req, int err, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        fail_v(req, err, NULL, fmt, ap);
        va_end(ap);
}

void srv_fail_data(struct srv_req *req, int err, json_t *data, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        fail_v(req, err, data, fmt, ap);
        va_end(ap);
}

int srv_req_errmsg(struct srv_req *req, int err, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(req->errmsg, sizeof(req->errmsg), fmt, ap);
        va_end(ap);
        return err;
}

bool srv_req_connected(const struct srv_req *req)
{
        return req->client->fd >= 0;
}

uint64_t srv_req_client(const struct srv_req *req)
{
        return req->client->number;
}

void server_on_close(struct server *s, void (*fn)(uint64_t client, void *ud), void *ud)
{
        s->on_close = fn;
        s->on_close_ud = ud;
}

const char *srv_req_method(const struct srv_req *req)
{
        return req->method;
}

static const struct srv_method *find_method(struct server *s, const char *name)
{
        for (const struct srv_method *m = s->methods; m->name; m++)
                if (strcmp(m->name, name) == 0)
                        return m;
        return NULL;
}

/* The path of the first listener of role, or NULL when there is none. */
static const char *role_path(const struct server *s, enum srv_role role)
{
        for (unsigned i = 0; i < s->n_listeners; i++)
                if (s->listeners[i].role == role)
                        return s->listeners[i].path;
        return NULL;
}

bool server_same_secret(const char *a, const char *b)
{
        size_t la = strlen(a), lb = strlen(b);
        unsigned char d = la != lb;

        for (size_t i = 0; i < la; i++)
                d |= (unsigned char)a[i] ^ (unsigned char)b[i % (lb ? lb : 1)];
        return d == 0;
}

/* On a connection that needs the token: whether this is the hello that gives it (the
 * connection is then free). */
static bool token_given(struct client *c, const struct srv_method *m, json_t *params)
{
        const char *t = json_string_value(json_object_get(params, "token"));

        if (strcmp(m->name, "hello") || !t || !server_same_secret(t, c->token))
                return false;
        c->token = NULL;
        return true;
}

/* Runs one request. A notification from the client (no id) runs too, unanswered. */
static void dispatch(struct client *c, struct proto_msg *msg)
{
        const struct srv_method *m = find_method(c->server, msg->method);
        json_t *params = msg->params;
        struct srv_req *req;
        int r;

        if (!m) {
                char text[300];
                snprintf(text, sizeof(text), "unknown method '%.200s'", msg->method);
                if (msg->id) /* a notification gets no response, not even an error */
                        send_error(c, msg->id, PROTO_METHOD_NOT_FOUND, text);
                return;
        }
        req = calloc(1, sizeof(*req));
        if (!req) {
                if (msg->id)
                        send_error(c, msg->id, PROTO_INTERNAL_ERROR, "out of memory");
                return;
        }
        req->client = c;
        c->ref++;
        req->id = msg->id ? json_incref(msg->id) : NULL;
        req->method = m->name;
        if (params && !json_is_object(params)) {
                srv_fail(req, -EINVAL, "params must be an object");
                return;
        }
        if (c->token && !token_given(c, m, params)) {
                srv_fail(req, -EACCES, "%s",
                         strcmp(m->name, "hello") ? "say hello with the token first"
                                                  : "wrong or missing token");
                if (++c->bad_tokens >= MAX_BAD_TOKENS) {
                        (void)client_flush(c); /* the error, if it fits, then the close */
                        client_close(c);
                }
                return;
        }
        if (m->admin && c->role != SRV_ADMIN) {
                const char *admin = role_path(c->server, SRV_ADMIN);
                srv_fail(req, -EPERM, "method '%s' is allowed only on the admin socket (%s)",
                         m->name, admin ? admin : "goniod has none");
                return;
        }
        params = params ? json_incref(params) : json_object();
        r = m->fn(req, params, c->server->userdata);
        json_decref(params);
        if (r < 0)
                srv_fail(req, r, "%s", req->errmsg[0] ? req->errmsg : strerror(-r));
}

static void handle_line(struct client *c, const char *line, size_t len)
{
        struct proto_msg msg = {0};
        json_t *id = NULL;
        char err[256] = "";
        int r = proto_parse(line, len, &msg, &id, err, sizeof(err));

        c->last_active = loop_now(c->server);
        if (r != 0) {
                send_error(c, id, r, err);
                json_decref(id);
                return;
        }
        if (msg.kind == PROTO_RESPONSE)
                send_error(c, NULL, PROTO_INVALID_REQUEST, "the daemon takes no responses");
        else
                dispatch(c, &msg);
        json_decref(msg.root);
}

/* Reads what c's transport has into buf. Returns the bytes read, 0 at the end of the
 * stream, -EAGAIN or -errno. */
static ssize_t client_recv(struct client *c, char *buf, size_t len)
{
        ssize_t n;

        if (c->tls)
                return tls_read(c->tls, buf, len);
        n = recv(c->fd, buf, len, MSG_DONTWAIT);
        return n < 0 ? -errno : n;
}

/* Reads and handles what c sent; with TLS also what GnuTLS already decrypted, which does
 * not make the socket readable. */
static int client_read(struct client *c)
{
        char buf[16384];
        char *line;
        size_t len;
        int r;

        do {
                ssize_t n = client_recv(c, buf, sizeof(buf));

                if (n == -EAGAIN || n == -EINTR)
                        return 0;
                if (n <= 0)
                        return n < 0 ? (int)n : -ECONNRESET;
                if (proto_lines_feed(&c->in, buf, n) < 0)
                        return -ENOMEM;
                while (c->fd >= 0 && (r = proto_lines_next(&c->in, &line, &len)) != 0) {
                        if (r == -EMSGSIZE)
                                send_error(c, NULL, PROTO_E_LINE_TOO_LONG,
                                           "line longer than the protocol's maximum, dropped");
                        else if (r > 0)
                                handle_line(c, line, len);
                }
        } while (c->fd >= 0 && c->tls && tls_pending(c->tls) > 0);
        return c->fd < 0 ? -ECONNRESET : 0;
}

/* Logs an eviction or refusal, at most one a second with a count of those skipped, so
 * that a flood of connections does not flood the journal. */
static void log_drop(struct server *s, const char *what, const char *text)
{
        uint64_t now = loop_now(s);

        if (now < s->log_quiet_until) {
                s->log_skipped++;
                return;
        }
        log_notice("%s: %s (%u more not logged)", what, text, s->log_skipped);
        s->log_skipped = 0;
        s->log_quiet_until = now + 1000000;
}

/* Writes msg (taken, may be NULL) as one line straight to fd, a connection we will not
 * serve, as far as its socket takes it. */
static void send_raw(int fd, json_t *msg)
{
        _cleanup_free_ char *line = NULL;
        size_t len;

        if (msg && (line = proto_dump(msg, &len)))
                (void)send(fd, line, len, MSG_NOSIGNAL | MSG_DONTWAIT);
        json_decref(msg);
}

/* Writes one error line for -EUSERS straight to a connection we will not serve. */
static void refuse(struct server *s, int fd, const char *why)
{
        char text[256];

        snprintf(text, sizeof(text),
                 "too many clients (%u)%s; close idle connections or retry later", s->max_clients,
                 why);
        send_raw(fd, proto_error_errno(NULL, -EUSERS, text));
        log_drop(s, "refused a connection", text);
}

/* Tells a client that spoke without TLS to a TLS listener why it is not served, as the
 * error of a request that could not be read. Its input is read first (at most
 * MAX_PLAIN_DRAIN bytes): closing over unread input would reset the connection, and the
 * reset could overtake the line. */
static void refuse_plain(struct client *c)
{
        char buf[4096];

        for (int i = 0; i < MAX_PLAIN_DRAIN / (int)sizeof(buf); i++)
                if (recv(c->fd, buf, sizeof(buf), MSG_DONTWAIT) <= 0)
                        break;
        send_raw(c->fd, proto_error(NULL, PROTO_INVALID_REQUEST,
                                    "this port of goniod takes TLS connections only "
                                    "(gonioctl --tls-ca FILE, or --tls)",
                                    NULL));
}

/* Goes on with c's TLS handshake. Returns 1 once it has ended, 0 while it goes on, or
 * -errno when it failed (logged, rate-limited). */
static int client_handshake(struct client *c)
{
        char what[64];
        int r = tls_handshake(c->tls);

        if (r == -EAGAIN)
                return sd_event_source_set_io_events(c->io,
                                                     tls_wants_write(c->tls) ? EPOLLOUT : EPOLLIN);
        if (r == -EPROTONOSUPPORT)
                refuse_plain(c);
        if (r < 0) {
                log_drop(c->server, "TLS handshake failed", tls_conn_error(c->tls));
                return r;
        }
        log_debug("client %p: %s", (void *)c, tls_conn_describe(c->tls, what, sizeof(what)));
        return 1;
}

/* Handles revents on c: on TLS the handshake first, then output and input. */
static int client_io(struct client *c, uint32_t revents)
{
        int r = 0;

        if (c->tls && !tls_ready(c->tls)) {
                r = client_handshake(c);
                if (r <= 0)
                        return r;
                revents |= EPOLLIN | EPOLLOUT; /* requests may have come with its end */
        }
        if (revents & EPOLLOUT)
                r = client_flush(c);
        if (r >= 0 && (revents & (EPOLLIN | EPOLLHUP | EPOLLERR)))
                r = client_read(c);
        return r;
}

static int on_client_io(sd_event_source *es, int fd, uint32_t revents, void *userdata)
{
        struct client *c = userdata;

        c->ref++; /* keep c while handlers run: they may close it */
        if (client_io(c, revents) < 0 && c->fd >= 0)
                client_close(c);
        client_unref(c);
        return 0;
}

/* A TLS client that has not ended its handshake in time (stalled, or trickling bytes). */
static int on_handshake_timeout(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct client *c = userdata;

        log_drop(c->server, "TLS handshake failed", "not ended in time, connection closed");
        client_close(c);
        return 0;
}

/* The client to drop for a new one: the oldest that never said hello, else the one idle
 * longest past idle_usec with no request pending (ref 1); NULL when there is none. */
static struct client *pick_victim(struct server *s, uint64_t now)
{
        struct client *anon = NULL, *idle = NULL;

        for (struct client *c = s->clients; c; c = c->next) {
                if (!c->hello)
                        anon = c; /* newest first: the last one seen is the oldest */
                else if (c->ref == 1 && now - c->last_active >= s->idle_usec &&
                         (!idle || c->last_active < idle->last_active))
                        idle = c;
        }
        return anon ? anon : idle;
}

/* Disconnects a client to make room, telling it why. Returns false if nobody qualifies. */
static bool evict(struct server *s, uint64_t now)
{
        struct client *v = pick_victim(s, now);
        char text[256];
        json_t *msg;

        if (!v)
                return false;
        if (v->hello)
                snprintf(text, sizeof(text),
                         "too many clients (%u); this connection was idle for %llu s and is closed",
                         s->max_clients, (unsigned long long)((now - v->last_active) / 1000000));
        else
                snprintf(text, sizeof(text),
                         "too many clients (%u); this connection never said hello and is closed",
                         s->max_clients);
        log_drop(s, "evicted a client", text);
        msg = proto_error_errno(NULL, -EUSERS, text);
        v->ref++; /* client_send may close v already */
        if (msg)
                client_send(v, msg);
        json_decref(msg);
        client_close(v);
        client_unref(v);
        return true;
}

/* Serves a new connection of listener l (cfd is taken). */
static void client_add(struct listener *l, int cfd, uint64_t now)
{
        _cleanup_close_ int fd = cfd;
        struct server *s = l->server;
        struct client *c = calloc(1, sizeof(*c));
        int r;

        if (!c)
                return;
        c->server = s;
        c->ref = 1;
        c->role = l->role;
        c->token = l->token[0] ? l->token : NULL;
        c->last_active = now;
        c->number = ++s->last_number;
        r = sd_event_add_io(s->event, &c->io, fd, EPOLLIN, on_client_io, c);
        if (r >= 0 && l->tls)
                r = tls_conn_new(l->tls, fd, NULL, &c->tls);
        if (r >= 0 && l->tls)
                r = tls_conn_set_deadline(c->tls, s->event, TLS_HANDSHAKE_USEC,
                                          on_handshake_timeout, c);
        if (r < 0) {
                c->io = sd_event_source_disable_unref(c->io);
                tls_conn_free(c->tls);
                free(c);
                log_warning_errno(r, "cannot watch client, ignoring: %m");
                return;
        }
        sd_event_source_set_description(c->io, "client");
        c->fd = TAKE_FD(fd);
        c->next = s->clients;
        s->clients = c;
        s->n_clients++;
        log_debug("client %p connected", (void *)c);
}

/* Takes a new connection from l, evicting a client when the table is full, or refuses it. */
static void admit(struct listener *l, int cfd)
{
        _cleanup_close_ int fd = cfd;
        struct server *s = l->server;
        uint64_t now = loop_now(s);

        if (s->n_clients >= s->max_clients && !evict(s, now)) {
                refuse(s, fd, "");
                return;
        }
        client_add(l, TAKE_FD(fd), now);
}

/* Out of descriptors: frees the spare one to accept and refuse one pending connection, so
 * the listening socket does not stay readable forever. Returns 0, or -errno of accept. */
static int refuse_without_fd(struct server *s, int lfd)
{
        int cfd, r = 0;

        s->spare_fd = safe_close(s->spare_fd);
        cfd = accept4(lfd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (cfd >= 0) {
                refuse(s, cfd, " and out of file descriptors");
                close(cfd);
        } else
                r = -errno;
        s->spare_fd = open("/dev/null", O_RDONLY | O_CLOEXEC);
        return r;
}

static int on_accept(sd_event_source *es, int fd, uint32_t revents, void *userdata)
{
        struct listener *l = userdata;

        for (unsigned i = 0; i < SRV_ACCEPT_BATCH; i++) {
                int cfd = accept4(fd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
                int err = cfd < 0 ? errno : 0;

                if (err == EMFILE || err == ENFILE)
                        err = -refuse_without_fd(l->server, fd);
                if (cfd >= 0)
                        admit(l, cfd);
                else if (err == EAGAIN)
                        break;
                else if (err != 0 && err != EINTR && err != ECONNABORTED)
                        return log_warning_errno(err, "accept() failed, ignoring: %m"), 0;
        }
        return 0;
}

/* Raises the soft RLIMIT_NOFILE to fit SRV_MAX_CLIENTS plus SRV_FD_RESERVE when it is
 * lower, but never past that: libmodbus uses select(), which cannot watch a descriptor
 * past FD_SETSIZE (1024). Returns how many clients the limit allows. */
static unsigned client_budget(void)
{
        rlim_t need = SRV_MAX_CLIENTS + SRV_FD_RESERVE;
        struct rlimit rl;

        if (getrlimit(RLIMIT_NOFILE, &rl) < 0 || rl.rlim_cur >= need)
                return SRV_MAX_CLIENTS;
        rl.rlim_cur = MIN(need, rl.rlim_max);
        if (setrlimit(RLIMIT_NOFILE, &rl) < 0)
                (void)getrlimit(RLIMIT_NOFILE, &rl);
        if (rl.rlim_cur >= need)
                return SRV_MAX_CLIENTS;
        log_warning("RLIMIT_NOFILE is %llu and cannot be raised to %llu: serving at most %llu "
                    "clients",
                    (unsigned long long)rl.rlim_cur, (unsigned long long)need,
                    (unsigned long long)rl.rlim_cur / 2);
        return MAX(rl.rlim_cur / 2, 1);
}

/* Takes an exclusive flock on "<path>.lock", held while the returned fd is open.
 * Returns the fd, -EADDRINUSE when another process holds it, or -errno (logged). */
static int lock_path(const char *path)
{
        _cleanup_close_ int fd = -EBADF;
        char lock[PATH_MAX];

        if (snprintf(lock, sizeof(lock), "%s.lock", path) >= (int)sizeof(lock))
                return log_error_errno(ENAMETOOLONG, "Socket path too long: %s", path);
        fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC | O_NOCTTY, 0660);
        if (fd < 0)
                return log_error_errno(errno, "Cannot open lock file %s: %m", lock);
        if (flock(fd, LOCK_EX | LOCK_NB) < 0)
                return errno == EWOULDBLOCK ? -EADDRINUSE
                                            : log_error_errno(errno, "Cannot lock %s: %m", lock);
        return TAKE_FD(fd);
}

/* What is at path: 1 when a connect() succeeds (a server), 0 when nothing is there,
 * -ECONNREFUSED for a stale socket, -ENOTSOCK for anything but a socket, or -errno. */
static int probe_path(const char *path)
{
        _cleanup_close_ int fd = -EBADF;
        struct sockaddr_un sa;
        struct stat st;

        if (lstat(path, &st) < 0)
                return errno == ENOENT ? 0 : -errno;
        if (!S_ISSOCK(st.st_mode))
                return -ENOTSOCK;
        fd = proto_unix_socket(path, &sa);
        if (fd < 0)
                return fd;
        if (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0 || errno == EAGAIN)
                return 1; /* EAGAIN: a server whose backlog is full */
        return -errno;
}

/* Frees path for bind: refuses a live server, a lock held elsewhere or a file that is not
 * a socket; removes a stale socket. Returns 0, -EADDRINUSE, -EEXIST or -errno (logged). */
static int clear_path(const char *path, bool locked)
{
        int r = probe_path(path);

        if (r > 0)
                return log_error_errno(EADDRINUSE,
                                       "another goniod is serving %s (connect succeeded); "
                                       "stop it first",
                                       path);
        if (!locked)
                return log_error_errno(EADDRINUSE,
                                       "another goniod holds %s.lock (starting or stopping); "
                                       "stop it first",
                                       path);
        if (r == -ENOTSOCK)
                return log_error_errno(EEXIST, "%s exists and is not a socket; not removing it",
                                       path);
        if (r == -ECONNREFUSED) {
                log_info("removing stale socket %s (nothing listens there)", path);
                if (unlink(path) < 0 && errno != ENOENT)
                        return log_error_errno(errno, "Cannot remove stale socket %s: %m", path);
                return 0;
        }
        return r < 0 ? log_error_errno(r, "Cannot probe %s: %m", path) : 0;
}

/* Locks, clears, binds and listens on l->path with mode. Returns the fd or -errno (logged). */
static int listen_unix(struct listener *l, mode_t mode)
{
        struct sockaddr_un sa;
        _cleanup_close_ int fd = proto_unix_socket(l->path, &sa);
        struct stat st;
        int r;

        if (fd < 0)
                return log_error_errno(fd, "Cannot listen on %s: %m", l->path);
        l->lock_fd = lock_path(l->path);
        if (l->lock_fd < 0 && l->lock_fd != -EADDRINUSE)
                return l->lock_fd;
        r = clear_path(l->path, l->lock_fd >= 0);
        if (r < 0)
                return r;
        if (bind(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0 || lstat(l->path, &st) < 0)
                return log_error_errno(errno, "Cannot bind %s: %m", l->path);
        l->bound = true;
        l->dev = st.st_dev;
        l->ino = st.st_ino;
        if (chmod(l->path, mode) < 0 || listen(fd, SOMAXCONN) < 0)
                return log_error_errno(errno, "Cannot listen on %s: %m", l->path);
        return TAKE_FD(fd);
}

/* Whether l's path is still the socket we bound (another process may have replaced it). */
static bool own_socket(const struct listener *l)
{
        struct stat st;

        return l->bound && lstat(l->path, &st) == 0 && S_ISSOCK(st.st_mode) &&
               st.st_dev == l->dev && st.st_ino == l->ino;
}

/* Stops listening on l; unlinks its path if it is still the socket we bound. */
static void listener_close(struct listener *l)
{
        l->src = sd_event_source_disable_unref(l->src);
        l->fd = safe_close(l->fd);
        if (own_socket(l))
                (void)unlink(l->path);
        l->lock_fd = safe_close(l->lock_fd); /* after the unlink: the next daemon may take over */
        l->tls = NULL;                       /* the credentials are main.c's */
}

/* Takes the next listener slot of s for role and path. Returns it, or NULL with *err set
 * (-ENOBUFS: all slots taken, -ENAMETOOLONG; logged). */
static struct listener *listener_new(struct server *s, enum srv_role role, const char *path,
                                     int *err)
{
        struct listener *l = &s->listeners[s->n_listeners];

        if (s->n_listeners == SRV_MAX_LISTENERS) {
                *err = log_error_errno(ENOBUFS, "goniod listens on %d sockets at most",
                                       SRV_MAX_LISTENERS);
                return NULL;
        }
        *l = (struct listener){.server = s, .fd = -EBADF, .lock_fd = -EBADF, .role = role};
        if (snprintf(l->path, sizeof(l->path), "%s", path) >= (int)sizeof(l->path)) {
                *err = log_error_errno(ENAMETOOLONG, "Socket path too long: %s", path);
                return NULL;
        }
        s->n_listeners++;
        return l;
}

/* Watches fd (taken; r < 0: the error that left none) for the newest listener l, enabled
 * once the server is started. Returns 0, or -errno after undoing l. */
static int listener_add(struct listener *l, int fd)
{
        struct server *s = l->server;
        int r = fd;

        l->fd = fd;
        if (r >= 0)
                r = sd_event_add_io(s->event, &l->src, fd, EPOLLIN, on_accept, l);
        if (r >= 0)
                r = sd_event_source_set_enabled(l->src, s->started ? SD_EVENT_ON : SD_EVENT_OFF);
        if (r < 0) {
                listener_close(l);
                s->n_listeners--;
                return r;
        }
        (void)sd_event_source_set_description(l->src, l->role == SRV_ADMIN ? "admin-socket"
                                                                           : "control-socket");
        log_debug("listening on %s (%s)", l->path, l->role == SRV_ADMIN ? "admin" : "operator");
        return 0;
}

int server_new(sd_event *event, const struct srv_method *methods, void *userdata,
               struct server **ret)
{
        struct server *s = calloc(1, sizeof(*s));

        if (!s)
                return -ENOMEM;
        s->event = event;
        s->methods = methods;
        s->userdata = userdata;
        s->max_clients = s->budget = client_budget();
        s->idle_usec = SRV_IDLE_TIMEOUT_USEC;
        s->spare_fd = open("/dev/null", O_RDONLY | O_CLOEXEC);
        if (s->spare_fd < 0) {
                int r = -errno;
                free(s);
                return r;
        }
        *ret = s;
        return 0;
}

int server_listen(struct server *s, const char *path, enum srv_role role)
{
        int r;
        struct listener *l = listener_new(s, role, path, &r);

        if (!l)
                return r;
        return listener_add(l, listen_unix(l, role == SRV_ADMIN ? 0600 : 0660));
}

/* The address of addr ("HOST:PORT", HOST numeric, [::1] bracketed) into sa. Returns 0 for a
 * loopback address, -EPERM for another (sa filled all the same), or -EINVAL. */
static int tcp_address(const char *addr, struct sockaddr_storage *sa, socklen_t *len)
{
        struct addrinfo hints = {.ai_family = AF_UNSPEC,
                                 .ai_socktype = SOCK_STREAM,
                                 .ai_flags = AI_NUMERICHOST | AI_NUMERICSERV | AI_PASSIVE},
                        *res = NULL;
        char host[64];
        const char *colon = strrchr(addr, ':');
        bool loop;

        if (!colon || colon == addr || (size_t)(colon - addr) >= sizeof(host))
                return -EINVAL;
        snprintf(host, sizeof(host), "%.*s", (int)(colon - addr), addr);
        if (host[0] == '[' && host[strlen(host) - 1] == ']')
                memmove(host, host + 1, strlen(host)), host[strlen(host) - 1] = 0;
        if (getaddrinfo(host, colon + 1, &hints, &res) != 0 || !res)
                return -EINVAL;
        memcpy(sa, res->ai_addr, res->ai_addrlen);
        *len = res->ai_addrlen;
        freeaddrinfo(res);
        loop = sa->ss_family == AF_INET
                       ? (ntohl(((struct sockaddr_in *)sa)->sin_addr.s_addr) >> 24) == 127
                       : IN6_IS_ADDR_LOOPBACK(&((struct sockaddr_in6 *)sa)->sin6_addr);
        return loop ? 0 : -EPERM;
}

int server_tcp_socket(const char *addr, const char *what, const char *beyond)
{
        struct sockaddr_storage sa;
        socklen_t len = 0;
        int r = tcp_address(addr, &sa, &len), one = 1;
        _cleanup_close_ int fd = -EBADF;

        if (r == -EPERM && beyond)
                return log_error_errno(EPERM, "%s %s: not a loopback address: beyond loopback %s",
                                       what, addr, beyond);
        if (r < 0 && r != -EPERM)
                return log_error_errno(EINVAL,
                                       "%s %s: expected HOST:PORT, HOST a numeric address "
                                       "(127.0.0.1, [::1]; others with TLS)",
                                       what, addr);
        fd = socket(sa.ss_family, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
        if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one)) < 0 ||
            bind(fd, (struct sockaddr *)&sa, len) < 0 || listen(fd, SOMAXCONN) < 0)
                return log_error_errno(errno, "Cannot listen on %s %s: %m", what, addr);
        return TAKE_FD(fd);
}

int server_check_token(const char *token, const char *what, const char *addr)
{
        if (!token || strlen(token) < SRV_TOKEN_MIN || strlen(token) > SRV_TOKEN_MAX)
                return log_error_errno(EINVAL, "%s %s: the token must be %d to %d characters", what,
                                       addr, SRV_TOKEN_MIN, SRV_TOKEN_MAX);
        return 0;
}

int server_listen_tcp(struct server *s, const char *addr, const char *token,
                      const struct tls_creds *tls)
{
        struct listener *l;
        int r, fd;

        if ((r = server_check_token(token, "TCP listener", addr)) < 0)
                return r;
        fd = server_tcp_socket(addr, "TCP listener",
                               tls ? NULL : "goniod needs TLS (--tls-cert FILE --tls-key FILE)");
        if (fd < 0 || !(l = listener_new(s, SRV_OPERATOR, addr, &r))) {
                safe_close(fd);
                return fd < 0 ? fd : r;
        }
        snprintf(l->token, sizeof(l->token), "%s", token);
        l->tls = tls;
        log_info("listening on TCP %s (%s)", addr, tls ? "TLS" : "plain, loopback");
        return listener_add(l, fd);
}

int server_listen_fd(struct server *s, int fd, enum srv_role role)
{
        _cleanup_close_ int owned = fd;
        struct sockaddr_un sa = {0};
        socklen_t len = sizeof(sa);
        struct listener *l;
        int r = sd_is_socket_unix(fd, SOCK_STREAM, 1, NULL, 0), flags;

        if (r <= 0)
                return log_error_errno(r < 0 ? r : ENOTSOCK,
                                       "descriptor %d is not a listening AF_UNIX stream socket",
                                       fd);
        if (getsockname(fd, (struct sockaddr *)&sa, &len) < 0 || (flags = fcntl(fd, F_GETFL)) < 0 ||
            fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0)
                return log_error_errno(errno, "Cannot use descriptor %d: %m", fd);
        l = listener_new(s, role, sa.sun_path[0] ? sa.sun_path : "(abstract socket)", &r);
        if (!l)
                return r;
        return listener_add(l, TAKE_FD(owned));
}

/* The role of a socket systemd passed, by its FileDescriptorName=; -EINVAL (logged) for
 * another name. "unknown" is what a socket without a name gets. */
static int role_of(const char *name)
{
        if (strcmp(name, "admin") == 0)
                return SRV_ADMIN;
        if (strcmp(name, "operator") == 0 || strcmp(name, "unknown") == 0)
                return SRV_OPERATOR;
        return log_error_errno(EINVAL,
                               "systemd passed a socket named '%s'; goniod takes 'operator' "
                               "and 'admin' (FileDescriptorName=)",
                               name);
}

int server_listen_systemd(struct server *s)
{
        char **names = NULL;
        int n = sd_listen_fds_with_names(true, &names), r = 0;

        if (n < 0)
                return log_error_errno(n, "Cannot take the sockets systemd passed: %m");
        for (int i = 0; i < n; i++) {
                int fd = SD_LISTEN_FDS_START + i, role = r < 0 ? r : role_of(names[i]);

                if (role < 0) {
                        r = role;
                        close(fd);
                } else
                        r = server_listen_fd(s, fd, role);
                free(names[i]);
        }
        free(names);
        if (r >= 0 && n > 0 && !role_path(s, SRV_OPERATOR))
                r = log_error_errno(EINVAL, "systemd passed no operator socket "
                                            "(FileDescriptorName=operator)");
        if (r >= 0 && n > 0 && !role_path(s, SRV_ADMIN))
                log_notice("systemd passed no admin socket: admin methods are refused");
        return r < 0 ? r : n;
}

int server_start(struct server *s)
{
        int r = 0;

        s->started = true;
        for (unsigned i = 0; i < s->n_listeners && r >= 0; i++)
                r = sd_event_source_set_enabled(s->listeners[i].src, SD_EVENT_ON);
        return r;
}

void server_set_limits(struct server *s, unsigned max_clients, uint64_t idle_usec)
{
        s->max_clients = CLAMP(max_clients, 1u, s->budget);
        s->idle_usec = idle_usec;
}

struct server *server_free(struct server *s)
{
        if (!s)
                return NULL;
        s->on_close = NULL;
        while (s->clients)
                client_close(s->clients);
        for (unsigned i = 0; i < s->n_listeners; i++)
                listener_close(&s->listeners[i]);
        safe_close(s->spare_fd);
        free(s);
        return NULL;
}

void server_broadcast(struct server *s, const char *method, json_t *params)
{
        json_t *msg = proto_notification(method, params);
        _cleanup_free_ char *text = NULL;
        size_t len;

        if (msg && (text = proto_dump(msg, &len))) /* once for every client */
                for (struct client *c = s->clients, *next; c; c = next) {
                        next = c->next;
                        if (!c->token) /* the rig's doings are not for strangers */
                                client_send_text(c, text, len);
                }
        json_decref(msg);
}

unsigned server_clients(const struct server *s)
{
        return s->n_clients;
}

int srv_params_check(struct srv_req *req, json_t *params, const char *const *allowed)
{
        const char *key;
        json_t *v = NULL;

        json_object_foreach(params, key, v)
        {
                bool ok = false;
                for (const char *const *a = allowed; *a; a++)
                        ok = ok || strcmp(*a, key) == 0;
                if (!ok)
                        return srv_req_errmsg(req, -EINVAL, "unknown param '%s'", key);
        }
        return 0;
}

/* Looks up key; 0 when absent or null, 1 when present of the wanted type, else -EINVAL. */
static int param(struct srv_req *req, json_t *params, const char *key, json_type type,
                 const char *what, json_t **out)
{
        json_t *v = json_object_get(params, key);

        if (!v || json_is_null(v))
                return 0;
        if (json_typeof(v) != type && !(type == JSON_REAL && json_is_integer(v)) &&
            !(type == JSON_TRUE && json_is_boolean(v)))
                return srv_req_errmsg(req, -EINVAL, "param '%s': expected %s", key, what);
        *out = v;
        return 1;
}

int srv_param_str(struct srv_req *req, json_t *params, const char *key, const char **out)
{
        json_t *v = NULL;
        int r = param(req, params, key, JSON_STRING, "a string", &v);

        if (r > 0)
                *out = json_string_value(v);
        return r;
}

int srv_param_double(struct srv_req *req, json_t *params, const char *key, double *out)
{
        json_t *v = NULL;
        int r = param(req, params, key, JSON_REAL, "a number", &v);

        if (r > 0)
                *out = json_number_value(v);
        return r;
}

int srv_param_int(struct srv_req *req, json_t *params, const char *key, long min, long max,
                  long *out)
{
        json_t *v = NULL;
        int r = param(req, params, key, JSON_INTEGER, "an integer", &v);

        if (r <= 0)
                return r;
        if (json_integer_value(v) < min || json_integer_value(v) > max)
                return srv_req_errmsg(req, -EINVAL, "param '%s': %lld is outside [%ld, %ld]", key,
                                      (long long)json_integer_value(v), min, max);
        *out = json_integer_value(v);
        return 1;
}

int srv_param_bool(struct srv_req *req, json_t *params, const char *key, bool *out)
{
        json_t *v = NULL;
        int r = param(req, params, key, JSON_TRUE, "true or false", &v);

        if (r > 0)
                *out = json_is_true(v);
        return r;
}
