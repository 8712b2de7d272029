/* conn.c - gonioctl's connection to goniod over a Unix stream socket or TCP (plain or TLS,
 * daemon/tls.h): non-blocking I/O with poll() and a deadline on every wait, line framing
 * and message validation from protocol/, one outstanding request at a time. */
#include <errno.h>
#include <netdb.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>

#include "client/conn.h"
#include "common/clock.h"
#include "common/cleanup.h"
#include "daemon/tls.h"
#include "protocol/proto.h"

#define CONNECT_RETRY_MS 10 /* pause between connects while the listen backlog is full */

struct conn {
        int fd;
        struct tls_creds *creds; /* TLS: what the server's certificate is checked against */
        struct tls_conn *tls;    /* NULL: a plain connection */
        json_int_t next_id;
        json_int_t abandoned_id; /* a request whose wait was given up (0: none) */
        struct proto_lines lines;
};

int64_t conn_now_ms(void)
{
        return (int64_t)(gn_monotonic_ns() / 1000000);
}

/* The poll() timeout left until deadline: -1 for none, else >= 0. */
static int poll_timeout(int64_t deadline)
{
        int64_t left;

        if (deadline == CONN_NO_DEADLINE)
                return -1;
        left = deadline - conn_now_ms();
        return (int)CLAMP(left, 0, (int64_t)INT32_MAX);
}

/* Waits until fd is ready for events. Returns 0, -ETIMEDOUT, -EINTR (intr_fd readable). */
static int wait_fd(int fd, short events, int64_t deadline, int intr_fd)
{
        struct pollfd p[2] = {{.fd = fd, .events = events}, {.fd = intr_fd, .events = POLLIN}};

        for (;;) {
                int r = poll(p, intr_fd >= 0 ? 2 : 1, poll_timeout(deadline));

                if (r < 0 && errno == EINTR)
                        continue;
                if (r < 0)
                        return -errno;
                if (r == 0)
                        return -ETIMEDOUT;
                if (intr_fd >= 0 && p[1].revents)
                        return -EINTR;
                return 0;
        }
}

static int connect_socket(int fd, const struct sockaddr *sa, socklen_t len, int64_t deadline)
{
        for (;;) {
                int err = 0;
                socklen_t sl = sizeof(err);

                if (connect(fd, sa, len) == 0)
                        return 0;
                if (errno == EAGAIN) { /* Unix sockets: backlog full, try again shortly */
                        if (conn_now_ms() + CONNECT_RETRY_MS > deadline)
                                return -ETIMEDOUT;
                        poll(NULL, 0, CONNECT_RETRY_MS);
                        continue;
                }
                if (errno != EINPROGRESS)
                        return -errno;
                int r = wait_fd(fd, POLLOUT, deadline, -1);
                if (r < 0)
                        return r;
                if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &sl) < 0)
                        return -errno;
                return -err;
        }
}

int conn_open(const char *path, int64_t deadline, struct conn **ret)
{
        struct sockaddr_un sa;
        _cleanup_close_ int fd = proto_unix_socket(path, &sa);
        struct conn *c;
        int r;

        if (fd < 0)
                return fd;
        r = connect_socket(fd, (const struct sockaddr *)&sa, sizeof(sa), deadline);
        if (r < 0)
                return r;
        c = calloc(1, sizeof(*c));
        if (!c)
                return -ENOMEM;
        c->fd = TAKE_FD(fd);
        c->next_id = 1;
        *ret = c;
        return 0;
}

/* Splits addr ("HOST:PORT", "[V6]:PORT") into host and port. Returns 0 or -EINVAL. */
static int split_addr(const char *addr, char *host, size_t len, const char **port)
{
        const char *colon = strrchr(addr, ':');
        size_t n = colon ? (size_t)(colon - addr) : 0;

        if (!colon || n == 0 || n >= len || !colon[1])
                return -EINVAL;
        if (addr[0] == '[' && addr[n - 1] == ']')
                snprintf(host, len, "%.*s", (int)n - 2, addr + 1);
        else
                snprintf(host, len, "%.*s", (int)n, addr);
        *port = colon + 1;
        return host[0] ? 0 : -EINVAL;
}

/* A TCP connection to host:port before deadline, trying each address of host in turn.
 * Returns the socket (non-blocking), -EHOSTUNREACH when host has no address, or the errno
 * of the last connect. */
static int connect_tcp(const char *host, const char *port, int64_t deadline)
{
        struct addrinfo hints = {.ai_socktype = SOCK_STREAM}, *res = NULL;
        int r = -EHOSTUNREACH;

        if (getaddrinfo(host, port, &hints, &res) != 0)
                return -EHOSTUNREACH;
        for (struct addrinfo *ai = res; ai; ai = ai->ai_next) {
                _cleanup_close_ int fd =
                        socket(ai->ai_family, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);

                r = fd < 0 ? -errno : connect_socket(fd, ai->ai_addr, ai->ai_addrlen, deadline);
                if (r >= 0) {
                        r = TAKE_FD(fd);
                        break;
                }
        }
        freeaddrinfo(res);
        return r;
}

/* The handshake of c's TLS session with the server host before deadline. Returns 0 or the
 * -errno of tls_handshake (err->message says why), -ETIMEDOUT. */
static int handshake(struct conn *c, const char *host, int64_t deadline, struct conn_error *err)
{
        int r = tls_conn_new(c->creds, c->fd, host, &c->tls);

        while (r >= 0 && (r = tls_handshake(c->tls)) == -EAGAIN)
                r = wait_fd(c->fd, tls_wants_write(c->tls) ? POLLOUT : POLLIN, deadline, -1);
        if (r < 0 && c->tls && tls_conn_error(c->tls)[0])
                snprintf(err->message, sizeof(err->message), "TLS: %s", tls_conn_error(c->tls));
        return r;
}

int conn_open_tcp(const char *addr, bool tls, const char *ca_file, int64_t deadline,
                  struct conn **ret, struct conn_error *err)
{
        _cleanup_(conn_freep) struct conn *c = NULL;
        const char *port;
        char host[256];
        int r = split_addr(addr, host, sizeof(host), &port);

        *err = (struct conn_error){};
        if (r < 0) {
                snprintf(err->message, sizeof(err->message), "expected HOST:PORT");
                return r;
        }
        c = calloc(1, sizeof(*c));
        if (!c)
                return -ENOMEM;
        c->next_id = 1;
        c->fd = -EBADF;
        if ((tls || ca_file) &&
            (r = tls_creds_new_client(ca_file, &c->creds, err->message, sizeof(err->message))) < 0)
                return r;
        c->fd = connect_tcp(host, port, deadline);
        if (c->fd == -EHOSTUNREACH)
                snprintf(err->message, sizeof(err->message), "no address for %s", host);
        if (c->fd < 0)
                return c->fd;
        if (c->creds && (r = handshake(c, host, deadline, err)) < 0)
                return r;
        *ret = TAKE_PTR(c);
        return 0;
}

struct conn *conn_free(struct conn *c)
{
        if (!c)
                return NULL;
        tls_conn_free(c->tls);
        tls_creds_free(c->creds);
        closep(&c->fd);
        proto_lines_done(&c->lines);
        free(c);
        return NULL;
}

/* Sends what c's transport takes of s. Returns the bytes taken, -EAGAIN or -errno. */
static ssize_t send_some(struct conn *c, const char *s, size_t n)
{
        ssize_t k;

        if (c->tls)
                return tls_write(c->tls, s, n);
        k = send(c->fd, s, n, MSG_NOSIGNAL);
        return k < 0 ? -errno : k;
}

static int send_all(struct conn *c, const char *s, size_t n, int64_t deadline)
{
        while (n > 0) {
                ssize_t k = send_some(c, s, n);

                if (k == -EINTR)
                        continue;
                if (k == -EAGAIN) {
                        bool in = c->tls && !tls_wants_write(c->tls);
                        int r = wait_fd(c->fd, in ? POLLIN : POLLOUT, deadline, -1);
                        if (r < 0)
                                return r;
                        continue;
                }
                if (k < 0)
                        return k == -EPIPE ? -ECONNRESET : (int)k;
                s += k;
                n -= (size_t)k;
        }
        return 0;
}

/* Reads what is available into the framer. Returns 0, -ECONNRESET on EOF, or -errno. */
static int read_some(struct conn *c)
{
        char buf[16384];
        ssize_t n = c->tls ? tls_read(c->tls, buf, sizeof(buf)) : recv(c->fd, buf, sizeof(buf), 0);

        if (!c->tls && n < 0)
                n = -errno;
        if (n == -EAGAIN || n == -EINTR)
                return 0;
        if (n <= 0)
                return n < 0 ? (int)n : -ECONNRESET;
        return proto_lines_feed(&c->lines, buf, (size_t)n);
}

/* Reads the next valid message before deadline into *msg (json_decref(msg->root)). */
static int read_msg(struct conn *c, int64_t deadline, int intr_fd, struct proto_msg *msg,
                    struct conn_error *err)
{
        for (;;) {
                char *line;
                size_t len;
                int r = proto_lines_next(&c->lines, &line, &len);

                if (r == -EMSGSIZE) {
                        snprintf(err->message, sizeof(err->message),
                                 "message from server longer than %d bytes", PROTO_MAX_LINE);
                        return r;
                }
                if (r > 0) {
                        char why[256];

                        if (proto_parse(line, len, msg, NULL, why, sizeof(why)) == 0)
                                return 0;
                        snprintf(err->message, sizeof(err->message), "bad message from server: %s",
                                 why);
                        return -EPROTO;
                }
                r = c->tls && tls_pending(c->tls) ? 0 : wait_fd(c->fd, POLLIN, deadline, intr_fd);
                if (r >= 0)
                        r = read_some(c);
                if (r < 0)
                        return r;
        }
}

/* Fails on a response that does not answer request id (0 when none is outstanding). */
static int unexpected_reply(const struct proto_msg *m, json_int_t id, struct conn_error *err)
{
        _cleanup_free_ char *got = json_dumps(m->id, JSON_ENCODE_ANY);

        if (id > 0)
                snprintf(err->message, sizeof(err->message),
                         "bad message from server: reply with id %s to request "
                         "%" JSON_INTEGER_FORMAT,
                         got ? got : "?", id);
        else
                snprintf(err->message, sizeof(err->message),
                         "bad message from server: reply with id %s, no request outstanding",
                         got ? got : "?");
        return -EPROTO;
}

static void dispatch(const struct proto_msg *m, conn_notify_fn fn, void *userdata)
{
        if (fn && m->kind == PROTO_NOTIFICATION)
                fn(m->method, json_is_object(m->params) ? m->params : NULL, userdata);
}

/* Handles the reply to request id: 0 with *result, or -EREMOTEIO with *err. */
static int take_reply(const struct proto_msg *m, json_t **result, struct conn_error *err)
{
        if (m->result) {
                *result = json_incref(m->result);
                return 0;
        }
        err->code = (int)json_integer_value(json_object_get(m->error, "code"));
        snprintf(err->message, sizeof(err->message), "%s",
                 json_string_value(json_object_get(m->error, "message")));
        return -EREMOTEIO;
}

static int send_request(struct conn *c, const char *method, json_t *params, int64_t deadline)
{
        json_t *req = proto_request(c->next_id, method, params);
        _cleanup_free_ char *s = NULL;
        size_t n;

        if (!req)
                return -ENOMEM;
        s = proto_dump(req, &n);
        json_decref(req);
        if (!s)
                return -errno;
        return send_all(c, s, n, deadline);
}

/* True for the late reply to the request whose wait was abandoned (-EINTR, -ETIMEDOUT),
 * e.g. a move canceled by the stop sent after the interruption, until it came once. Any
 * other id is an error. */
static bool late_reply(const struct conn *c, const struct proto_msg *m)
{
        return c->abandoned_id > 0 && m->kind == PROTO_RESPONSE && json_is_integer(m->id) &&
               json_integer_value(m->id) == c->abandoned_id;
}

int conn_call(struct conn *c, const char *method, json_t *params, int64_t deadline, int intr_fd,
              conn_notify_fn fn, void *userdata, json_t **result, struct conn_error *err)
{
        json_int_t id = c->next_id;
        int r;

        *err = (struct conn_error){};
        r = send_request(c, method, params, deadline);
        c->next_id++;
        if (r < 0)
                return r;
        for (;;) {
                struct proto_msg m;
                bool answered;

                r = read_msg(c, deadline, intr_fd, &m, err);
                if (r == -EINTR || r == -ETIMEDOUT)
                        c->abandoned_id = id;
                if (r < 0)
                        return r;
                answered = proto_answers(&m, id);
                if (answered)
                        r = take_reply(&m, result, err);
                else if (late_reply(c, &m))
                        c->abandoned_id = 0; /* a second reply to it is an error */
                else if (m.kind == PROTO_RESPONSE)
                        r = unexpected_reply(&m, id, err);
                else
                        dispatch(&m, fn, userdata);
                json_decref(m.root);
                if (r < 0 || answered)
                        return r;
        }
}

int conn_wait_notification(struct conn *c, int64_t deadline, int intr_fd, conn_notify_fn fn,
                           void *userdata, struct conn_error *err)
{
        *err = (struct conn_error){};
        for (;;) {
                struct proto_msg m;
                int r = read_msg(c, deadline, intr_fd, &m, err);

                if (r < 0)
                        return r;
                if (m.kind == PROTO_RESPONSE)
                        r = unexpected_reply(&m, 0, err);
                else
                        dispatch(&m, fn, userdata);
                json_decref(m.root);
                if (r < 0 || m.kind == PROTO_NOTIFICATION)
                        return r < 0 ? r : 1;
        }
}
