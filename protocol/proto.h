/* proto.h - the wire protocol between gonioctl (or any client) and goniod:
 * JSON-RPC 2.0, one object per line, at most PROTO_MAX_LINE bytes per line,
 * over a Unix stream socket. docs/protocol.md is the specification.
 *
 * This module is shared by both sides: line framing, message classification,
 * builders for requests/results/errors/notifications, and the one table that
 * maps -errno to JSON-RPC error codes. */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#include <jansson.h>

struct sockaddr_un;

#define PROTO_VERSION  1
#define PROTO_MAX_LINE (64 * 1024)

/* JSON-RPC 2.0 standard codes, and gonio's application codes (-32000..-32099). */
enum proto_code {
        PROTO_PARSE_ERROR = -32700,
        PROTO_INVALID_REQUEST = -32600,
        PROTO_METHOD_NOT_FOUND = -32601,
        PROTO_INVALID_PARAMS = -32602,
        PROTO_INTERNAL_ERROR = -32603,
        PROTO_E_BUSY = -32001,      /* EBUSY, EAGAIN, EUSERS: busy, queue full, too many clients */
        PROTO_E_RANGE = -32002,     /* ERANGE: outside soft limits */
        PROTO_E_DEVICE = -32003,    /* EIO, EPROTO, ENODEV: device fault */
        PROTO_E_TIMEOUT = -32004,   /* ETIMEDOUT */
        PROTO_E_NOT_FOUND = -32005, /* ENOENT: no such axis/lamp/camera/dataset */
        PROTO_E_STORAGE = -32006,   /* ENOSPC, EROFS, EDQUOT */
        PROTO_E_CANCELED = -32007,  /* ECANCELED: stopped by stop/abort */
        PROTO_E_STATE = -32008,     /* ESTALE, EPERM: not homed, faulted, not allowed */
        PROTO_E_LINE_TOO_LONG = -32009,
};

/* Line framing for a stream socket. */
struct proto_lines {
        char *buf;
        size_t len, cap;
        bool discarding; /* inside an over-long line, dropping until '\n' */
        size_t start;    /* bytes at the front of buf already handed out by _next */
};

/* Appends received bytes (a zeroed struct is an empty framer). Memory stays bounded by
 * PROTO_MAX_LINE plus one feed as long as the caller drains with proto_lines_next after
 * each feed. Returns 0 or -ENOMEM. */
int proto_lines_feed(struct proto_lines *pl, const char *data, size_t n);

/* Pops the next complete line (without '\n' or a trailing '\r', NUL-terminated) into
 * *line, which stays valid until the next feed/next call; empty lines are skipped.
 * Returns 1 for a line, 0 when none is complete, -EMSGSIZE once for each line longer
 * than PROTO_MAX_LINE including its '\n' (which is dropped; framing then resumes). */
int proto_lines_next(struct proto_lines *pl, char **line, size_t *len);

/* Frees the buffer. */
void proto_lines_done(struct proto_lines *pl);

enum proto_kind { PROTO_REQUEST, PROTO_NOTIFICATION, PROTO_RESPONSE };

/* A parsed message; members are borrowed from msg->root. */
struct proto_msg {
        json_t *root;
        enum proto_kind kind;
        const char *method; /* request / notification */
        json_t *params;     /* object, array or NULL (absent) */
        json_t *id;         /* request / response; NULL for notification */
        json_t *result;     /* response */
        json_t *error;      /* response */
};

/* Parses and validates one line. On failure returns PROTO_PARSE_ERROR or
 * PROTO_INVALID_REQUEST with a message in err, and *id_out (if non-NULL) gets a new
 * reference to the id when one could be read (else NULL; always NULL on success).
 * Returns 0 on success; the caller then owns msg->root (json_decref it). */
int proto_parse(const char *line, size_t len, struct proto_msg *msg, json_t **id_out, char *err,
                size_t errlen);

/* Whether the response m answers the request sent with integer id: its id is that
 * integer, or it is one of the errors with "id": null that docs/protocol.md documents,
 * which a client with one request outstanding takes as that request's answer: the server
 * could not read a request's id (-32700 parse error, -32600 invalid request, -32009 line
 * too long), or it closes the connection because it has too many clients (-32001 with
 * data.errno "EUSERS"). A response with any other id (a string, null with a result or
 * with another error, another integer) does not answer it. */
bool proto_answers(const struct proto_msg *m, json_int_t id);

/* Builders; each returns a new reference (NULL on ENOMEM). params/result/data are stolen
 * (NULL params are omitted, a NULL result becomes {}); id is borrowed (NULL means null). */
json_t *proto_request(json_int_t id, const char *method, json_t *params);
json_t *proto_notification(const char *method, json_t *params);
json_t *proto_result(json_t *id, json_t *result);
json_t *proto_error(json_t *id, int code, const char *message, json_t *data);

/* Serialises msg compactly with a trailing '\n'. Returns a malloc'd string (free it) or
 * NULL with errno ENOMEM, or EMSGSIZE when the line would exceed PROTO_MAX_LINE. */
char *proto_dump(const json_t *msg, size_t *len);

/* The JSON-RPC code for a -errno or errno (the one table); PROTO_INTERNAL_ERROR for an
 * errno the table lacks. */
int proto_errno_to_code(int err);

/* The positive errno a client maps an error code back to (for exit codes); EPROTO for
 * codes the table lacks. */
int proto_code_to_errno(int code);

/* An error response for -errno err: code from the table, data {"errno": "ENOENT"}.
 * message is copied; id is borrowed. Returns a new reference or NULL (ENOMEM). */
json_t *proto_error_errno(json_t *id, int err, const char *message);

/* Writes the default socket path into buf: $GONIO_SOCKET, else
 * $XDG_RUNTIME_DIR/gonio/goniod.sock, else /run/gonio/goniod.sock.
 * Returns 0 or -ENAMETOOLONG (longer than size or than sun_path). */
int proto_socket_path(char *buf, size_t size);

/* Fills *sa for path and opens a non-blocking, close-on-exec Unix stream socket.
 * Returns the fd, -ENAMETOOLONG or -errno. */
int proto_unix_socket(const char *path, struct sockaddr_un *sa);
