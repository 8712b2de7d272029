/* proto.c - the wire protocol shared by goniod and its clients: line framing,
 * JSON-RPC 2.0 validation, message builders and the -errno <-> code table.
 * Pure code: no I/O, no global mutable state. docs/protocol.md is the spec. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>

#include "common/cleanup.h"
#include "protocol/proto.h"

/* Drops the bytes already handed out, so buf starts at unread data. */
static void lines_compact(struct proto_lines *pl)
{
        if (pl->start == 0)
                return;
        memmove(pl->buf, pl->buf + pl->start, pl->len - pl->start);
        pl->len -= pl->start;
        pl->start = 0;
}

static int lines_reserve(struct proto_lines *pl, size_t extra)
{
        size_t need = pl->len + extra + 1, cap;
        char *b;

        if (need <= pl->cap)
                return 0;
        cap = MAX(need, pl->cap * 2);
        cap = MAX(cap, (size_t)4096);
        b = realloc(pl->buf, cap);
        if (!b)
                return -ENOMEM;
        pl->buf = b;
        pl->cap = cap;
        return 0;
}

int proto_lines_feed(struct proto_lines *pl, const char *data, size_t n)
{
        lines_compact(pl);
        if (pl->discarding) {
                /* The over-long line was reported: drop the rest of it. */
                const char *nl = memchr(data, '\n', n);

                if (!nl)
                        return 0;
                pl->discarding = false;
                n -= (size_t)(nl + 1 - data);
                data = nl + 1;
        }
        if (n == 0)
                return 0;
        if (lines_reserve(pl, n) < 0)
                return -ENOMEM;
        memcpy(pl->buf + pl->len, data, n);
        pl->len += n;
        return 0;
}

int proto_lines_next(struct proto_lines *pl, char **line, size_t *len)
{
        for (;;) {
                size_t n;
                char *p, *nl;

                lines_compact(pl);
                p = pl->buf;
                nl = pl->len > 0 ? memchr(p, '\n', pl->len) : NULL;
                if (!nl) {
                        if (pl->len < PROTO_MAX_LINE)
                                return 0;
                        /* No room left for the '\n': report once, drop until the next '\n'. */
                        pl->len = 0;
                        pl->discarding = true;
                        return -EMSGSIZE;
                }
                n = (size_t)(nl - p);
                pl->start = n + 1;
                if (n + 1 > PROTO_MAX_LINE)
                        return -EMSGSIZE;
                *nl = '\0';
                if (n > 0 && p[n - 1] == '\r') /* tolerate CRLF from hand-written clients */
                        p[--n] = '\0';
                if (n == 0)
                        continue; /* empty lines are ignored */
                *line = p;
                *len = n;
                return 1;
        }
}

void proto_lines_done(struct proto_lines *pl)
{
        free(pl->buf);
        *pl = (struct proto_lines){};
}

static int parse_fail(int code, char *err, size_t errlen, const char *what)
{
        if (errlen > 0)
                snprintf(err, errlen, "%s", what);
        return code;
}

static bool id_valid(const json_t *id)
{
        return json_is_string(id) || json_is_integer(id) || json_is_null(id);
}

/* Validates the error member of a response: {code: integer, message: string, data?}. */
static bool error_valid(const json_t *e)
{
        return json_is_object(e) && json_is_integer(json_object_get(e, "code")) &&
               json_is_string(json_object_get(e, "message"));
}

/* Classifies an object already known to carry jsonrpc "2.0" and a valid or absent id. */
static int classify(struct proto_msg *msg, char *err, size_t errlen)
{
        json_t *root = msg->root, *method = json_object_get(root, "method");

        msg->id = json_object_get(root, "id");
        if (method) {
                if (!json_is_string(method))
                        return parse_fail(PROTO_INVALID_REQUEST, err, errlen,
                                          "method must be a string");
                msg->method = json_string_value(method);
                msg->params = json_object_get(root, "params");
                if (msg->params && !json_is_object(msg->params) && !json_is_array(msg->params))
                        return parse_fail(PROTO_INVALID_REQUEST, err, errlen,
                                          "params must be an object or an array");
                msg->kind = msg->id ? PROTO_REQUEST : PROTO_NOTIFICATION;
                return 0;
        }
        msg->result = json_object_get(root, "result");
        msg->error = json_object_get(root, "error");
        if (!msg->id)
                return parse_fail(PROTO_INVALID_REQUEST, err, errlen, "missing method or id");
        if (!msg->result == !msg->error)
                return parse_fail(PROTO_INVALID_REQUEST, err, errlen,
                                  "a response has exactly one of result and error");
        if (msg->error && !error_valid(msg->error))
                return parse_fail(PROTO_INVALID_REQUEST, err, errlen,
                                  "error must be an object with integer code and string message");
        msg->kind = PROTO_RESPONSE;
        return 0;
}

int proto_parse(const char *line, size_t len, struct proto_msg *msg, json_t **id_out, char *err,
                size_t errlen)
{
        json_error_t jerr;
        json_t *root, *id;
        int r;

        *msg = (struct proto_msg){};
        if (id_out)
                *id_out = NULL;
        root = json_loadb(line, len, JSON_REJECT_DUPLICATES | JSON_DECODE_ANY, &jerr);
        if (!root) {
                if (errlen > 0)
                        snprintf(err, errlen, "parse error at column %d: %s", jerr.column,
                                 jerr.text);
                return PROTO_PARSE_ERROR;
        }
        msg->root = root;
        if (json_is_array(root))
                r = parse_fail(PROTO_INVALID_REQUEST, err, errlen, "batches are not supported");
        else if (!json_is_object(root))
                r = parse_fail(PROTO_INVALID_REQUEST, err, errlen, "message must be an object");
        else if ((id = json_object_get(root, "id")) && !id_valid(id))
                r = parse_fail(PROTO_INVALID_REQUEST, err, errlen,
                               "id must be a string, an integer or null");
        else {
                if (id_out && id)
                        *id_out = json_incref(id);
                if (!json_is_string(json_object_get(root, "jsonrpc")) ||
                    strcmp(json_string_value(json_object_get(root, "jsonrpc")), "2.0") != 0)
                        r = parse_fail(PROTO_INVALID_REQUEST, err, errlen,
                                       "jsonrpc must be \"2.0\"");
                else
                        r = classify(msg, err, errlen);
        }
        if (r < 0) {
                json_decref(root);
                *msg = (struct proto_msg){};
        } else if (id_out) {
                json_decref(*id_out);
                *id_out = NULL;
        }
        return r;
}

bool proto_answers(const struct proto_msg *m, json_int_t id)
{
        const char *errname;
        int code;

        if (m->kind != PROTO_RESPONSE)
                return false;
        if (json_is_integer(m->id))
                return json_integer_value(m->id) == id;
        if (!json_is_null(m->id) || !m->error)
                return false;
        code = (int)json_integer_value(json_object_get(m->error, "code"));
        errname = json_string_value(json_object_get(json_object_get(m->error, "data"), "errno"));
        return code == PROTO_PARSE_ERROR || code == PROTO_INVALID_REQUEST ||
               code == PROTO_E_LINE_TOO_LONG ||
               (code == PROTO_E_BUSY && errname && strcmp(errname, "EUSERS") == 0);
}

/* {"jsonrpc":"2.0", "id": id} (id borrowed, NULL meaning JSON null), or NULL. */
static json_t *envelope(json_t *id)
{
        return json_pack("{s:s,s:O}", "jsonrpc", "2.0", "id", id ? id : json_null());
}

/* Sets key to a stolen value on m; on failure frees m and returns NULL. */
static json_t *set_stolen(json_t *m, const char *key, json_t *value)
{
        if (!m || !value || json_object_set_new(m, key, value) < 0) {
                json_decref(m);
                json_decref(value);
                return NULL;
        }
        return m;
}

/* Adds method and (stolen, optional) params to m; frees everything on failure. */
static json_t *call_message(json_t *m, const char *method, json_t *params)
{
        m = set_stolen(m, "method", json_string(method));
        if (!params)
                return m;
        if (!m) {
                json_decref(params);
                return NULL;
        }
        return set_stolen(m, "params", params);
}

json_t *proto_request(json_int_t id, const char *method, json_t *params)
{
        return call_message(json_pack("{s:s,s:I}", "jsonrpc", "2.0", "id", id), method, params);
}

json_t *proto_notification(const char *method, json_t *params)
{
        return call_message(json_pack("{s:s}", "jsonrpc", "2.0"), method, params);
}

json_t *proto_result(json_t *id, json_t *result)
{
        return set_stolen(envelope(id), "result", result ? result : json_object());
}

json_t *proto_error(json_t *id, int code, const char *message, json_t *data)
{
        json_t *e = json_pack("{s:i,s:s}", "code", code, "message", message ? message : "");

        if (e && data)
                e = set_stolen(e, "data", data);
        else
                json_decref(data);
        return set_stolen(envelope(id), "error", e);
}

char *proto_dump(const json_t *msg, size_t *len)
{
        char *s = json_dumps(msg, JSON_COMPACT), *t;
        size_t n;

        if (!s) {
                errno = ENOMEM;
                return NULL;
        }
        n = strlen(s);
        if (n + 1 > PROTO_MAX_LINE) {
                free(s);
                errno = EMSGSIZE;
                return NULL;
        }
        t = realloc(s, n + 2);
        if (!t) {
                free(s);
                errno = ENOMEM;
                return NULL;
        }
        s = t;
        s[n] = '\n';
        s[n + 1] = '\0';
        if (len)
                *len = n + 1;
        return s;
}

/* The one table. errno -> code takes the first row with that errno; code -> errno the
 * first row with that code, so rows that only serve the reverse direction come last. */
static const struct {
        int err;
        int code;
} errno_codes[] = {
        {EINVAL, PROTO_INVALID_PARAMS},
        {EOPNOTSUPP, PROTO_INVALID_PARAMS},
        {ENOSYS, PROTO_METHOD_NOT_FOUND},
        {EBUSY, PROTO_E_BUSY},
        {EAGAIN, PROTO_E_BUSY},
        {EUSERS, PROTO_E_BUSY}, /* too many clients (forward only) */
        {ERANGE, PROTO_E_RANGE},
        {EDOM, PROTO_E_RANGE},
        {EIO, PROTO_E_DEVICE},
        {EPROTO, PROTO_E_DEVICE},
        {ENODEV, PROTO_E_DEVICE},
        {ENXIO, PROTO_E_DEVICE},
        {ETIMEDOUT, PROTO_E_TIMEOUT},
        {ENOENT, PROTO_E_NOT_FOUND},
        {ENOSPC, PROTO_E_STORAGE},
        {EROFS, PROTO_E_STORAGE},
        {EDQUOT, PROTO_E_STORAGE},
        {EEXIST, PROTO_E_STORAGE},
        {EBADMSG, PROTO_E_STORAGE},
        {EACCES, PROTO_E_STORAGE},
        {ECANCELED, PROTO_E_CANCELED},
        {ESTALE, PROTO_E_STATE},
        {EPERM, PROTO_E_STATE},
        {EMSGSIZE, PROTO_E_LINE_TOO_LONG},
        /* Reverse only: protocol-level failures map to EPROTO (a bad exchange). */
        {EPROTO, PROTO_PARSE_ERROR},
        {EPROTO, PROTO_INVALID_REQUEST},
        {EPROTO, PROTO_INTERNAL_ERROR},
        /* Forward only (the code's reverse row is above): hello with an unknown version. */
        {EPROTONOSUPPORT, PROTO_INVALID_REQUEST},
};

int proto_errno_to_code(int err)
{
        err = abs(err);
        for (size_t i = 0; i < ELEMENTSOF(errno_codes); i++)
                if (errno_codes[i].err == err)
                        return errno_codes[i].code;
        return PROTO_INTERNAL_ERROR;
}

int proto_code_to_errno(int code)
{
        for (size_t i = 0; i < ELEMENTSOF(errno_codes); i++)
                if (errno_codes[i].code == code)
                        return errno_codes[i].err;
        return EPROTO;
}

json_t *proto_error_errno(json_t *id, int err, const char *message)
{
        const char *name = strerrorname_np(abs(err));
        json_t *data = json_pack("{s:s}", "errno", name ? name : "EUNKNOWN");

        if (!data)
                return NULL;
        return proto_error(id, proto_errno_to_code(err), message, data);
}

int proto_socket_path(char *buf, size_t size)
{
        const char *e = getenv("GONIO_SOCKET"), *rt = getenv("XDG_RUNTIME_DIR");
        int n;

        if (e && *e)
                n = snprintf(buf, size, "%s", e);
        else if (rt && *rt)
                n = snprintf(buf, size, "%s/gonio/goniod.sock", rt);
        else
                n = snprintf(buf, size, "/run/gonio/goniod.sock");
        if (n < 0 || (size_t)n >= size || (size_t)n >= sizeof(((struct sockaddr_un *)0)->sun_path))
                return -ENAMETOOLONG;
        return 0;
}

int proto_unix_socket(const char *path, struct sockaddr_un *sa)
{
        int fd;

        if (strlen(path) >= sizeof(sa->sun_path))
                return -ENAMETOOLONG;
        memset(sa, 0, sizeof(*sa));
        sa->sun_family = AF_UNIX;
        strcpy(sa->sun_path, path);
        fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
        return fd < 0 ? -errno : fd;
}
