/* server.h - the control server of goniod: JSON-RPC 2.0 over a Unix stream
 * socket, one object per line (protocol/proto.h, docs/protocol.md).
 *
 * Runs entirely on the daemon's sd-event loop. A method handler receives a
 * struct srv_req and answers it exactly once, at once or later (a move answers
 * when the axis is in position); meanwhile the server keeps serving every
 * client. Notifications are broadcast to all connected clients.
 *
 * The server remembers which clients said hello (a successful reply to the method
 * named "hello", whatever its handler), so that when the table is full it evicts
 * clients that never did before any that did.
 *
 * It listens on one or more sockets, each with a role: an operator socket serves every
 * method but the admin ones (struct srv_method.admin), an admin socket serves them all.
 * Sockets are bound by path (server_listen) or taken from systemd (server_listen_systemd). */
#pragma once

#include <jansson.h>
#include <stdbool.h>
#include <stdint.h>

typedef struct sd_event sd_event;

/* Clients served at once (fewer if RLIMIT_NOFILE cannot be raised to fit them). */
#define SRV_MAX_CLIENTS 256
/* A client that said hello and sent no request for this long may be evicted for a new one
 * when the table is full; below it, it is kept (e.g. one listening to notifications). */
#define SRV_IDLE_TIMEOUT_USEC (60 * 1000000ULL)
/* Listening sockets of one server. */
#define SRV_MAX_LISTENERS 4

/* What the connections accepted on a listening socket may call. */
enum srv_role {
        SRV_OPERATOR, /* every method but the admin ones, refused with -EPERM */
        SRV_ADMIN,    /* every method */
};

struct server;
struct srv_req;

/* Handles one request. Returns 0 when it took the request (and answers it with
 * srv_reply or srv_fail, now or later), or -errno to have the server answer with that
 * error (message from srv_req_errmsg, else strerror). params is an object (maybe empty). */
typedef int (*srv_method_fn)(struct srv_req *req, json_t *params, void *userdata);

struct srv_method {
        const char *name;
        srv_method_fn fn;
        bool admin; /* reconfigures the rig or overrides a fault: admin sockets only */
};

/* Creates a server of methods (a table ending in {NULL}) with userdata, listening nowhere
 * yet. Raises the soft RLIMIT_NOFILE to fit SRV_MAX_CLIENTS if needed. Returns 0 or -errno. */
int server_new(sd_event *event, const struct srv_method *methods, void *userdata,
               struct server **ret);

/* Listens on path for role (mode 0660 operator, 0600 admin; backlog SOMAXCONN), accepting once
 * server_start is called: connections wait in the backlog until then, so the socket can be
 * claimed before the devices are opened. Holds an flock on "<path>.lock" until server_free.
 * Refuses with -EADDRINUSE when something accepts connections on path or another process holds
 * the lock, with -EEXIST when path is not a socket (never removed); a stale socket is removed.
 * -ENOBUFS past SRV_MAX_LISTENERS. Returns 0 or -errno; failures are logged with the path. */
int server_listen(struct server *s, const char *path, enum srv_role role);

/* Listens on fd for role, as server_listen does; fd (taken, closed on failure) must be a
 * listening AF_UNIX stream socket (-ENOTSOCK otherwise) and is made non-blocking. Its path
 * is never unlinked (its owner, e.g. systemd, keeps it). Returns 0 or -errno (logged). */
int server_listen_fd(struct server *s, int fd, enum srv_role role);

/* Takes the sockets systemd passed (sd_listen_fds_with_names; LISTEN_* are unset), each by its
 * FileDescriptorName=: "operator" (or none, "unknown") or "admin". Returns how many (0: not
 * socket-activated), or -EINVAL for another name or when none is an operator socket, or -errno
 * of server_listen_fd (logged). Every passed descriptor is taken, also on failure. */
int server_listen_systemd(struct server *s);

/* Shortest and longest token of a TCP listener, in characters. */
#define SRV_TOKEN_MIN 16
#define SRV_TOKEN_MAX 127

struct tls_creds;

/* Listens on TCP at addr ("HOST:PORT", HOST numeric: "127.0.0.1", "[::1]", "0.0.0.0"...) for
 * operator connections that must say hello with params.token equal to token (SRV_TOKEN_MIN
 * to SRV_TOKEN_MAX characters) before anything else; three wrong tokens close the connection.
 * With tls (server credentials, borrowed: keep them while s lives; NULL: none) connections
 * speak TLS only (daemon/tls.h): a handshake not ended in TLS_HANDSHAKE_USEC is dropped, a
 * client without TLS is told so and closed. Without them addr must be a loopback address.
 * Returns 0, -EINVAL (a bad address, a short token), -EPERM (beyond loopback without TLS)
 * or -errno of bind/listen; every failure is logged with its cause. */
int server_listen_tcp(struct server *s, const char *addr, const char *token,
                      const struct tls_creds *tls);

/* 0 when token is SRV_TOKEN_MIN to SRV_TOKEN_MAX characters, else -EINVAL, logged for the
 * listener what at addr ("TCP listener", "HTTP listener"). */
int server_check_token(const char *token, const char *what, const char *addr);

/* A listening TCP socket (non-blocking, SO_REUSEADDR, backlog SOMAXCONN) on addr
 * ("HOST:PORT", HOST numeric, [::1] bracketed) for goniod's TCP listeners (this server's, the
 * dashboard's); what names it in the log ("TCP listener"). An address beyond loopback is
 * refused with the reason beyond ("goniod needs TLS ..."), taken when beyond is NULL. Returns
 * the fd, -EINVAL (a bad address), -EPERM (refused) or -errno of bind/listen, logged. */
int server_tcp_socket(const char *addr, const char *what, const char *beyond);

/* Whether a and b are the same string, in a time that does not tell where they differ
 * (tokens). */
bool server_same_secret(const char *a, const char *b);

/* Starts accepting connections. Returns 0 or -errno. */
int server_start(struct server *s);

/* Closes every connection and socket, unlinks each path server_listen bound if it is still
 * that socket, releases the locks. Pending requests get no answer. NULL is a no-op; returns
 * NULL. */
struct server *server_free(struct server *s);

/* Has fn(client, ud) called when the connection numbered client (srv_req_client) closes,
 * whoever closes it; not for the connections server_free closes. */
void server_on_close(struct server *s, void (*fn)(uint64_t client, void *ud), void *ud);

/* Overrides SRV_MAX_CLIENTS (at least 1, at most what RLIMIT_NOFILE allows) and
 * SRV_IDLE_TIMEOUT_USEC, e.g. for tests. */
void server_set_limits(struct server *s, unsigned max_clients, uint64_t idle_usec);

/* Sends notification method with params (stolen) to every client, but those of a TCP
 * listener that have not given its token yet (nor ended their TLS handshake). */
void server_broadcast(struct server *s, const char *method, json_t *params);

/* Number of connected clients. */
unsigned server_clients(const struct server *s);

/* Answers req with result (stolen) and frees req. Safe if the client has gone. */
void srv_reply(struct srv_req *req, json_t *result);

/* Answers req with the error for -errno err and a message, and frees req. */
void srv_fail(struct srv_req *req, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* Like srv_fail, with the keys of data (stolen) added to the error's data object. */
void srv_fail_data(struct srv_req *req, int err, json_t *data, const char *fmt, ...)
        __attribute__((format(printf, 4, 5)));

/* Sets the message used when the handler returns -errno. Returns err. */
int srv_req_errmsg(struct srv_req *req, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));

/* True while the client that sent req is connected. */
bool srv_req_connected(const struct srv_req *req);

/* The number of the connection req came on: unique over the server's life, never 0. */
uint64_t srv_req_client(const struct srv_req *req);

/* The method name of req; valid until answered. */
const char *srv_req_method(const struct srv_req *req);

/* Parameter readers: 0 when absent (out unchanged), 1 when read, or -EINVAL after setting
 * the request's error message ("param 'x': expected ..."). */
int srv_param_str(struct srv_req *req, json_t *params, const char *key, const char **out);
int srv_param_double(struct srv_req *req, json_t *params, const char *key, double *out);
int srv_param_int(struct srv_req *req, json_t *params, const char *key, long min, long max,
                  long *out);
int srv_param_bool(struct srv_req *req, json_t *params, const char *key, bool *out);
/* Fails with -EINVAL if params has a key not in the NULL-terminated list. */
int srv_params_check(struct srv_req *req, json_t *params, const char *const *allowed);
