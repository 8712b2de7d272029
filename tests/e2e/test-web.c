/* test-web.c - goniod's dashboard (docs/goniod.md, "Dashboard") over raw HTTP on gonio-sim,
 * one case per run:
 *   serve  an address beyond loopback stops goniod at its start with the reason; without
 *          credentials 401, a wrong token 403; /?token=T answers 303 with an HttpOnly,
 *          SameSite=Strict cookie that then opens every route; /api/status is what
 *          `gonioctl status` prints (storage aside), /api/session what session.status
 *          answers; /events starts with a status event; one part of /preview/CAM.mjpg
 *          decodes as a JPEG of the camera's size downscaled to at most 320 pixels wide
 *          (a 720x480 camera: 240x160; a 16-bit one too); an unknown camera 404; while
 *          pictures come from peeks of the idle rig, no move, switch or capture is refused; the
 *          bash
 *          completion (argument 5: daemon/goniod.bash) offers --listen-http
 *   rude   a request that never ends (slowloris) gets 408 and is closed at the deadline;
 *          huge headers 431; POST and DELETE 405; unknown paths 401 before 404; path
 *          traversal never serves a file; 70 idle connections do not lock a client out
 *          (the oldest are dropped); HEAD of a picture stream opens none; the 17th picture
 *          stream gets 503
 *   tls    with --tls-cert/--tls-key (tests/tls-certs.sh, argument 5): GET /api/status over
 *          TLS with the token answers the status (the sign-in's cookie is Secure), while a
 * handshake that stalls does not hold it up and is dropped at the deadline; a client trusting
 * another CA fails its handshake; plain HTTP gets a plain-text 400 and no page netns  in a network
 * namespace of its own (skipped, 77, where none can be made) with 10.77.0.1 on lo: that address
 * without TLS stops goniod at its start, with TLS it serves the status over HTTPS */
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <jpeglib.h> /* after stdio.h */

#include "daemon/tls.h"
#include "daemon/web.h"
#include "harness.h"
#include "tests/test.h"

#define TOKEN  "a-dashboard-token-of-some-length"
#define BEARER "Authorization: Bearer " TOKEN "\r\n"

static int port;
static char cookie[200]; /* "Cookie: gonio_session=...\r\n" once signed in */

static void http_env(void *ud)
{
        char addr[64];

        snprintf(addr, sizeof(addr), "%s:%d", (const char *)ud, port);
        setenv("GONIO_LISTEN_HTTP", addr, 1);
        setenv("GONIO_HTTP_TIMEOUT_MS", "400", 1);
}

/* Reads fd into buf (len bytes, NUL-terminated) until needle is there (NULL: end of file)
 * or timeout s. Returns the bytes read. */
static size_t read_until(int fd, char *buf, size_t len, const char *needle, double timeout)
{
        size_t n = 0;

        buf[0] = 0;
        for (double end = now_s() + timeout; now_s() < end && n + 1 < len;) {
                struct pollfd p = {.fd = fd, .events = POLLIN};
                ssize_t r;
                if (poll(&p, 1, 50) <= 0)
                        continue;
                r = recv(fd, buf + n, len - 1 - n, 0);
                if (r <= 0)
                        break;
                n += r;
                buf[n] = 0;
                if (needle && memmem(buf, n, needle, strlen(needle)))
                        break;
        }
        return n;
}

/* Sends request text on a new connection and reads the whole answer into buf. Returns its
 * status code. */
static int http(const char *request, char *buf, size_t len)
{
        int fd = tcp_connect("127.0.0.1", port), code = 0;

        CHECK(send(fd, request, strlen(request), MSG_NOSIGNAL) == (ssize_t)strlen(request));
        read_until(fd, buf, len, NULL, 5);
        close(fd);
        CHECK(sscanf(buf, "HTTP/1.1 %d", &code) == 1);
        return code;
}

/* GET path with the header lines extra; the answer in buf. Returns its status code. */
static int get(const char *path, const char *extra, char *buf, size_t len)
{
        char req[1024];

        snprintf(req, sizeof(req), "GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\n%s\r\n", path, extra);
        return http(req, buf, len);
}

/* The body of an answer in buf. */
static const char *body_of(const char *buf)
{
        const char *p = strstr(buf, "\r\n\r\n");

        CHECK(p);
        return p + 4;
}

/* goniod with the dashboard on host: exits 1 at its start, its log saying why. */
static void start_refused(struct rigenv *e, const char *host, const char *why)
{
        char cmd[700];
        int status;

        rigenv_spawn_daemon(e, e->sock, http_env, (void *)host);
        CHECK(waitpid(e->daemon, &status, 0) == e->daemon);
        e->daemon = 0;
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 1);
        snprintf(cmd, sizeof(cmd), "grep -q '%s' %s/goniod.log", why, e->dir);
        CHECK(system(cmd) == 0);
}

/* The sign-in: the cookie of /?token=T. */
static void sign_in(void)
{
        char buf[4096];
        const char *set;

        CHECK_INT(get("/?token=" TOKEN, "", buf, sizeof(buf)), 303);
        CHECK_STR_CONTAINS(buf, "\r\nLocation: /\r\n");
        CHECK((set = strstr(buf, "Set-Cookie: gonio_session=")));
        CHECK_STR_CONTAINS(set, "; HttpOnly; SameSite=Strict\r\n");
        snprintf(cookie, sizeof(cookie), "Cookie: theme=dark; %.*s\r\n",
                 (int)strcspn(set + 12, ";"), set + 12);
}

/* /api/status against `gonioctl status`, the free space aside. */
static void check_status(struct rigenv *e)
{
        static char buf[65536];
        json_t *web, *ctl = ctl_ok(e, "status", NULL);

        CHECK_INT(get("/api/status", cookie, buf, sizeof(buf)), 200);
        CHECK_STR_CONTAINS(buf, "Content-Type: application/json");
        CHECK((web = json_loads(body_of(buf), 0, NULL)));
        json_object_del(web, "storage");
        json_object_del(ctl, "storage");
        if (!json_equal(web, ctl)) {
                print_json("web", web);
                print_json("gonioctl", ctl);
        }
        CHECK(json_equal(web, ctl));
        json_decref(web);
        json_decref(ctl);
        CHECK_INT(get("/api/session", cookie, buf, sizeof(buf)), 200);
        CHECK_STR_CONTAINS(body_of(buf), "\"state\":\"none\"");
}

/* Decodes jpeg (len bytes): its size into w and h. */
static void decode(const unsigned char *jpeg, size_t len, int *w, int *h)
{
        struct jpeg_decompress_struct d;
        struct jpeg_error_mgr err;

        d.err = jpeg_std_error(&err);
        jpeg_create_decompress(&d);
        jpeg_mem_src(&d, jpeg, len);
        CHECK(jpeg_read_header(&d, TRUE) == JPEG_HEADER_OK);
        CHECK(jpeg_start_decompress(&d));
        unsigned char *row = malloc((size_t)d.output_width * d.output_components);
        while (d.output_scanline < d.output_height)
                CHECK(jpeg_read_scanlines(&d, &row, 1) == 1);
        free(row);
        *w = d.output_width;
        *h = d.output_height;
        jpeg_finish_decompress(&d);
        jpeg_destroy_decompress(&d);
}

/* One picture of camera cam from its stream: a JPEG of w x h. */
static void check_picture(const char *cam, int w, int h)
{
        static char buf[1 << 20];
        char req[512];
        int fd = tcp_connect("127.0.0.1", port), len = 0, got_w, got_h;
        const char *part, *jpeg;
        size_t n;

        snprintf(req, sizeof(req), "GET /preview/%s.mjpg HTTP/1.1\r\n%s\r\n", cam, cookie);
        CHECK(send(fd, req, strlen(req), MSG_NOSIGNAL) > 0);
        n = read_until(fd, buf, sizeof(buf), "\r\n--gonioframe", 5); /* one whole part */
        close(fd);
        CHECK_STR_CONTAINS(buf, "Content-Type: multipart/x-mixed-replace; boundary=gonioframe");
        CHECK((part = strstr(buf, "--gonioframe\r\nContent-Type: image/jpeg\r\n")));
        CHECK(sscanf(strstr(part, "Content-Length: "), "Content-Length: %d", &len) == 1);
        CHECK((jpeg = strstr(part, "\r\n\r\n")));
        jpeg += 4;
        CHECK(len > 100 && jpeg + len <= buf + n);
        decode((const unsigned char *)jpeg, len, &got_w, &got_h);
        fprintf(stderr, "%s: a %dx%d JPEG of %d bytes\n", cam, got_w, got_h, len);
        CHECK_INT(got_w, w);
        CHECK_INT(got_h, h);
}

/* goniod's bash completion (daemon/goniod.bash) offers its HTTP options, from its --help. */
static void check_completion(struct rigenv *e, const char *completion)
{
        const char *slash = strrchr(e->goniod, '/');
        char cmd[2048], out[256] = "";
        FILE *p;

        CHECK(slash && completion);
        snprintf(cmd, sizeof(cmd),
                 "PATH='%.*s':\"$PATH\" bash -c 'source %s; COMP_WORDS=(goniod --listen-h);"
                 " COMP_CWORD=1; _goniod; echo \"${COMPREPLY[*]}\"'",
                 (int)(slash - e->goniod), e->goniod, completion);
        CHECK((p = popen(cmd, "r")));
        CHECK(fgets(out, sizeof(out), p));
        CHECK_INT(pclose(p), 0);
        CHECK_STR(out, "--listen-http\n");
}

/* One request on the control connection fd, which must succeed (never refused busy). */
static void control_ok(int fd, const char *method, const char *params)
{
        char req[512];
        json_t *r;

        snprintf(req, sizeof(req),
                 "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"%s\",\"params\":%s}\n", method,
                 params);
        r = raw_call(fd, req);
        if (!json_object_get(r, "result"))
                print_json(method, r);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
}

/* While the pictures of an idle rig are watched (from peeks), moves, switching and captures
 * are never refused: a peek holds nothing. The pictures keep coming meanwhile. */
static void check_peeks_hold_nothing(struct rigenv *e)
{
        static char buf[1 << 18];
        char req[512], params[128];
        int fds[3], ctl = raw_connect(e), parts = 0;
        const char *cams[] = {"cam0", "cam1", "cam2"}, *p = buf;
        size_t n;

        for (int i = 0; i < 3; i++) {
                fds[i] = tcp_connect("127.0.0.1", port);
                snprintf(req, sizeof(req), "GET /preview/%s.mjpg HTTP/1.1\r\n%s\r\n", cams[i],
                         cookie);
                CHECK(send(fds[i], req, strlen(req), MSG_NOSIGNAL) > 0);
        }
        control_ok(ctl, "home", "{}");
        control_ok(ctl, "dataset.open", "{\"name\":\"webpeek\",\"create\":true}");
        for (int i = 0; i < 5; i++) {
                snprintf(params, sizeof(params), "{\"axis\":\"turntable\",\"position\":%d}",
                         10 * i);
                control_ok(ctl, "move", params);
                control_ok(ctl, "lamp.set",
                           i % 2 ? "{\"lamp\":0,\"on\":true}" : "{\"lamp\":0,\"on\":false}");
                control_ok(ctl, "capture", "{}");
        }
        close(ctl);
        n = read_until(fds[0], buf, sizeof(buf), NULL, 0.2);
        for (int i = 0; i < 3; i++)
                close(fds[i]);
        while ((p = memmem(p, buf + n - p, "--gonioframe\r\n", 14)))
                parts++, p++;
        fprintf(stderr, "%d pictures of cam0 while moving, switching and capturing\n", parts);
        CHECK(parts >= 2);
}

static void case_serve(struct rigenv *e, const char *completion)
{
        static char buf[65536];
        int fd;

        start_refused(e, "0.0.0.0", "not a loopback address");
        rigenv_spawn_daemon(e, e->sock, http_env, "127.0.0.1");
        CHECK_INT(get("/api/status", "", buf, sizeof(buf)), 401);
        CHECK_STR_CONTAINS(buf, "WWW-Authenticate: Bearer");
        CHECK_INT(get("/", "", buf, sizeof(buf)), 401);
        CHECK_INT(get("/api/status", "Authorization: Bearer not-the-token-at-all\r\n", buf,
                      sizeof(buf)),
                  403);
        CHECK_INT(get("/?token=not-the-token-at-all", "", buf, sizeof(buf)), 403);
        CHECK_INT(get("/api/status", "Cookie: gonio_session=0123\r\n", buf, sizeof(buf)), 403);
        CHECK_INT(get("/api/status", BEARER, buf, sizeof(buf)), 200);
        sign_in();
        CHECK_INT(get("/", cookie, buf, sizeof(buf)), 200);
        CHECK_STR_CONTAINS(buf, "<title>goniod</title>");
        CHECK_INT(get("/dashboard.js", cookie, buf, sizeof(buf)), 200);
        check_status(e);
        fd = tcp_connect("127.0.0.1", port);
        snprintf(buf, sizeof(buf), "GET /events HTTP/1.1\r\n%s\r\n", cookie);
        CHECK(send(fd, buf, strlen(buf), MSG_NOSIGNAL) > 0);
        read_until(fd, buf, sizeof(buf), "\n\n", 5);
        close(fd);
        CHECK_STR_CONTAINS(buf, "Content-Type: text/event-stream");
        CHECK_STR_CONTAINS(buf, "event: status\ndata: {\"status\":{\"state\":");
        check_picture("cam2", 240, 160);
        check_picture("cam1", 160, 120); /* 16-bit */
        CHECK_INT(get("/preview/nosuch.mjpg", cookie, buf, sizeof(buf)), 404);
        check_peeks_hold_nothing(e);
        check_completion(e, completion);
}

/* A request that never ends, huge headers, other methods, unknown paths, traversals. */
static void check_bad_requests(void)
{
        static const char *const traversals[] = {
                "/../../../../etc/passwd",      "/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
                "/preview/../../../etc/passwd", "/preview/..%2f..%2fetc%2fpasswd.mjpg",
                "/..\\..\\etc\\passwd",         "//etc/passwd"};
        static char buf[65536], big[12000];
        int fd = tcp_connect("127.0.0.1", port);
        double t = now_s();

        CHECK(send(fd, "GET / HTTP/1.1\r\nHost: x\r\n", 25, MSG_NOSIGNAL) == 25); /* slowloris */
        read_until(fd, buf, sizeof(buf), NULL, 3);
        close(fd);
        CHECK(now_s() - t < 2);
        CHECK_STR_CONTAINS(buf, "HTTP/1.1 408");
        memset(big, 'a', sizeof(big) - 1);
        snprintf(buf, sizeof(buf), "GET / HTTP/1.1\r\nX-Big: ");
        CHECK(send(fd = tcp_connect("127.0.0.1", port), buf, strlen(buf), MSG_NOSIGNAL) > 0);
        (void)send(fd, big, strlen(big), MSG_NOSIGNAL);
        read_until(fd, buf, sizeof(buf), NULL, 3);
        close(fd);
        CHECK_STR_CONTAINS(buf, "HTTP/1.1 431");
        CHECK_INT(http("POST /api/status HTTP/1.1\r\n" BEARER "Content-Length: 2\r\n\r\n{}", buf,
                       sizeof(buf)),
                  405);
        CHECK_INT(http("DELETE / HTTP/1.1\r\n" BEARER "\r\n", buf, sizeof(buf)), 405);
        CHECK_INT(get("/etc/passwd", "", buf, sizeof(buf)), 401);
        CHECK_INT(get("/no/such/page", BEARER, buf, sizeof(buf)), 404);
        for (size_t i = 0; i < sizeof(traversals) / sizeof(*traversals); i++) {
                int code = get(traversals[i], BEARER, buf, sizeof(buf));
                CHECK(code == 404 || code == 400);
                CHECK(!strstr(buf, "root:"));
        }
}

/* Idle connections past the limit drop the oldest; HEAD opens no stream; streams are
 * bounded. */
static void check_crowds(void)
{
        static char buf[65536];
        int fds[70], streams[WEB_MAX_VIEWERS + 1];
        struct pollfd p;

        for (int i = 0; i < 70; i++)
                fds[i] = tcp_connect("127.0.0.1", port);
        CHECK_INT(get("/api/status", BEARER, buf, sizeof(buf)), 200);
        p = (struct pollfd){.fd = fds[0], .events = POLLIN};
        CHECK(poll(&p, 1, 1000) == 1 && recv(fds[0], buf, 1, MSG_DONTWAIT) == 0); /* dropped */
        for (int i = 0; i < 70; i++)
                close(fds[i]);
        for (int i = 0; i < WEB_MAX_VIEWERS + 4; i++)
                CHECK_INT(http("HEAD /preview/cam0.mjpg HTTP/1.1\r\n" BEARER "\r\n", buf,
                               sizeof(buf)),
                          200);
        for (int i = 0; i <= WEB_MAX_VIEWERS; i++) {
                streams[i] = tcp_connect("127.0.0.1", port);
                snprintf(buf, sizeof(buf), "GET /preview/cam0.mjpg HTTP/1.1\r\n" BEARER "\r\n");
                CHECK(send(streams[i], buf, strlen(buf), MSG_NOSIGNAL) > 0);
                read_until(streams[i], buf, sizeof(buf), "\r\n\r\n", 3);
                CHECK_STR_CONTAINS(buf, i < WEB_MAX_VIEWERS ? "HTTP/1.1 200" : "HTTP/1.1 503");
        }
        for (int i = 0; i <= WEB_MAX_VIEWERS; i++)
                close(streams[i]);
}

/* GET path with the token over TLS to ip:port, trusting the CA file ca (in e's directory);
 * the answer in buf. Returns its status code, or the -errno of the handshake. */
static int https_get(struct rigenv *e, const char *ip, const char *ca, const char *path, char *buf,
                     size_t len)
{
        struct tls_creds *creds = NULL;
        struct tls_conn *t = NULL;
        char req[512], ca_path[400], err[600];
        int fd = tcp_connect(ip, port), code = 0; /* blocking: no call returns -EAGAIN */
        ssize_t n = 0, r;

        snprintf(req, sizeof(req), "GET %s HTTP/1.1\r\n" BEARER "\r\n", path);
        snprintf(ca_path, sizeof(ca_path), "%s/%s", e->dir, ca);
        CHECK(tls_creds_new_client(ca_path, &creds, err, sizeof(err)) == 0);
        CHECK(tls_conn_new(creds, fd, ip, &t) == 0);
        r = tls_handshake(t);
        if (r == 0)
                CHECK(tls_write(t, req, strlen(req)) == (ssize_t)strlen(req));
        while (r >= 0 && n + 1 < (ssize_t)len && (r = tls_read(t, buf + n, len - 1 - n)) > 0)
                n += r;
        buf[n] = 0;
        if (n > 0)
                CHECK(sscanf(buf, "HTTP/1.1 %d", &code) == 1);
        tls_conn_free(t);
        tls_creds_free(creds);
        close(fd);
        return n > 0 ? code : (int)r;
}

/* Has goniod started next serve HTTPS with the certificates made for san. */
static void use_tls(struct rigenv *e, const char *certs_script, const char *san)
{
        char path[400];

        rigenv_make_certs(e, certs_script, san);
        snprintf(path, sizeof(path), "%s/server.pem", e->dir);
        setenv("GONIO_TLS_CERT", path, 1);
        snprintf(path, sizeof(path), "%s/server.key", e->dir);
        setenv("GONIO_TLS_KEY", path, 1);
}

static void case_tls(struct rigenv *e, const char *certs_script)
{
        static const char partial_hello[] = "\x16\x03\x01\x02\x00\x01\x00"; /* of 512 bytes */
        static char buf[65536];
        struct pollfd p;
        int stalled;
        double t0;

        use_tls(e, certs_script, "IP:127.0.0.1");
        rigenv_spawn_daemon(e, e->sock, http_env, "127.0.0.1");
        stalled = tcp_connect("127.0.0.1", port);
        CHECK(write(stalled, partial_hello, sizeof(partial_hello) - 1) > 0);
        t0 = now_s();
        CHECK_INT(https_get(e, "127.0.0.1", "ca.pem", "/api/status", buf, sizeof(buf)), 200);
        CHECK_STR_CONTAINS(body_of(buf), "\"state\":");
        CHECK(now_s() - t0 < 0.3); /* not held up by the stalled handshake */
        CHECK_INT(https_get(e, "127.0.0.1", "ca.pem", "/?token=" TOKEN, buf, sizeof(buf)), 303);
        CHECK_STR_CONTAINS(buf, "; HttpOnly; SameSite=Strict; Secure\r\n");
        CHECK_INT(https_get(e, "127.0.0.1", "other-ca.pem", "/", buf, sizeof(buf)), -EKEYREJECTED);
        CHECK_INT(get("/api/status", BEARER, buf, sizeof(buf)), 400);
        CHECK_STR_CONTAINS(body_of(buf), "this port takes HTTPS only");
        p = (struct pollfd){.fd = stalled, .events = POLLIN};
        CHECK(poll(&p, 1, 2000) == 1 && recv(stalled, buf, 1, 0) <= 0); /* dropped at 400 ms */
        close(stalled);
}

static void case_netns(struct rigenv *e, const char *certs_script)
{
        static char buf[65536];

        start_refused(e, "10.77.0.1", "not a loopback address: beyond loopback the dashboard");
        use_tls(e, certs_script, "IP:10.77.0.1");
        rigenv_spawn_daemon(e, e->sock, http_env, "10.77.0.1");
        CHECK_INT(https_get(e, "10.77.0.1", "ca.pem", "/api/status", buf, sizeof(buf)), 200);
        CHECK_STR_CONTAINS(body_of(buf), "\"state\":");
}

static void case_rude(struct rigenv *e)
{
        char buf[4096];

        rigenv_spawn_daemon(e, e->sock, http_env, "127.0.0.1");
        check_bad_requests();
        check_crowds();
        CHECK_INT(get("/api/status", BEARER, buf, sizeof(buf)), 200); /* still serving */
}

int main(int argc, char **argv)
{
        struct rigenv e;
        char token_file[300], *rig;

        CHECK(argc >= 5);
        if (strcmp(argv[4], "netns") == 0)
                enter_netns("10.77.0.1"); /* before any process starts: they all live in it */
        port = 20000 + (getpid() * 7) % 20000;
        rig = rig_insert(NULL, "bits: 16 }\n",
                         "  - { name: cam2, sim: { bus: frames }, elevation: 30, distance: 600,\n"
                         "      azimuth: 60, target: [0, 0, 40], width: 720, height: 480,\n"
                         "      fx: 1200, fy: 1200, exposure_us: 20000 }\n");
        rigenv_start_sim_rig(&e, argv, 10, rig);
        free(rig);
        snprintf(token_file, sizeof(token_file), "%s/token", e.dir);
        write_file(token_file, TOKEN "\n");
        setenv("GONIO_TOKEN_FILE", token_file, 1);
        if (strcmp(argv[4], "serve") == 0)
                case_serve(&e, argc > 5 ? argv[5] : NULL);
        else if (strcmp(argv[4], "rude") == 0)
                case_rude(&e);
        else if (strcmp(argv[4], "tls") == 0 && argc > 5)
                case_tls(&e, argv[5]);
        else if (strcmp(argv[4], "netns") == 0 && argc > 5)
                case_netns(&e, argv[5]);
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return 0;
}
