/* server.c - JSON-RPC 2.0 control server on a Unix stream socket, on sd-event.
 *
 * DESIGN: every client has a line reader (proto_lines, bounded) and an output
 * buffer. Output is written as far as the socket takes it; the rest waits for
 * EPOLLOUT. A client whose unsent output passes SRV_MAX_OUTPUT is disconnected,
 * so a stalled client cannot grow the daemon's memory. Requests hold a
 * reference on their client, so a deferred answer to a client that has gone is
 * dropped safely. Nothing here blocks. */
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "common/log.h"
#include "protocol/proto.h"
#include "server.h"

#define SRV_MAX_OUTPUT  (8u << 20)
#define SRV_MAX_CLIENTS 64

struct client {
        struct server *server;
        unsigned ref;
        int fd;
        sd_event_source *io;
        struct proto_lines in;
        char *out;
        size_t out_len, out_cap;
        struct client *next;
};

struct server {
        sd_event *event;
        int fd;
        char *path;
        sd_event_source *listen;
        const struct srv_method *methods;
        void *userdata;
        struct client *clients;
        unsigned n_clients;
};

struct srv_req {
        struct client *client;
        json_t *id;
        const char *method;
        char errmsg[512];
};

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
        close(c->fd);
        c->fd = -EBADF;
        for (struct client **p = &s->clients; *p; p = &(*p)->next)
                if (*p == c) {
                        *p = c->next;
                        break;
                }
        s->n_clients--;
        log_debug("client %p disconnected", (void *)c);
        client_unref(c);
}

static int client_flush(struct client *c)
{
        while (c->out_len > 0) {
                ssize_t n = send(c->fd, c->out, c->out_len, MSG_NOSIGNAL | MSG_DONTWAIT);

                if (n < 0 && errno == EINTR)
                        continue;
                if (n < 0 && errno == EAGAIN)
                        break;
                if (n < 0)
                        return -errno;
                memmove(c->out, c->out + n, c->out_len - n);
                c->out_len -= n;
        }
        return sd_event_source_set_io_events(c->io, EPOLLIN | (c->out_len ? EPOLLOUT : 0));
}

/* Queues one message (not stolen) to c; disconnects c if it cannot keep up. */
static void client_send(struct client *c, const json_t *msg)
{
        _cleanup_free_ char *text = NULL;
        size_t len;

        if (c->fd < 0 || !(text = proto_dump(msg, &len)))
                return;
        if (c->out_len + len > SRV_MAX_OUTPUT) {
                log_warning("client %p does not read its replies, disconnecting", (void *)c);
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

static void req_free(struct srv_req *req)
{
        json_decref(req->id);
        client_unref(req->client);
        free(req);
}

void srv_reply(struct srv_req *req, json_t *result)
{
        json_t *msg;

        if (!req->id) { /* a notification: no answer */
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
                send_error(c, msg->id, PROTO_METHOD_NOT_FOUND, text);
                return;
        }
        req = calloc(1, sizeof(*req));
        if (!req) {
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

static int client_read(struct client *c)
{
        char buf[16384];
        ssize_t n = recv(c->fd, buf, sizeof(buf), MSG_DONTWAIT);
        char *line;
        size_t len;
        int r;

        if (n < 0)
                return errno == EAGAIN || errno == EINTR ? 0 : -errno;
        if (n == 0)
                return -ECONNRESET;
        if (proto_lines_feed(&c->in, buf, n) < 0)
                return -ENOMEM;
        c->ref++; /* keep c while handlers run */
        while (c->fd >= 0 && (r = proto_lines_next(&c->in, &line, &len)) != 0) {
                if (r == -EMSGSIZE)
                        send_error(c, NULL, PROTO_E_LINE_TOO_LONG,
                                   "line longer than the protocol's maximum, dropped");
                else if (r > 0)
                        handle_line(c, line, len);
        }
        r = c->fd < 0 ? -ECONNRESET : 0;
        client_unref(c);
        return r;
}

static int on_client_io(sd_event_source *es, int fd, uint32_t revents, void *userdata)
{
        struct client *c = userdata;
        int r = 0;

        if (revents & EPOLLOUT)
                r = client_flush(c);
        if (r >= 0 && (revents & (EPOLLIN | EPOLLHUP | EPOLLERR)))
                r = client_read(c);
        if (r < 0 && c->fd >= 0)
                client_close(c);
        return 0;
}

static int on_accept(sd_event_source *es, int fd, uint32_t revents, void *userdata)
{
        struct server *s = userdata;
        _cleanup_close_ int cfd = accept4(fd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
        struct client *c;
        int r;

        if (cfd < 0)
                return log_warning_errno(errno, "accept() failed, ignoring: %m"), 0;
        if (s->n_clients >= SRV_MAX_CLIENTS)
                return log_warning("too many clients, refusing a connection"), 0;
        c = calloc(1, sizeof(*c));
        if (!c)
                return 0;
        c->server = s;
        c->ref = 1;
        r = sd_event_add_io(s->event, &c->io, cfd, EPOLLIN, on_client_io, c);
        if (r < 0) {
                free(c);
                return log_warning_errno(r, "cannot watch client, ignoring: %m"), 0;
        }
        sd_event_source_set_description(c->io, "client");
        c->fd = TAKE_FD(cfd);
        c->next = s->clients;
        s->clients = c;
        s->n_clients++;
        log_debug("client %p connected", (void *)c);
        return 0;
}

static int listen_unix(const char *path)
{
        struct sockaddr_un sa;
        _cleanup_close_ int fd = proto_unix_socket(path, &sa);

        if (fd < 0)
                return fd;
        (void)unlink(path);
        if (bind(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0 || chmod(path, 0660) < 0 ||
            listen(fd, 16) < 0)
                return -errno;
        return TAKE_FD(fd);
}

int server_new(sd_event *event, const char *path, const struct srv_method *methods, void *userdata,
               struct server **ret)
{
        struct server *s = calloc(1, sizeof(*s));
        int r;

        if (!s)
                return -ENOMEM;
        s->event = event;
        s->methods = methods;
        s->userdata = userdata;
        s->fd = listen_unix(path);
        s->path = strdup(path);
        if (s->fd < 0 || !s->path) {
                r = s->fd < 0 ? s->fd : -ENOMEM;
                server_free(s);
                return log_error_errno(r, "Cannot listen on %s: %m", path);
        }
        r = sd_event_add_io(event, &s->listen, s->fd, EPOLLIN, on_accept, s);
        if (r < 0) {
                server_free(s);
                return r;
        }
        sd_event_source_set_description(s->listen, "control-socket");
        *ret = s;
        return 0;
}

struct server *server_free(struct server *s)
{
        if (!s)
                return NULL;
        while (s->clients)
                client_close(s->clients);
        sd_event_source_disable_unref(s->listen);
        if (s->fd >= 0) {
                close(s->fd);
                unlink(s->path);
        }
        free(s->path);
        free(s);
        return NULL;
}

void server_broadcast(struct server *s, const char *method, json_t *params)
{
        json_t *msg = proto_notification(method, params);

        for (struct client *c = s->clients, *next; msg && c; c = next) {
                next = c->next;
                client_send(c, msg);
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
