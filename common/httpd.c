/* httpd.c - the static-file HTTP/1.1 server of httpd.h, on sd-event.
 *
 * DESIGN: each connection has one io source and one timer, and goes through three phases;
 * nothing blocks the loop:
 *   READ    the request (at most HTTPD_MAX_REQUEST bytes) is collected up to its blank line.
 *           The whole request must arrive within the idle time of the accept, however
 *           slowly it trickles in (slowloris); a late partial request gets 408.
 *   WRITE   the status line and headers, then the file, as far as the socket takes them:
 *           the file is pread into the server's one buffer and sent with MSG_NOSIGNAL (a
 *           client that resets the connection gives EPIPE, never SIGPIPE); what the socket
 *           refused is read again next time. The timer restarts on every byte sent, so a
 *           client that stops reading is closed after the idle time.
 *   LINGER  the response is out: shutdown(SHUT_WR), then what the client still sends is
 *           read and dropped until it closes (at most HTTPD_LINGER_USEC and
 *           HTTPD_LINGER_BYTES), so that unread request bytes (a POST body, an over-long
 *           line) do not make the kernel reset the connection before the client has read
 *           the answer.
 * Every response carries Connection: close; there is no keep-alive.
 *
 * HTTPS (httpd_set_tls): a connection runs its TLS handshake in READ before the request,
 * within the same deadline; reads and writes go through the caller's TLS functions, and
 * what the TLS layer decrypted ahead is read before waiting. LINGER and the watch of a
 * stream for its close read the raw socket: what comes is dropped anyway.
 *
 * Paths: percent-decoded, query and fragment dropped, NUL, backslash and ".." refused
 * (400); opened below root_fd with openat2(RESOLVE_BENEATH | RESOLVE_NO_MAGICLINKS), or,
 * where the kernel lacks openat2, one component at a time with O_NOFOLLOW (no symlink is
 * followed at all then). Only a regular file is served (a directory: its index.html);
 * anything else is 404. Files are opened O_NONBLOCK so that a fifo cannot block.
 *
 * Connections: at most HTTPD_MAX_CLIENTS. When the table is full a new connection evicts
 * a lingering one, else the oldest one still reading its request; when every connection
 * is sending a file the new one is closed. Evictions and refusals are counted and logged
 * at each power of two. Out of descriptors, accepting pauses for HTTPD_PAUSE_USEC. */
#include <arpa/inet.h>
#include <fcntl.h>
#include <linux/openat2.h>
#include <netinet/in.h>
#include <errno.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "cleanup.h"
#include "httpd.h"
#include "log.h"

#define HTTPD_LINGER_USEC  2000000u   /* after the response, wait this long for the close */
#define HTTPD_LINGER_BYTES (1u << 20) /* and drop at most this much of what the client sends */
#define HTTPD_PAUSE_USEC   100000u    /* accepting pauses this long when out of descriptors */
#define HTTPD_CHUNK        65536u     /* bytes per send() */
#define HTTPD_SENDS        16         /* send() calls per wake-up, for fairness */
#define HTTPD_ACCEPTS      256        /* accept() calls per wake-up */
#define HTTPD_HEAD_MAX     (512 + HTTPD_EXTRA_MAX) /* status line, headers, an error's body */
#define HTTPD_PATH_MAX     HTTPD_MAX_REQUEST

#define OPEN_FLAGS (O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK)

enum phase { PHASE_READ, PHASE_WRITE, PHASE_LINGER };

struct httpd_conn {
        struct httpd *h;
        int fd, file_fd;
        sd_event_source *io, *timer;
        struct tls_conn *tls; /* HTTPS: the connection's TLS, else NULL */
        bool secure;          /* its handshake has ended */
        enum phase phase;
        char head[HTTPD_HEAD_MAX];
        size_t head_len, head_off;
        uint64_t file_off, file_len;
        char *body; /* a handler's response body, or a stream's unsent data */
        size_t body_len, body_off, body_cap, max_pending;
        bool stream, head_only;
        void (*on_close)(struct httpd_conn *c, void *ud);
        void *close_ud;
        const char *headers; /* in req: the header lines after the request line */
        size_t lingered;
        struct httpd_conn *next; /* the list is newest first */
        size_t req_len;
        char req[HTTPD_MAX_REQUEST + 1]; /* NUL-terminated */
};

struct httpd {
        sd_event *event;
        int root_fd, fd;
        uint16_t port;
        sd_event_source *listen, *resume;
        struct httpd_conn *conns;
        unsigned n_conns, evicted, refused;
        uint64_t idle_usec;
        bool no_openat2; /* the kernel said ENOSYS once */
        httpd_handler_fn handler;
        void *handler_ud;
        const struct httpd_tls *tls; /* HTTPS only: its functions and credentials */
        const struct tls_creds *creds;
        char buf[HTTPD_CHUNK];
};

static const struct {
        int code;
        const char *reason;
} statuses[] = {
        {200, "OK"},
        {400, "Bad Request"},
        {303, "See Other"},
        {401, "Unauthorized"},
        {403, "Forbidden"},
        {404, "Not Found"},
        {405, "Method Not Allowed"},
        {408, "Request Timeout"},
        {414, "URI Too Long"},
        {431, "Request Header Fields Too Large"},
        {500, "Internal Server Error"},
        {503, "Service Unavailable"},
        {505, "HTTP Version Not Supported"},
};

static const struct {
        const char *ext;
        const char *type;
} types[] = {
        {".html", "text/html; charset=utf-8"},
        {".js", "text/javascript"},
        {".json", "application/json"},
        {".css", "text/css"},
        {".png", "image/png"},
        {".bin", "application/octet-stream"},
        {".gz", "application/octet-stream"},
};

static const char *status_reason(int code)
{
        for (size_t i = 0; i < ELEMENTSOF(statuses); i++)
                if (statuses[i].code == code)
                        return statuses[i].reason;
        return "Error";
}

static const char *content_type(const char *path)
{
        const char *base = strrchr(path, '/'), *dot;

        dot = strrchr(base ? base : path, '.');
        for (size_t i = 0; dot && i < ELEMENTSOF(types); i++)
                if (strcasecmp(dot, types[i].ext) == 0)
                        return types[i].type;
        return "application/octet-stream";
}

/* Logs the n-th eviction or refusal when n is a power of two: a flood stays quiet. */
static void log_dropped(const char *what, unsigned n)
{
        if ((n & (n - 1)) == 0)
                log_notice("httpd: %s a connection: %d connections at most (%u so far)", what,
                           HTTPD_MAX_CLIENTS, n);
}

static void conn_close(struct httpd_conn *c)
{
        struct httpd *h = c->h;

        for (struct httpd_conn **p = &h->conns; *p; p = &(*p)->next)
                if (*p == c) {
                        *p = c->next;
                        break;
                }
        h->n_conns--;
        if (c->on_close) {
                void (*fn)(struct httpd_conn *, void *) = c->on_close;
                c->on_close = NULL;
                fn(c, c->close_ud);
        }
        free(c->body);
        sd_event_source_disable_unref(c->io);
        sd_event_source_disable_unref(c->timer);
        if (c->tls)
                h->tls->conn_free(c->tls);
        closep(&c->file_fd);
        closep(&c->fd);
        free(c);
}

/* Reads up to len bytes from c, through TLS when it has it. Returns how many, 0 at the end,
 * or -errno (-EAGAIN: nothing yet). */
static ssize_t conn_recv(struct httpd_conn *c, void *buf, size_t len)
{
        ssize_t n;

        if (c->tls)
                return c->h->tls->read(c->tls, buf, len);
        n = recv(c->fd, buf, len, 0);
        return n >= 0 ? n : errno == EINTR ? -EAGAIN : -errno;
}

/* Sends up to len bytes to c, through TLS when it has it. Returns how many, or -errno
 * (-EAGAIN: the socket takes nothing now; with TLS, send the same bytes again). */
static ssize_t conn_send(struct httpd_conn *c, const void *buf, size_t len)
{
        ssize_t n;

        if (c->tls)
                return c->h->tls->write(c->tls, buf, len);
        n = send(c->fd, buf, len, MSG_NOSIGNAL | MSG_DONTWAIT);
        return n >= 0 ? n : errno == EINTR ? -EAGAIN : -errno;
}

/* (Re)starts c's timer: it fires usec from now, once. */
static int conn_arm(struct httpd_conn *c, uint64_t usec)
{
        int r = sd_event_source_set_time_relative(c->timer, usec);

        return r < 0 ? r : sd_event_source_set_enabled(c->timer, SD_EVENT_ONESHOT);
}

/* Sets c's response head: status, headers and, for an error, a short text body. A length of
 * UINT64_MAX (a stream) is not sent. */
static void set_head(struct httpd_conn *c, int code, const char *type, uint64_t length,
                     const char *extra, const char *body)
{
        char len_line[48] = "";
        int n;

        if (length != UINT64_MAX)
                snprintf(len_line, sizeof(len_line), "Content-Length: %llu\r\n",
                         (unsigned long long)length);
        n = snprintf(c->head, sizeof(c->head),
                     "HTTP/1.1 %d %s\r\n"
                     "Content-Type: %s\r\n"
                     "%s"
                     "Cache-Control: no-cache\r\n"
                     "X-Content-Type-Options: nosniff\r\n"
                     "Connection: close\r\n"
                     "%s\r\n%s",
                     code, status_reason(code), type, len_line, extra, body);

        c->head_len = MIN((size_t)MAX(n, 0), sizeof(c->head) - 1);
        c->head_off = 0;
}

/* Starts sending what set_head and c->file_* hold. Returns 0 or -errno. */
static int begin_write(struct httpd_conn *c)
{
        int r;

        c->phase = PHASE_WRITE;
        r = sd_event_source_set_io_events(c->io, EPOLLOUT);
        return r < 0 ? r : conn_arm(c, c->h->idle_usec);
}

/* Answers code with a text body (none for HEAD); 405 says what is allowed. */
static int respond_error(struct httpd_conn *c, int code, bool head_only)
{
        char body[64];

        snprintf(body, sizeof(body), "%d %s\n", code, status_reason(code));
        set_head(c, code, "text/plain; charset=utf-8", strlen(body),
                 code == 405 ? "Allow: GET, HEAD\r\n" : "", head_only ? "" : body);
        log_debug("httpd: answered %d", code);
        return begin_write(c);
}

static int hex_digit(char ch)
{
        if (ch >= '0' && ch <= '9')
                return ch - '0';
        if (ch >= 'a' && ch <= 'f')
                return ch - 'a' + 10;
        if (ch >= 'A' && ch <= 'F')
                return ch - 'A' + 10;
        return -1;
}

/* Percent-decodes target's path (up to '?' or '#') into out (size bytes). Returns 0, or
 * -EINVAL for a bad escape, a NUL or a backslash. */
static int decode_target(const char *target, char *out, size_t size)
{
        size_t n = 0;

        for (const char *p = target; *p && *p != '?' && *p != '#'; p++) {
                int ch = (unsigned char)*p;

                if (ch == '%') {
                        int hi = hex_digit(p[1]), lo = hi < 0 ? -1 : hex_digit(p[2]);
                        if (lo < 0)
                                return -EINVAL;
                        ch = hi * 16 + lo;
                        p += 2;
                }
                if (ch == 0 || ch == '\\' || n + 1 >= size)
                        return -EINVAL;
                out[n++] = (char)ch;
        }
        out[n] = 0;
        return 0;
}

/* Rewrites the decoded absolute path in place as a relative one without empty or "."
 * segments, "index.html" when it names a directory by a trailing slash. Returns 0, or
 * -EINVAL for a ".." segment or a path that does not start with '/'. */
static int normalize_path(char *path, size_t size)
{
        bool dir = true;
        size_t n = 0;

        if (path[0] != '/')
                return -EINVAL;
        for (char *seg = path, *end; *seg; seg = end) {
                size_t len;

                seg += strspn(seg, "/");
                end = seg + strcspn(seg, "/");
                len = end - seg;
                dir = len == 0 || (len == 1 && seg[0] == '.');
                if (dir)
                        continue;
                if (len == 2 && seg[0] == '.' && seg[1] == '.')
                        return -EINVAL;
                if (n > 0)
                        path[n++] = '/';
                memmove(path + n, seg, len);
                n += len;
        }
        path[n] = 0;
        if (dir && snprintf(path + n, size - n, "%sindex.html", n ? "/" : "") >= (int)(size - n))
                return -EINVAL;
        return 0;
}

/* Opens rel below dir_fd one component at a time, following no symlink. Returns the fd or
 * -errno (-ELOOP for a symlink, -ENOTDIR...). */
static int open_walk(int dir_fd, const char *rel)
{
        _cleanup_close_ int cur = -EBADF;

        for (const char *p = rel;;) {
                const char *slash = strchr(p, '/');
                size_t len = slash ? (size_t)(slash - p) : strlen(p);
                char name[NAME_MAX + 1];
                int fd;

                if (len == 0 || len > NAME_MAX)
                        return -ENOENT;
                memcpy(name, p, len);
                name[len] = 0;
                fd = openat(cur >= 0 ? cur : dir_fd, name,
                            (slash ? O_RDONLY | O_DIRECTORY | O_CLOEXEC : OPEN_FLAGS) | O_NOFOLLOW);
                if (fd < 0)
                        return -errno;
                closep(&cur);
                cur = fd;
                if (!slash)
                        return TAKE_FD(cur);
                p = slash + 1;
        }
}

/* Opens rel (relative, no "..") below dir_fd, never resolving outside it. Returns the fd
 * or -errno. */
static int open_beneath(struct httpd *h, int dir_fd, const char *rel)
{
        struct open_how how = {
                .flags = OPEN_FLAGS,
                .resolve = RESOLVE_BENEATH | RESOLVE_NO_MAGICLINKS,
        };

        if (!h->no_openat2) {
                int fd = (int)syscall(SYS_openat2, dir_fd, rel, &how, sizeof(how));

                if (fd >= 0 || errno != ENOSYS)
                        return fd >= 0 ? fd : -errno;
                log_info("httpd: the kernel has no openat2, opening files component-wise");
                h->no_openat2 = true;
        }
        return open_walk(dir_fd, rel);
}

/* Opens the regular file rel names (a directory: its index.html). Returns the fd with its
 * size in *size and its name's type in *type, or -ENOENT when it is not a regular file,
 * or -errno. */
static int open_file(struct httpd *h, const char *rel, uint64_t *size, const char **type)
{
        _cleanup_close_ int fd = open_beneath(h, h->root_fd, rel);
        struct stat st;

        *type = content_type(rel);
        if (fd >= 0 && fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
                int index = open_beneath(h, fd, "index.html");
                closep(&fd);
                fd = index;
                *type = content_type("index.html");
        }
        if (fd < 0)
                return fd;
        if (fstat(fd, &st) < 0)
                return -errno;
        if (!S_ISREG(st.st_mode))
                return -ENOENT;
        *size = st.st_size;
        return TAKE_FD(fd);
}

/* Hands the request to the handler. Returns 1 when it answered, 0 when it passed, or -errno
 * (answered 500). */
static int call_handler(struct httpd_conn *c, const char *path, const char *target)
{
        const char *q = strchr(target, '?');
        char query[HTTPD_PATH_MAX];
        int r;

        snprintf(query, sizeof(query), "%.*s", q ? (int)strcspn(q + 1, "#") : 0, q ? q + 1 : "");
        r = c->h->handler(c, c->head_only ? "HEAD" : "GET", path, query, c->h->handler_ud);
        if (r < 0) {
                log_debug("httpd: the handler failed on %s: %s", path, strerror(-r));
                r = respond_error(c, 500, c->head_only);
                return r < 0 ? r : 1;
        }
        return r;
}

/* Answers GET or HEAD of target. Returns 0 or -errno (c is to be closed). */
static int serve(struct httpd_conn *c, char *target, bool head_only)
{
        char path[HTTPD_PATH_MAX];
        const char *type;
        uint64_t size = 0;
        int fd;

        c->head_only = head_only;
        if (decode_target(target, path, sizeof(path)) < 0)
                return respond_error(c, 400, head_only);
        if (c->h->handler && (fd = call_handler(c, path, target)) != 0)
                return fd < 0 ? fd : 0;
        if (normalize_path(path, sizeof(path)) < 0)
                return respond_error(c, 400, head_only);
        if (c->h->root_fd < 0)
                return respond_error(c, 404, head_only);
        fd = open_file(c->h, path, &size, &type);
        log_debug("httpd: %s /%s: %s", head_only ? "HEAD" : "GET", path,
                  fd < 0 ? strerror(-fd) : "found");
        if (fd < 0)
                return respond_error(c, fd == -EMFILE || fd == -ENFILE ? 500 : 404, head_only);
        set_head(c, 200, type, size, "", "");
        c->file_fd = fd;
        c->file_len = head_only ? 0 : size;
        return begin_write(c);
}

/* Parses the request line in c->req (its headers are not looked at) and answers it. */
static int handle_request(struct httpd_conn *c)
{
        char *line = c->req, *target, *version;
        size_t mlen;

        c->headers = line + strcspn(line, "\r\n");
        c->headers += strspn(c->headers, "\r\n") > 0 ? (c->headers[0] == '\r' ? 2 : 1) : 0;
        line[strcspn(line, "\r\n")] = 0;
        target = strchr(line, ' ');
        version = target ? strchr(target + 1, ' ') : NULL;
        if (!version || strchr(version + 1, ' '))
                return respond_error(c, 400, false);
        *target++ = 0;
        *version++ = 0;
        mlen = strlen(line);
        if (mlen == 0 || mlen > 20 || strspn(line, "ABCDEFGHIJKLMNOPQRSTUVWXYZ") != mlen)
                return respond_error(c, 400, false);
        if (strcmp(version, "HTTP/1.1") != 0 && strcmp(version, "HTTP/1.0") != 0)
                return respond_error(c, strncmp(version, "HTTP/", 5) == 0 ? 505 : 400, false);
        if (strcmp(line, "GET") != 0 && strcmp(line, "HEAD") != 0)
                return respond_error(c, 405, false);
        return serve(c, target, strcmp(line, "HEAD") == 0);
}

/* Whether the request in c->req is complete: a blank line ends its headers. */
static bool request_complete(const struct httpd_conn *c, size_t from)
{
        const char *p = c->req + (from > 3 ? from - 3 : 0);

        return strstr(p, "\r\n\r\n") || strstr(p, "\n\n");
}

/* Goes on with c's TLS handshake. Returns 1 once it has ended, 0 while it goes on (a client
 * without TLS: answered 400 in plain text), or -errno (c is to be closed). */
static int conn_handshake(struct httpd_conn *c)
{
        static const char body[] = "400 this port takes HTTPS only\n";
        int r = c->h->tls->handshake(c->tls);

        if (r == -EAGAIN)
                return sd_event_source_set_io_events(
                        c->io, c->h->tls->wants_write(c->tls) ? EPOLLOUT : EPOLLIN);
        if (r == -EPROTONOSUPPORT) {
                c->tls = c->h->tls->conn_free(c->tls); /* nothing was read: plain from here */
                set_head(c, 400, "text/plain; charset=utf-8", strlen(body), "", body);
                return begin_write(c);
        }
        if (r < 0) {
                log_debug("httpd: TLS handshake failed: %s", strerror(-r));
                return r;
        }
        c->secure = true;
        r = sd_event_source_set_io_events(c->io, EPOLLIN);
        return r < 0 ? r : 1;
}

/* Reads request bytes (the TLS handshake first); answers the request once it is whole, or
 * an error. Returns 0 or -errno (c is to be closed). */
static int conn_read(struct httpd_conn *c)
{
        size_t old = c->req_len;
        ssize_t n;

        if (c->tls && !c->secure && (n = conn_handshake(c)) <= 0)
                return (int)n;
        n = conn_recv(c, c->req + old, HTTPD_MAX_REQUEST - old);
        if (n < 0)
                return n == -EAGAIN ? 0 : (int)n;
        if (n == 0) /* a partial request then EOF (the client may still read): 400 */
                return old > 0 ? respond_error(c, 400, false) : -ECONNRESET;
        c->req_len += n;
        c->req[c->req_len] = 0;
        if (memchr(c->req + old, 0, n))
                return respond_error(c, 400, false);
        if (request_complete(c, old))
                return handle_request(c);
        if (c->req_len == HTTPD_MAX_REQUEST)
                return respond_error(c, memchr(c->req, '\n', c->req_len) ? 431 : 414, false);
        return c->tls && c->h->tls->pending(c->tls) > 0 ? conn_read(c) : 0;
}

/* The response is out: half-close and wait for the client's close. Returns 0 or -errno. */
static int conn_linger(struct httpd_conn *c)
{
        int r;

        closep(&c->file_fd);
        c->file_fd = -EBADF;
        if (shutdown(c->fd, SHUT_WR) < 0)
                return -errno;
        c->phase = PHASE_LINGER;
        r = sd_event_source_set_io_events(c->io, EPOLLIN);
        return r < 0 ? r : conn_arm(c, MIN(c->h->idle_usec, HTTPD_LINGER_USEC));
}

/* The response's next bytes after the head into buf (room bytes): the file's or the body's.
 * Returns their number, 0 at the end, or -errno. */
static ssize_t next_bytes(struct httpd_conn *c, char *buf, size_t room)
{
        size_t n;

        if (c->file_off < c->file_len) {
                ssize_t r = pread(c->file_fd, buf, MIN(room, c->file_len - c->file_off),
                                  (off_t)c->file_off);
                /* 0: the file shrank, Content-Length cannot be kept */
                return r < 0 ? -errno : r == 0 ? -EIO : r;
        }
        n = MIN(room, c->body_len - c->body_off);
        if (n > 0) /* no body: c->body is NULL */
                memcpy(buf, c->body + c->body_off, n);
        return (ssize_t)n;
}

/* Everything queued is out: a response lingers, a stream waits for more (watching only for
 * the client's close, with no deadline). Returns 0 or -errno. */
static int conn_sent(struct httpd_conn *c)
{
        int r;

        if (!c->stream)
                return conn_linger(c);
        c->body_len = c->body_off = 0;
        r = sd_event_source_set_io_events(c->io, EPOLLIN);
        return r < 0 ? r : sd_event_source_set_enabled(c->timer, SD_EVENT_OFF);
}

/* Sends as much of the head and the file or body as the socket takes. Returns 0 or -errno. */
static int conn_write(struct httpd_conn *c)
{
        char *buf = c->h->buf;
        bool sent_some = false;

        for (int i = 0; i < HTTPD_SENDS; i++) {
                size_t head = c->head_len - c->head_off, len = head, data;
                ssize_t n;

                memcpy(buf, c->head + c->head_off, head);
                n = next_bytes(c, buf + head, HTTPD_CHUNK - head);
                if (n < 0)
                        return n;
                len += n;
                if (len == 0)
                        return conn_sent(c);
                n = conn_send(c, buf, len);
                if (n == -EAGAIN)
                        break;
                if (n < 0)
                        return (int)n;
                c->head_off += MIN((size_t)n, head);
                data = (size_t)n - MIN((size_t)n, head);
                if (c->file_off < c->file_len)
                        c->file_off += data;
                else
                        c->body_off += data;
                sent_some = true;
        }
        return sent_some ? conn_arm(c, c->h->idle_usec) : 0;
}

/* Reads and drops what a lingering client sends. Returns 0, or <0 when c is to close. */
static int conn_drain(struct httpd_conn *c)
{
        ssize_t n = recv(c->fd, c->h->buf, HTTPD_CHUNK, 0);

        if (n < 0)
                return errno == EAGAIN || errno == EINTR ? 0 : -errno;
        if (n == 0)
                return -ECONNRESET;
        c->lingered += n;
        return c->lingered > HTTPD_LINGER_BYTES ? -EMSGSIZE : 0;
}

static int on_conn_io(sd_event_source *es, int fd, uint32_t revents, void *userdata)
{
        struct httpd_conn *c = userdata;
        int r;

        if (c->phase == PHASE_READ)
                r = conn_read(c);
        else if (c->phase == PHASE_WRITE && c->stream) {
                r = revents & EPOLLOUT ? conn_write(c) : 0;
                if (r >= 0 && (revents & (EPOLLIN | EPOLLHUP | EPOLLERR)))
                        r = conn_drain(c); /* what a viewer sends is dropped; EOF closes */
        } else if (c->phase == PHASE_WRITE)
                r = conn_write(c);
        else
                r = conn_drain(c);
        if (r < 0)
                conn_close(c);
        return 0;
}

/* The idle time is over: a partial request gets 408 (best effort), then c closes. */
static int on_conn_timer(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct httpd_conn *c = userdata;

        if (c->phase == PHASE_READ && c->req_len > 0) {
                set_head(c, 408, "text/plain; charset=utf-8", 0, "", "");
                (void)conn_send(c, c->head, c->head_len);
        }
        log_debug("httpd: closing a connection idle for %llu ms",
                  (unsigned long long)c->h->idle_usec / 1000);
        conn_close(c);
        return 0;
}

/* The connection to close for a new one: a lingering one, else the oldest still reading
 * its request; NULL when all are sending files. */
static struct httpd_conn *pick_victim(struct httpd *h)
{
        struct httpd_conn *oldest_reader = NULL;

        for (struct httpd_conn *c = h->conns; c; c = c->next) {
                if (c->phase == PHASE_LINGER)
                        return c;
                if (c->phase == PHASE_READ)
                        oldest_reader = c; /* newest first: the last one seen is the oldest */
        }
        return oldest_reader;
}

/* Serves the new connection fd (taken), making room when the table is full. */
static void conn_add(struct httpd *h, int cfd)
{
        _cleanup_close_ int fd = cfd;
        struct httpd_conn *c, *victim;
        int r;

        if (h->n_conns >= HTTPD_MAX_CLIENTS) {
                victim = pick_victim(h);
                if (!victim) {
                        log_dropped("refused", ++h->refused);
                        return;
                }
                conn_close(victim);
                log_dropped("evicted", ++h->evicted);
        }
        c = calloc(1, sizeof(*c));
        if (!c)
                return;
        c->h = h;
        c->file_fd = -EBADF;
        c->fd = fd;
        r = h->creds ? h->tls->conn_new(h->creds, fd, NULL, &c->tls) : 0;
        if (r >= 0)
                r = sd_event_add_io(h->event, &c->io, fd, EPOLLIN, on_conn_io, c);
        if (r >= 0)
                r = sd_event_add_time_relative(h->event, &c->timer, CLOCK_MONOTONIC, h->idle_usec,
                                               0, on_conn_timer, c);
        if (r < 0) {
                sd_event_source_disable_unref(c->io);
                if (c->tls)
                        h->tls->conn_free(c->tls);
                free(c);
                log_warning_errno(r, "httpd: cannot watch a connection, ignoring: %m");
                return;
        }
        sd_event_source_set_description(c->io, "httpd-conn");
        sd_event_source_set_description(c->timer, "httpd-idle");
        TAKE_FD(fd);
        c->next = h->conns;
        h->conns = c;
        h->n_conns++;
}

/* Out of descriptors: stops accepting for HTTPD_PAUSE_USEC (the listener would stay
 * readable and spin the loop). */
static void pause_accept(struct httpd *h, int err)
{
        log_warning_errno(err, "httpd: accept() failed, pausing: %m");
        (void)sd_event_source_set_enabled(h->listen, SD_EVENT_OFF);
        (void)sd_event_source_set_time_relative(h->resume, HTTPD_PAUSE_USEC);
        (void)sd_event_source_set_enabled(h->resume, SD_EVENT_ONESHOT);
}

static int on_resume(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct httpd *h = userdata;

        return sd_event_source_set_enabled(h->listen, SD_EVENT_ON);
}

static int on_accept(sd_event_source *es, int fd, uint32_t revents, void *userdata)
{
        struct httpd *h = userdata;

        for (int i = 0; i < HTTPD_ACCEPTS; i++) {
                int cfd = accept4(fd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);

                if (cfd >= 0)
                        conn_add(h, cfd);
                else if (errno == EAGAIN)
                        break;
                else if (errno != EINTR && errno != ECONNABORTED) {
                        pause_accept(h, errno);
                        break;
                }
        }
        return 0;
}

/* Binds and listens on addr:port (SO_REUSEADDR). Returns the fd with the bound port in
 * *ret_port, -EINVAL for an address that is no IPv4 or IPv6 literal, or -errno. */
static int listen_on(const char *addr, uint16_t port, uint16_t *ret_port)
{
        union {
                struct sockaddr sa;
                struct sockaddr_in in;
                struct sockaddr_in6 in6;
        } u = {0};
        socklen_t len = sizeof(u.in);
        _cleanup_close_ int fd = -EBADF;
        int one = 1;

        if (inet_pton(AF_INET, addr, &u.in.sin_addr) == 1) {
                u.in.sin_family = AF_INET;
                u.in.sin_port = htons(port);
        } else if (inet_pton(AF_INET6, addr, &u.in6.sin6_addr) == 1) {
                u.in6.sin6_family = AF_INET6;
                u.in6.sin6_port = htons(port);
                len = sizeof(u.in6);
        } else
                return -EINVAL;
        fd = socket(u.sa.sa_family, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
        if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one)) < 0 ||
            bind(fd, &u.sa, len) < 0 || listen(fd, SOMAXCONN) < 0 ||
            getsockname(fd, &u.sa, &len) < 0)
                return -errno;
        *ret_port = ntohs(u.sa.sa_family == AF_INET ? u.in.sin_port : u.in6.sin6_port);
        return TAKE_FD(fd);
}

int httpd_new(sd_event *event, int root_fd, const char *addr, uint16_t port, struct httpd **ret)
{
        uint16_t bound = 0;
        int fd, r;

        if (!event || root_fd < 0 || !addr || !ret)
                return -EINVAL;
        fd = listen_on(addr, port, &bound);
        if (fd < 0)
                return fd;
        r = httpd_new_fd(event, root_fd, fd, ret);
        if (r >= 0)
                log_debug("httpd: serving on %s port %u", addr, bound);
        return r;
}

/* The port the listening socket fd is bound to (0 when it cannot tell). */
static uint16_t bound_port(int fd)
{
        struct sockaddr_storage ss;
        socklen_t len = sizeof(ss);

        if (getsockname(fd, (struct sockaddr *)&ss, &len) < 0)
                return 0;
        if (ss.ss_family == AF_INET)
                return ntohs(((struct sockaddr_in *)&ss)->sin_port);
        return ss.ss_family == AF_INET6 ? ntohs(((struct sockaddr_in6 *)&ss)->sin6_port) : 0;
}

int httpd_new_fd(sd_event *event, int root_fd, int listen_fd, struct httpd **ret)
{
        _cleanup_close_ int fd = listen_fd;
        struct httpd *h;
        int r, flags;

        if (!event || fd < 0 || !ret)
                return -EINVAL;
        if ((flags = fcntl(fd, F_GETFL)) < 0 || fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0)
                return -errno;
        h = calloc(1, sizeof(*h));
        if (!h)
                return -ENOMEM;
        h->event = event;
        h->root_fd = root_fd;
        h->idle_usec = HTTPD_IDLE_USEC;
        h->port = bound_port(fd);
        h->fd = TAKE_FD(fd);
        r = sd_event_add_io(event, &h->listen, h->fd, EPOLLIN, on_accept, h);
        if (r >= 0)
                r = sd_event_add_time_relative(event, &h->resume, CLOCK_MONOTONIC, HTTPD_PAUSE_USEC,
                                               0, on_resume, h);
        if (r >= 0)
                r = sd_event_source_set_enabled(h->resume, SD_EVENT_OFF);
        if (r < 0) {
                httpd_free(h);
                return r;
        }
        sd_event_source_set_description(h->listen, "httpd-listen");
        sd_event_source_set_description(h->resume, "httpd-resume");
        *ret = h;
        return 0;
}

void httpd_set_tls(struct httpd *h, const struct httpd_tls *fns, const struct tls_creds *creds)
{
        h->tls = fns;
        h->creds = creds;
}

void httpd_set_handler(struct httpd *h, httpd_handler_fn fn, void *ud)
{
        h->handler = fn;
        h->handler_ud = ud;
}

const char *httpd_header(const struct httpd_conn *c, const char *name, char *buf, size_t len)
{
        size_t nlen = strlen(name);

        for (const char *p = c->headers; p && *p; p += strcspn(p, "\n"), p += *p == '\n') {
                const char *v = p + nlen;
                if (strncasecmp(p, name, nlen) != 0 || *v != ':')
                        continue;
                v += 1 + strspn(v + 1, " \t");
                snprintf(buf, len, "%.*s", (int)strcspn(v, "\r\n"), v);
                return buf;
        }
        return NULL;
}

int httpd_query_param(const char *query, const char *name, char *buf, size_t len)
{
        size_t nlen = strlen(name);
        char raw[HTTPD_PATH_MAX];

        for (const char *p = query; *p; p += strcspn(p, "&"), p += *p == '&') {
                if (strncmp(p, name, nlen) != 0 || p[nlen] != '=')
                        continue;
                snprintf(raw, sizeof(raw), "/%.*s", (int)strcspn(p + nlen + 1, "&"), p + nlen + 1);
                for (char *s = raw; (s = strchr(s, '+'));)
                        *s = ' ';
                if (decode_target(raw, raw, sizeof(raw)) < 0 || strlen(raw + 1) >= len)
                        return -EINVAL;
                memcpy(buf, raw + 1, strlen(raw + 1) + 1);
                return 1;
        }
        return 0;
}

/* Makes room for len more bytes of body in c (compacting what was sent). 0 or -ENOMEM. */
static int body_reserve(struct httpd_conn *c, size_t len)
{
        char *p;

        if (c->body_off > 0) {
                memmove(c->body, c->body + c->body_off, c->body_len - c->body_off);
                c->body_len -= c->body_off;
                c->body_off = 0;
        }
        if (c->body_len + len <= c->body_cap)
                return 0;
        p = realloc(c->body, c->body_len + len);
        if (!p)
                return -ENOMEM;
        c->body = p;
        c->body_cap = c->body_len + len;
        return 0;
}

int httpd_respond(struct httpd_conn *c, int code, const char *type, const char *extra,
                  const void *body, size_t len)
{
        if (strlen(extra) > HTTPD_EXTRA_MAX)
                return -E2BIG;
        if (!c->head_only && len > 0) {
                if (body_reserve(c, len) < 0)
                        return -ENOMEM;
                memcpy(c->body, body, len);
                c->body_len = len;
        }
        set_head(c, code, type, len, extra, "");
        log_debug("httpd: answered %d (%zu bytes)", code, len);
        return begin_write(c);
}

int httpd_stream(struct httpd_conn *c, const char *type, const char *extra, size_t max_pending,
                 void (*on_close)(struct httpd_conn *c, void *ud), void *ud)
{
        int r = httpd_respond(c, 200, type, extra, NULL, 0);

        if (r < 0)
                return r;
        set_head(c, 200, type, UINT64_MAX, extra, ""); /* no length: until the close */
        c->stream = !c->head_only;
        c->max_pending = max_pending;
        c->on_close = c->stream ? on_close : NULL;
        c->close_ud = ud;
        return sd_event_source_set_io_events(c->io, EPOLLOUT | (c->stream ? EPOLLIN : 0));
}

int httpd_stream_send(struct httpd_conn *c, const void *data, size_t len)
{
        size_t pending = httpd_stream_pending(c);
        int r;

        if (!c->stream || c->phase != PHASE_WRITE)
                return -ENOTCONN;
        if (pending + len > c->max_pending)
                return -ENOBUFS;
        r = body_reserve(c, len);
        if (r >= 0) {
                memcpy(c->body + c->body_len, data, len);
                c->body_len += len;
                if (pending == 0 && c->head_off == c->head_len)
                        r = conn_arm(c, c->h->idle_usec); /* from the first unsent byte */
        }
        if (r >= 0)
                r = sd_event_source_set_io_events(c->io, EPOLLIN | EPOLLOUT);
        if (r >= 0)
                r = conn_write(c);
        if (r < 0)
                conn_close(c);
        return r;
}

size_t httpd_stream_pending(const struct httpd_conn *c)
{
        return c->body_len - c->body_off;
}

uint16_t httpd_port(const struct httpd *h)
{
        return h->port;
}

void httpd_set_idle(struct httpd *h, uint64_t usec)
{
        h->idle_usec = usec > 0 ? usec : HTTPD_IDLE_USEC;
}

struct httpd *httpd_free(struct httpd *h)
{
        if (!h)
                return NULL;
        while (h->conns)
                conn_close(h->conns);
        sd_event_source_disable_unref(h->listen);
        sd_event_source_disable_unref(h->resume);
        closep(&h->fd);
        free(h);
        return NULL;
}
