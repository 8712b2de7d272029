/* test-httpd.c - common/httpd against curl (a client we did not write) and raw sockets.
 * The server runs in a forked child on its own sd_event, on 127.0.0.1 port 0, over a
 * temporary folder, with SIGPIPE at its default (a write to a reset connection would kill
 * it). Cases:
 *   get           index.html via /, nested files, a 3 MiB file byte-exact, HEAD, types
 *   confine       "..", %2e%2e, backslashes, NUL, symlinks out, a fifo, a directory without
 *                 index.html: 400 or 404, never the content
 *   confine-walk  the same with openat2 made ENOSYS (seccomp): the component-wise walk
 *   rude          100 idle connections, a slow request, a client that never reads and one
 *                 that resets mid-file: curl is still served at once; the limit holds;
 *                 the idle timeout (1 s here) closes them
 *   bad           an over-long request line and header, a request cut short, POST,
 *                 garbage: 4xx (505 for HTTP/2.0), the server keeps serving
 *   bind          bad arguments and addresses, a port in use, IPv6 on ::1
 *   stream        a handler's routes (daemon/web.c's way): an answer from memory with its
 *                 headers, a query parameter decoded, a stream that a reading client gets
 *                 whole; a stream whose client never reads has its unsent data bounded
 *                 (sends refused with -ENOBUFS) and is closed after the idle time (1 s),
 *                 its close callback run; files are still served beside the handler
 *
 * Usage: test-httpd CASE (one meson test per case; $CURL names curl, 77 without it). */
#include <arpa/inet.h>
#include <fcntl.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>

#include "common/cleanup.h"
#include "common/httpd.h"
#include "tests/test.h"

#define BIG_SIZE (3u << 20)
#define N_IDLE   100

static const char index_html[] = "<!doctype html><title>gonio</title><p>INDEX-PAGE</p>\n";
static const char nested_js[] = "export const nested = 'NESTED-JS';\n";
static const char secret[] = "SECRET-OUTSIDE-THE-ROOT\n";

static struct {
        const char *addr, *host; /* what the server binds, what curl's URL names */
        char tmp[64];            /* holds root/ and secret.txt */
        char root[96];
        pid_t pid;
        uint16_t port;
        bool handler; /* the "stream" case's handler answers first */
} T;

static uint64_t now_usec(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return (uint64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

static void cleanup(void)
{
        char cmd[128];

        kill_own_child(T.pid);
        if (T.tmp[0]) {
                snprintf(cmd, sizeof(cmd), "rm -rf '%s'", T.tmp);
                (void)system(cmd);
        }
}

static void write_file(const char *rel, const void *data, size_t len)
{
        char path[256];
        FILE *f;

        snprintf(path, sizeof(path), "%s/%s", T.root, rel);
        f = fopen(path, "w");
        CHECK(f);
        CHECK_INT(fwrite(data, 1, len, f), len);
        CHECK_INT(fclose(f), 0);
}

/* Fills buf with bytes from a fixed LCG: every value, NULs, CRs and LFs included. */
static void fill_noise(uint8_t *buf, size_t len, uint32_t seed)
{
        for (size_t i = 0; i < len; i++) {
                seed = seed * 1664525u + 1013904223u;
                buf[i] = seed >> 24;
        }
}

static uint8_t *big_content(void)
{
        uint8_t *big = malloc(BIG_SIZE);

        CHECK(big);
        fill_noise(big, BIG_SIZE, 42);
        return big;
}

static void make_link(const char *target, const char *rel)
{
        char path[256];

        snprintf(path, sizeof(path), "%s/%s", T.root, rel);
        CHECK_INT(symlink(target, path), 0);
}

static void make_dir_or_fifo(const char *rel, bool fifo)
{
        char path[256];

        snprintf(path, sizeof(path), "%s/%s", T.root, rel);
        CHECK_INT(fifo ? mkfifo(path, 0644) : mkdir(path, 0755), 0);
}

/* The served folder, and next to it a secret that must never be served. */
static void make_tree(void)
{
        _cleanup_free_ uint8_t *big = big_content();
        char abs[256];

        snprintf(T.tmp, sizeof(T.tmp), "/tmp/test-httpd-XXXXXX");
        CHECK(mkdtemp(T.tmp));
        snprintf(T.root, sizeof(T.root), "%s/root", T.tmp);
        CHECK_INT(mkdir(T.root, 0755), 0);
        write_file("../secret.txt", secret, strlen(secret));
        write_file("index.html", index_html, strlen(index_html));
        make_dir_or_fifo("sub", false);
        make_dir_or_fifo("withindex", false);
        make_dir_or_fifo("noindex", false);
        make_dir_or_fifo("fifodir", false);
        write_file("sub/nested.js", nested_js, strlen(nested_js));
        write_file("withindex/index.html", "WITHINDEX\n", 10);
        write_file("noindex/other.html", "OTHER\n", 6);
        write_file("data.json", "{}\n", 3);
        write_file("style.css", "p{}\n", 4);
        write_file("img.png", "\x89PNG\r\n\x1a\n", 8);
        write_file("a b.txt", "SPACE\n", 6);
        write_file("big.bin", big, BIG_SIZE);
        make_dir_or_fifo("fifo.html", true);
        make_dir_or_fifo("fifodir/index.html", true);
        snprintf(abs, sizeof(abs), "%s/secret.txt", T.tmp);
        make_link("../secret.txt", "out.txt");
        make_link(abs, "abs.txt");
        make_link("..", "outdir");
        make_link("/etc/passwd", "passwd");
        make_link("/proc/self/root/etc/passwd", "magic");
        make_link("index.html", "inlink.html");
}

/* Makes openat2 fail with ENOSYS in this process, as on a kernel before 5.6. */
static void forbid_openat2(void)
{
        struct sock_filter f[] = {
                BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(struct seccomp_data, nr)),
                BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, SYS_openat2, 0, 1),
                BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | ENOSYS),
                BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
        };
        struct sock_fprog prog = {.len = ELEMENTSOF(f), .filter = f};

        CHECK_INT(prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0), 0);
        CHECK_INT(prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &prog), 0);
}

/* The streams of the "stream" case's handler (in the child) and what it counted. */
#define STREAM_CHUNK   65536
#define STREAM_PENDING (4 * STREAM_CHUNK)
static struct {
        struct httpd_conn *conns[8];
        unsigned opened, closed;
        unsigned long sent, refused;
        sd_event_source *feed;
} S;

static void stream_closed(struct httpd_conn *c, void *ud)
{
        for (size_t i = 0; i < ELEMENTSOF(S.conns); i++)
                if (S.conns[i] == c)
                        S.conns[i] = NULL;
        S.closed++;
}

/* Every 2 ms a chunk to each stream; refusals counted. */
static int on_feed(sd_event_source *es, uint64_t usec, void *ud)
{
        static char chunk[STREAM_CHUNK];

        memset(chunk, 'x', sizeof(chunk));
        for (size_t i = 0; i < ELEMENTSOF(S.conns); i++) {
                int r = S.conns[i] ? httpd_stream_send(S.conns[i], chunk, sizeof(chunk)) : 0;
                S.sent += r == 0 && S.conns[i];
                S.refused += r == -ENOBUFS;
        }
        return sd_event_source_set_time_relative(es, 2000);
}

static int handle(struct httpd_conn *c, const char *method, const char *path, const char *query,
                  void *ud)
{
        char buf[256], v[64];
        size_t i;

        if (strcmp(path, "/mem") == 0) {
                if (httpd_query_param(query, "v", v, sizeof(v)) <= 0)
                        snprintf(v, sizeof(v), "none");
                snprintf(buf, sizeof(buf), "MEMORY %s %s", method, v);
                return httpd_respond(c, 200, "text/plain", "X-Test: yes\r\n", buf, strlen(buf))
                               ?: 1;
        }
        if (strcmp(path, "/count") == 0) {
                snprintf(buf, sizeof(buf), "opened=%u closed=%u refused=%lu", S.opened, S.closed,
                         S.refused);
                return httpd_respond(c, 200, "text/plain", "", buf, strlen(buf)) ?: 1;
        }
        if (strcmp(path, "/stream") != 0)
                return 0;
        for (i = 0; i < ELEMENTSOF(S.conns) && S.conns[i]; i++)
                ;
        CHECK(i < ELEMENTSOF(S.conns));
        CHECK_INT(httpd_stream(c, "application/octet-stream", "", STREAM_PENDING, stream_closed,
                               NULL),
                  0);
        S.conns[i] = strcmp(method, "HEAD") ? c : NULL;
        S.opened++;
        return 1;
}

/* The child: serves T.root until killed, port written to fd. */
static _Noreturn void serve(int fd, bool walk, uint64_t idle_usec)
{
        sd_event *event = NULL;
        struct httpd *h = NULL;
        int root_fd;
        uint16_t port;

        CHECK_INT(prctl(PR_SET_PDEATHSIG, SIGKILL), 0);
        signal(SIGPIPE, SIG_DFL);
        if (walk)
                forbid_openat2();
        root_fd = open(T.root, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        CHECK(root_fd >= 0);
        CHECK_INT(sd_event_new(&event), 0);
        CHECK_INT(httpd_new(event, root_fd, T.addr, 0, &h), 0);
        httpd_set_idle(h, idle_usec);
        if (T.handler) {
                httpd_set_handler(h, handle, NULL);
                CHECK(sd_event_add_time_relative(event, &S.feed, CLOCK_MONOTONIC, 2000, 1000,
                                                 on_feed, NULL) >= 0);
                CHECK(sd_event_source_set_enabled(S.feed, SD_EVENT_ON) >= 0);
        }
        port = httpd_port(h);
        CHECK(port > 0);
        CHECK_INT(write(fd, &port, sizeof(port)), sizeof(port));
        close(fd);
        CHECK_INT(sd_event_loop(event), 0);
        _exit(1);
}

/* Builds the tree and starts the server (walk: without openat2); skips without curl. */
static void start(bool walk, uint64_t idle_usec)
{
        int p[2];

        if (!getenv("CURL") || access(getenv("CURL"), X_OK) < 0) {
                fprintf(stderr, "no curl ($CURL), skipping\n");
                exit(TEST_SKIP);
        }
        atexit(cleanup);
        if (!T.addr) {
                T.addr = "127.0.0.1";
                T.host = T.addr;
        }
        make_tree();
        CHECK_INT(pipe(p), 0);
        T.pid = fork();
        CHECK(T.pid >= 0);
        if (T.pid == 0)
                serve(p[1], walk, idle_usec);
        close(p[1]);
        CHECK_INT(read(p[0], &T.port, sizeof(T.port)), sizeof(T.port));
        close(p[0]);
}

/* The server has not died (of SIGPIPE or anything else). */
static void check_alive(void)
{
        CHECK_INT(waitpid(T.pid, NULL, WNOHANG), 0);
}

/* Runs curl -sS on http://HOST:PORT<path> with extra options before the URL, its
 * stdout into out (NUL-terminated). Returns curl's exit code. */
static int curl(const char *extra, const char *path, char *out, size_t len)
{
        char cmd[1024];
        size_t n;
        FILE *p;

        snprintf(cmd, sizeof(cmd), "'%s' -sS -g --path-as-is --max-time 5 %s 'http://%s:%u%s'",
                 getenv("CURL"), extra, T.host, T.port, path);
        p = popen(cmd, "r");
        CHECK(p);
        n = fread(out, 1, len - 1, p);
        out[n] = 0;
        return WEXITSTATUS(pclose(p));
}

/* curl's status code and content type for GET path, as "200 text/html...". */
static void check_status(const char *path, const char *expected)
{
        char out[256];

        CHECK_INT(curl("-o /dev/null -w '%{http_code} %{content_type}'", path, out, sizeof(out)),
                  0);
        fprintf(stderr, "GET %s -> %s\n", path, out);
        CHECK_STR(out, expected);
}

static void check_body(const char *path, const char *expected)
{
        char out[4096];

        CHECK_INT(curl("", path, out, sizeof(out)), 0);
        CHECK_STR(out, expected);
}

static int raw_connect(int rcvbuf)
{
        struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons(T.port)};
        int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);

        CHECK(fd >= 0);
        if (rcvbuf > 0)
                CHECK_INT(setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof(rcvbuf)), 0);
        sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        CHECK_INT(connect(fd, (struct sockaddr *)&sa, sizeof(sa)), 0);
        return fd;
}

static void send_all(int fd, const void *buf, size_t len)
{
        CHECK_INT(send(fd, buf, len, MSG_NOSIGNAL), len);
}

/* Reads from fd until EOF, at most timeout_ms; into buf (NUL-terminated) as far as it
 * fits. Returns the bytes read in all, or -1 when the time ran out or the connection was
 * reset (the server must not close with request bytes unread: see httpd.c's LINGER). */
static long read_to_end(int fd, char *buf, size_t len, int timeout_ms)
{
        uint64_t end = now_usec() + timeout_ms * 1000ull;
        size_t kept = 0;
        long total = 0;

        for (;;) {
                struct pollfd pfd = {.fd = fd, .events = POLLIN};
                char chunk[65536];
                uint64_t t = now_usec();
                ssize_t n;

                if (t >= end || poll(&pfd, 1, (int)((end - t) / 1000) + 1) <= 0)
                        return -1;
                n = recv(fd, chunk, sizeof(chunk), MSG_DONTWAIT);
                if (n < 0 && errno == EAGAIN)
                        continue;
                if (n < 0) /* a reset: the answer may be lost on a real network */
                        return -1;
                if (n == 0)
                        break;
                memcpy(buf + kept, chunk, MIN((size_t)n, len - 1 - kept));
                kept += MIN((size_t)n, len - 1 - kept);
                total += n;
        }
        buf[kept] = 0;
        return total;
}

/* Sends req (len bytes) on a new connection, half-closes it when asked, reads the answer
 * into resp. Returns its status code (-1 when there is none). */
static int exchange(const void *req, size_t len, bool half_close, char *resp, size_t resp_len)
{
        int fd = raw_connect(0), code = -1;

        send_all(fd, req, len);
        if (half_close)
                CHECK_INT(shutdown(fd, SHUT_WR), 0);
        CHECK(read_to_end(fd, resp, resp_len, 3000) >= 0);
        close(fd);
        if (sscanf(resp, "HTTP/1.1 %d ", &code) != 1)
                code = -1;
        fprintf(stderr, "%.*s... -> %d\n", (int)MIN(len, 60), (const char *)req, code);
        return code;
}

/* GET target in a raw request (curl would clean up the path). Returns the status. */
static int get_raw(const char *target, char *resp, size_t resp_len)
{
        char req[1024];

        snprintf(req, sizeof(req), "GET %s HTTP/1.1\r\nHost: localhost\r\n\r\n", target);
        return exchange(req, strlen(req), false, resp, resp_len);
}

static void test_get(void)
{
        _cleanup_free_ uint8_t *big = big_content();
        _cleanup_free_ char *got = malloc(BIG_SIZE + 1);
        char out[4096], path[256];
        FILE *f;

        start(false, 0);
        check_body("/", index_html);
        check_body("/index.html?v=3#top", index_html);
        check_body("/sub/nested.js", nested_js);
        check_body("//sub/./nested.js", nested_js);
        check_body("/withindex/", "WITHINDEX\n");
        check_body("/withindex", "WITHINDEX\n");
        check_body("/a%20b.txt", "SPACE\n");
        check_status("/", "200 text/html; charset=utf-8");
        check_status("/sub/nested.js", "200 text/javascript");
        check_status("/data.json", "200 application/json");
        check_status("/style.css", "200 text/css");
        check_status("/img.png", "200 image/png");
        check_status("/big.bin", "200 application/octet-stream");
        check_status("/a%20b.txt", "200 application/octet-stream");
        /* the 3 MiB file byte-exact, over HTTP/1.1 and 1.0 */
        for (int v = 0; v < 2; v++) {
                snprintf(path, sizeof(path), "%s -o '%s/got.bin'", v ? "-0" : "", T.tmp);
                CHECK_INT(curl(path, "/big.bin", out, sizeof(out)), 0);
                snprintf(path, sizeof(path), "%s/got.bin", T.tmp);
                f = fopen(path, "r");
                CHECK(f && got);
                CHECK_INT(fread(got, 1, BIG_SIZE + 1, f), BIG_SIZE);
                fclose(f);
                CHECK(memcmp(got, big, BIG_SIZE) == 0);
        }
        /* HEAD: the length and headers, no body */
        CHECK_INT(curl("-I", "/big.bin", out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "HTTP/1.1 200 OK\r\n");
        CHECK_STR_CONTAINS(out, "Content-Length: 3145728\r\n");
        CHECK_STR_CONTAINS(out, "Cache-Control: no-cache\r\n");
        CHECK_STR_CONTAINS(out, "X-Content-Type-Options: nosniff\r\n");
        CHECK_STR_CONTAINS(out, "Connection: close\r\n");
        static const char head[] = "HEAD /big.bin HTTP/1.0\r\n\r\n";
        CHECK_INT(exchange(head, strlen(head), false, out, sizeof(out)), 200);
        CHECK(strstr(out, "\r\n\r\n") && strstr(out, "\r\n\r\n")[4] == 0);
        check_alive();
}

/* 400 or 404 for each path that leads outside the root or to no regular file; the
 * content of what is outside never shows. */
static void check_confined(void)
{
        static const char *const paths[] = {
                "/../secret.txt",
                "/%2e%2e/secret.txt",
                "/%2E%2E%2Fsecret.txt",
                "/sub/../../secret.txt",
                "/sub/%2e%2e/%2e%2e/secret.txt",
                "/..%5csecret.txt",
                "/\\..\\secret.txt",
                "/..%c0%afsecret.txt",
                "/../../../../../../etc/passwd",
                "/out.txt",
                "/abs.txt",
                "/outdir/secret.txt",
                "/outdir/root/index.html",
                "/passwd",
                "/magic",
                "/fifo.html",
                "/fifodir/",
                "/fifodir",
                "/noindex/",
                "/noindex",
                "/sub/nested.js/",
                "/index.html%00.png",
                "/%00",
                "/nothing.html",
                "/%zz",
                "index.html",
                "http://localhost/index.html",
                "*",
        };
        char resp[8192];

        for (size_t i = 0; i < ELEMENTSOF(paths); i++) {
                int code = get_raw(paths[i], resp, sizeof(resp));

                CHECK(code == 400 || code == 404);
                CHECK(!strstr(resp, "SECRET") && !strstr(resp, "root:"));
        }
        check_status("/../secret.txt", "400 text/plain; charset=utf-8");
        check_status("/%2e%2e/secret.txt", "400 text/plain; charset=utf-8");
        check_status("/fifo.html", "404 text/plain; charset=utf-8");
        check_body("/", index_html); /* the fifo did not block the server */
        check_alive();
}

static void test_confine(void)
{
        start(false, 0);
        check_confined();
        check_status("/inlink.html", "200 text/html; charset=utf-8"); /* a link inside */
}

/* Without openat2 no symlink is followed, not even one that stays inside. */
static void test_confine_walk(void)
{
        start(true, 0);
        check_confined();
        check_status("/inlink.html", "404 text/plain; charset=utf-8");
        check_body("/sub/nested.js", nested_js);
        check_body("/withindex/", "WITHINDEX\n");
}

/* Whether the server has closed fd (EOF or reset; unread data is dropped). */
static bool is_closed(int fd)
{
        char buf[4096];
        ssize_t n;

        while ((n = recv(fd, buf, sizeof(buf), MSG_DONTWAIT)) > 0)
                ;
        return n == 0 || (n < 0 && errno != EAGAIN);
}

/* How many of fds[0..n) are closed by the server, waiting up to timeout_ms for at
 * least want of them. */
static int count_closed(const int *fds, int n, int want, int timeout_ms)
{
        uint64_t end = now_usec() + timeout_ms * 1000ull;
        int closed;

        for (;;) {
                closed = 0;
                for (int i = 0; i < n; i++)
                        closed += is_closed(fds[i]);
                if (closed >= want || now_usec() >= end)
                        return closed;
                usleep(20000);
        }
}

/* Requests the big file, reads a little of it and resets the connection: the server's
 * next send fails with EPIPE, which without MSG_NOSIGNAL raises SIGPIPE. */
static void reset_mid_file(void)
{
        static const char req[] = "GET /big.bin HTTP/1.1\r\n\r\n";
        struct linger lg = {.l_onoff = 1, .l_linger = 0};
        char buf[65536];
        int fd = raw_connect(0);

        send_all(fd, req, strlen(req));
        CHECK_INT(shutdown(fd, SHUT_WR), 0); /* the server's socket: CLOSE_WAIT, then EPIPE */
        CHECK(recv(fd, buf, sizeof(buf), MSG_WAITALL) > 0);
        CHECK_INT(setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof(lg)), 0);
        close(fd);
}

static void test_rude(void)
{
        static const char slow[] = "GET /index.html HTTP/1.1\r\nHost: localhost\r\n\r\n";
        static const char big[] = "GET /big.bin HTTP/1.1\r\n\r\n";
        int idle[N_IDLE], fresh[HTTPD_MAX_CLIENTS], slowfd, stuck;
        int evicted = N_IDLE - HTTPD_MAX_CLIENTS;
        uint64_t t0, took, t_stuck;
        char resp[8192];

        start(false, 1000000);
        for (int i = 0; i < N_IDLE; i++)
                idle[i] = raw_connect(0);
        /* beyond the limit the oldest idle connections are closed, the newest stay */
        CHECK_INT(count_closed(idle, N_IDLE, evicted, 500), evicted);
        CHECK_INT(count_closed(idle, evicted, evicted, 0), evicted);
        slowfd = raw_connect(0);
        send_all(slowfd, slow, 5);
        stuck = raw_connect(4096);
        send_all(stuck, big, strlen(big));
        t_stuck = now_usec();
        reset_mid_file();
        send_all(slowfd, slow + 5, 5);
        t0 = now_usec();
        check_body("/", index_html);
        took = now_usec() - t0;
        fprintf(stderr, "curl served in %llu ms\n", (unsigned long long)took / 1000);
        CHECK(took < 800000);
        send_all(slowfd, slow + 10, 1);
        /* the idle time (1 s) closes every idle connection and the slow request, with 408 */
        CHECK_INT(count_closed(idle, N_IDLE, N_IDLE, 2500), N_IDLE);
        CHECK(read_to_end(slowfd, resp, sizeof(resp), 1000) > 0);
        CHECK_STR_CONTAINS(resp, "HTTP/1.1 408 Request Timeout\r\n");
        /* and the client that stopped reading mid-file (the server's table tells: a
         * connection sending a file is never evicted, so 64 new ones fit only without it) */
        while (now_usec() < t_stuck + 1500000) /* its idle time, the timer's slack (0.25 s) */
                usleep(20000);
        for (int i = 0; i < HTTPD_MAX_CLIENTS; i++)
                fresh[i] = raw_connect(0);
        CHECK_INT(count_closed(fresh, HTTPD_MAX_CLIENTS, 1, 300), 0);
        for (int i = 0; i < HTTPD_MAX_CLIENTS; i++)
                close(fresh[i]);
        check_body("/", index_html);
        check_alive();
        for (int i = 0; i < N_IDLE; i++)
                close(idle[i]);
        close(slowfd);
        close(stuck);
}

/* Sends a text request; checks the status it gets. */
static void check_raw(const char *req, bool half_close, int expected)
{
        char resp[8192];

        CHECK_INT(exchange(req, strlen(req), half_close, resp, sizeof(resp)), expected);
        if (expected == 405)
                CHECK_STR_CONTAINS(resp, "Allow: GET, HEAD\r\n");
}

static void test_bad(void)
{
        _cleanup_free_ char *req = malloc(32768);
        uint8_t noise[4096];
        char resp[8192];
        int n;

        CHECK(req);
        start(false, 0);
        /* a 20 KB request line, then 20 KB of headers */
        n = snprintf(req, 32768, "GET /%020000d HTTP/1.1\r\n\r\n", 0);
        CHECK_INT(exchange(req, n, false, resp, sizeof(resp)), 414);
        n = snprintf(req, 32768, "GET / HTTP/1.1\r\n");
        while (n < 20000)
                n += snprintf(req + n, 32768 - n, "X-Filler-%d: %0100d\r\n", n, 0);
        n += snprintf(req + n, 32768 - n, "\r\n");
        CHECK_INT(exchange(req, n, false, resp, sizeof(resp)), 431);
        /* a request cut short: no blank line, then the client half-closes */
        check_raw("GET / HTTP/1.1\r\nHost: localhost", true, 400);
        check_raw("GET / HTTP/1.1\r\nHost: localhost\r\n", true, 400);
        /* methods other than GET and HEAD, a body unread */
        check_raw("POST /index.html HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello", false, 405);
        check_raw("DELETE /index.html HTTP/1.1\r\n\r\n", false, 405);
        check_raw("OPTIONS * HTTP/1.1\r\n\r\n", false, 405);
        CHECK_INT(curl("-o /dev/null -w '%{http_code}' -d x=1", "/index.html", resp, sizeof(resp)),
                  0);
        CHECK_STR(resp, "405");
        /* malformed request lines */
        check_raw("get / HTTP/1.1\r\n\r\n", false, 400);
        check_raw("GET / HTTP/2.0\r\n\r\n", false, 505);
        check_raw("GET / FOO\r\n\r\n", false, 400);
        check_raw("GET /\r\n\r\n", false, 400);
        check_raw("GET  / HTTP/1.1\r\n\r\n", false, 400);
        check_raw("GET / HTTP/1.1 extra\r\n\r\n", false, 400);
        check_raw("\r\n\r\n", false, 400);
        /* binary garbage, cut short and with a blank line */
        for (uint32_t seed = 1; seed <= 3; seed++) {
                fill_noise(noise, sizeof(noise), seed);
                n = exchange(noise, sizeof(noise), true, resp, sizeof(resp));
                CHECK(n >= 400 && n < 500);
                memcpy(noise + sizeof(noise) - 4, "\r\n\r\n", 4);
                n = exchange(noise, sizeof(noise), true, resp, sizeof(resp));
                CHECK(n >= 400 && n < 500);
        }
        check_body("/", index_html);
        check_alive();
}

/* Arguments and addresses: -EINVAL, -EADDRINUSE; IPv6 served when the host has ::1. */
static void test_bind(void)
{
        struct httpd *h = NULL, *h2 = NULL;
        sd_event *event = NULL;
        int r;

        CHECK_INT(sd_event_new(&event), 0);
        CHECK_INT(httpd_new(event, AT_FDCWD, "127.0.0.1", 0, &h), -EINVAL);
        CHECK_INT(httpd_new(NULL, 0, "127.0.0.1", 0, &h), -EINVAL);
        CHECK_INT(httpd_new(event, 0, "localhost", 0, &h), -EINVAL);
        CHECK_INT(httpd_new(event, 0, "127.0.0.1:80", 0, &h), -EINVAL);
        CHECK_INT(httpd_new(event, 0, "127.0.0.1", 0, &h), 0);
        CHECK_INT(httpd_new(event, 0, "127.0.0.1", httpd_port(h), &h2), -EADDRINUSE);
        CHECK(!httpd_free(h) && !httpd_free(NULL));
        r = httpd_new(event, 0, "::1", 0, &h);
        httpd_free(h);
        sd_event_unref(event);
        if (r == -EADDRNOTAVAIL || r == -EAFNOSUPPORT) {
                fprintf(stderr, "no ::1 here (%s), IPv6 not tried\n", strerror(-r));
                return;
        }
        CHECK_INT(r, 0);
        T.addr = "::1";
        T.host = "[::1]";
        start(false, 0);
        check_body("/", index_html);
        check_status("/sub/nested.js", "200 text/javascript");
}

/* Reads a stream's bytes from fd for ms; returns how many. */
static long read_for(int fd, int ms)
{
        uint64_t end = now_usec() + ms * 1000ull;
        char buf[65536];
        long total = 0;

        while (now_usec() < end) {
                struct pollfd p = {.fd = fd, .events = POLLIN};
                ssize_t n = poll(&p, 1, 20) > 0 ? recv(fd, buf, sizeof(buf), MSG_DONTWAIT) : 0;
                if (n > 0)
                        total += n;
                else if (n == 0 && p.revents)
                        break;
        }
        return total;
}

static void test_stream(void)
{
        static const char req[] = "GET /stream HTTP/1.1\r\nHost: localhost\r\n\r\n";
        char out[4096];
        int reader, stuck;
        long got;

        T.handler = true;
        start(false, 1000000);
        check_body("/mem?x=1&v=a%20b+c", "MEMORY GET a b c");
        check_status("/mem", "200 text/plain");
        CHECK_INT(curl("-sI", "/mem", out, sizeof(out)), 0);
        CHECK_STR_CONTAINS(out, "X-Test: yes\r\n"); /* HEAD: the headers alone */
        check_body("/sub/nested.js", nested_js);    /* files beside the handler */
        reader = raw_connect(0);
        send_all(reader, req, strlen(req));
        stuck = raw_connect(4096);
        send_all(stuck, req, strlen(req));
        got = read_for(reader, 500);
        fprintf(stderr, "a reading client got %ld bytes in 0.5 s\n", got);
        CHECK(got > 20 * STREAM_CHUNK);
        /* the client that never reads (never drained here: that would be progress) is
         * bounded, then closed at the idle time; the reader keeps reading meanwhile */
        for (uint64_t end = now_usec() + 3000000; now_usec() < end;) {
                got += read_for(reader, 100);
                CHECK_INT(curl("", "/count", out, sizeof(out)), 0);
                if (strstr(out, "closed=1 "))
                        break;
        }
        fprintf(stderr, "%s\n", out);
        CHECK_STR_CONTAINS(out, "opened=2 closed=1 refused=");
        CHECK(strtoul(strstr(out, "refused=") + 8, NULL, 10) > 10);
        CHECK(!is_closed(reader));
        CHECK_INT(count_closed(&stuck, 1, 1, 2000), 1);
        close(reader);
        close(stuck);
        check_alive();
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"get", test_get},
                {"confine", test_confine},
                {"confine-walk", test_confine_walk},
                {"rude", test_rude},
                {"bad", test_bad},
                {"bind", test_bind},
                {"stream", test_stream},
        };

        return TEST_RUN_CASES(cases, argc, argv);
}
