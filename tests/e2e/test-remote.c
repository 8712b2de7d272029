/* test-remote.c - goniod's TCP listener (docs/goniod.md, "Remote access") on gonio-sim.
 * Usage: test-e2e-remote GONIOD GONIOCTL GONIO_SIM CASE [CERTS-SCRIPT]
 *   token    loopback only without TLS, every request refused until hello gives the token, a
 *            wrong token refused and the third closes the connection, the token's client then
 *            served as any operator (status, a move), notifications only for it (not for a
 *            client without the token), the Unix socket unchanged; an address
 *            beyond loopback, or no token, stops goniod at its start with the reason;
 *   tls      with --tls-cert/--tls-key (made by tests/tls-certs.sh): a key that is not the
 *            certificate's or a missing certificate stops goniod at its start naming it;
 *            gonioctl over TLS (options, or $GONIO_CONNECT...) gets the status and moves an
 *            axis while a client stalls in its handshake; another CA is refused with the
 *            reason (a JSON error object), a client without TLS is told so and goniod goes on
 *            serving; gonioctl doctor over TLS (no socket file to check; another CA's
 *            failure named);
 *   netns    in a network namespace of its own (skipped, 77, where none can be made) with
 *            10.77.0.1 on lo: that address without TLS stops goniod at its start, with TLS
 *            gonioctl is served there. */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "harness.h"
#include "tests/test.h"

#define TOKEN       "a-token-of-twenty-six-chars"
#define TLS_STALL_S 8 /* below goniod's handshake deadline (TLS_HANDSHAKE_USEC, 10 s) */

/* goniod's TCP listener: address, token file, TLS certificate and key ("": none). */
struct tcp_env {
        char ip[32], addr[64], token_file[400], cert[400], key[400];
        int port;
};

static void tcp_env(void *ud)
{
        struct tcp_env *t = ud;

        setenv("GONIO_LISTEN_TCP", t->addr, 1);
        setenv("GONIO_TOKEN_FILE", t->token_file, 1);
        setenv("GONIO_TLS_CERT", t->cert, 1);
        setenv("GONIO_TLS_KEY", t->key, 1);
}

/* t for ip:port in e's directory with the token file written; TLS off. */
static void tcp_env_init(struct tcp_env *t, struct rigenv *e, const char *ip, int port)
{
        *t = (struct tcp_env){.port = port};
        snprintf(t->ip, sizeof(t->ip), "%s", ip);
        snprintf(t->addr, sizeof(t->addr), "%s:%d", ip, port);
        snprintf(t->token_file, sizeof(t->token_file), "%s/token", e->dir);
        write_file(t->token_file, TOKEN "\n");
}

/* raw_call's reply carries an error whose message holds what. */
static void refused(int fd, const char *req, const char *what)
{
        json_t *r = raw_call(fd, req);
        const char *msg =
                json_string_value(json_object_get(json_object_get(r, "error"), "message"));

        CHECK(msg);
        CHECK_STR_CONTAINS(msg, what);
        json_decref(r);
}

static void ok(int fd, const char *req)
{
        json_t *r = raw_call(fd, req);

        if (!json_object_get(r, "result"))
                print_json("expected a result", r);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
}

static const char *hello(const char *token, char *buf, size_t len)
{
        snprintf(buf, len,
                 "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"hello\",\"params\":{\"client\":"
                 "\"test\",\"protocol\":1%s%s%s}}\n",
                 token ? ",\"token\":\"" : "", token ? token : "", token ? "\"" : "");
        return buf;
}

/* goniod with addr and token file t: exits 1 at its start, its log saying why. */
static void start_refused(struct rigenv *e, struct tcp_env *t, const char *why)
{
        char log[500], cmd[700];
        int status;

        rigenv_spawn_daemon(e, e->sock, tcp_env, t);
        CHECK(waitpid(e->daemon, &status, 0) == e->daemon);
        e->daemon = 0;
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 1);
        snprintf(log, sizeof(log), "%s/goniod.log", e->dir);
        snprintf(cmd, sizeof(cmd), "grep -q '%s' %s", why, log);
        CHECK(system(cmd) == 0);
}

static void case_token(struct rigenv *e)
{
        static const char status[] = "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"status\"}\n";
        struct tcp_env t;
        char buf[400];
        int port = 20000 + getpid() % 20000, fd, unix_fd, stranger;

        tcp_env_init(&t, e, "0.0.0.0", port);
        start_refused(e, &t, "not a loopback address");
        tcp_env_init(&t, e, "127.0.0.1", port);
        write_file(t.token_file, "short\n");
        start_refused(e, &t, "the token must be 16 to 127 characters");
        write_file(t.token_file, TOKEN "\n");
        rigenv_spawn_daemon(e, e->sock, tcp_env, &t);
        stranger = tcp_connect(t.ip, port); /* never gives the token */
        fd = tcp_connect(t.ip, port);
        refused(fd, status, "say hello with the token first");
        refused(fd, hello(NULL, buf, sizeof(buf)), "wrong or missing token");
        ok(fd, hello(TOKEN, buf, sizeof(buf)));
        ok(fd, status);
        ok(fd, "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"home\"}\n");
        CHECK(strstr(raw_seen(), "state.changed")); /* home was told to the token's client, */
        CHECK(recv(stranger, buf, sizeof(buf), MSG_DONTWAIT) < 0 && errno == EAGAIN); /* only */
        close(stranger);
        close(fd);
        fd = tcp_connect(t.ip, port); /* three wrong tokens: closed */
        for (int i = 0; i < 2; i++)
                refused(fd, hello("a-wrong-token-of-some-length", buf, sizeof(buf)), "wrong");
        CHECK(write(fd, hello("x", buf, sizeof(buf)), strlen(buf)) > 0);
        usleep(300000);
        CHECK(recv(fd, buf, sizeof(buf), 0) >= 0); /* the error line, then end of file */
        CHECK(recv(fd, buf, sizeof(buf), 0) == 0);
        close(fd);
        unix_fd = raw_connect(e); /* the Unix socket needs no token */
        ok(unix_fd, status);
        close(unix_fd);
}

static const char *certs_script;

/* Makes the test certificates (tests/tls-certs.sh) for san in e's directory and sets t's
 * certificate and key to the server's; exits 77 without openssl. */
static void make_certs(struct rigenv *e, struct tcp_env *t, const char *san)
{
        rigenv_make_certs(e, certs_script, san);
        snprintf(t->cert, sizeof(t->cert), "%s/server.pem", e->dir);
        snprintf(t->key, sizeof(t->key), "%s/server.key", e->dir);
}

/* gonioctl --json --connect over TLS to t trusting the CA file ca (in e's directory) with
 * args (NULL-terminated); *out as ctl's. Returns the exit code. */
static int tls_ctl(struct rigenv *e, struct tcp_env *t, const char *ca, json_t **out,
                   const char *a1, const char *a2, const char *a3)
{
        char path[400];

        snprintf(path, sizeof(path), "%s/%s", e->dir, ca);
        return ctl(e, out, "--connect", t->addr, "--token-file", t->token_file, "--tls-ca", path,
                   a1, a2, a3, NULL);
}

/* The message of gonioctl's JSON error object out (taken), checked to hold what. */
static void error_holds(json_t *out, const char *what)
{
        const char *msg =
                json_string_value(json_object_get(json_object_get(out, "error"), "message"));

        if (!msg)
                print_json("expected an error object", out);
        CHECK_STR_CONTAINS(msg, what);
        json_decref(out);
}

/* gonioctl finds goniod by $GONIO_CONNECT, $GONIO_TOKEN_FILE and $GONIO_TLS_CA alone. */
static void status_by_env(struct rigenv *e, struct tcp_env *t)
{
        char ca[400], out[8192];

        snprintf(ca, sizeof(ca), "%s/ca.pem", e->dir);
        setenv("GONIO_CONNECT", t->addr, 1);
        setenv("GONIO_TOKEN_FILE", t->token_file, 1);
        setenv("GONIO_TLS_CA", ca, 1);
        CHECK_INT(run_capture((char *[]){(char *)e->gonioctl, "--json", "status", NULL}, out,
                              sizeof(out), NULL, 0),
                  0);
        CHECK_STR_CONTAINS(out, "\"state\"");
        unsetenv("GONIO_CONNECT");
        unsetenv("GONIO_TOKEN_FILE");
        unsetenv("GONIO_TLS_CA");
}

/* gonioctl doctor over TLS: no socket file to check, goniod answers; with another CA it
 * says why it does not. */
static void doctor(struct rigenv *e, struct tcp_env *t)
{
        json_t *out = NULL;
        char *text;

        CHECK_INT(tls_ctl(e, t, "ca.pem", &out, "doctor", NULL, NULL), 0);
        CHECK_STR_CONTAINS(json_string_value(json_object_get(
                                   json_array_get(json_object_get(out, "checks"), 0), "detail")),
                           "over TCP");
        json_decref(out);
        CHECK_INT(tls_ctl(e, t, "other-ca.pem", &out, "doctor", NULL, NULL), 3);
        text = json_dumps(out, 0);
        CHECK_STR_CONTAINS(text, "goniod does not answer: connect: ");
        CHECK_STR_CONTAINS(text, "The certificate issuer is unknown");
        free(text);
        json_decref(out);
}

static void case_tls(struct rigenv *e)
{
        static const char partial_hello[] = "\x16\x03\x01\x02\x00\x01\x00"; /* of 512 bytes */
        struct tcp_env t;
        json_t *out = NULL;
        int stalled;
        double t0;

        tcp_env_init(&t, e, "127.0.0.1", 20000 + getpid() % 20000);
        make_certs(e, &t, "IP:127.0.0.1");
        snprintf(t.key, sizeof(t.key), "%s/other-ca.key", e->dir);
        start_refused(e, &t, "the key is not the certificate");
        snprintf(t.key, sizeof(t.key), "%s/server.key", e->dir);
        snprintf(t.cert, sizeof(t.cert), "%s/no-such.pem", e->dir);
        start_refused(e, &t, "cannot read the certificate .*/no-such.pem");
        snprintf(t.cert, sizeof(t.cert), "%s/server.pem", e->dir);
        rigenv_spawn_daemon(e, e->sock, tcp_env, &t);
        stalled = tcp_connect(t.ip, t.port); /* stalls in its handshake from here on */
        CHECK(write(stalled, partial_hello, sizeof(partial_hello) - 1) > 0);
        t0 = now_s();
        CHECK_INT(tls_ctl(e, &t, "ca.pem", &out, "status", NULL, NULL), 0);
        CHECK(json_object_get(out, "state"));
        json_decref(out);
        CHECK_INT(tls_ctl(e, &t, "ca.pem", NULL, "home", "turntable", NULL), 0);
        CHECK_INT(tls_ctl(e, &t, "ca.pem", &out, "move", "turntable", "45"), 0);
        CHECK_NEAR(json_number_value(json_object_get(out, "position")), 45, POSE_TOL_DEG);
        json_decref(out);
        CHECK(now_s() - t0 < TLS_STALL_S); /* not held up by the stalled handshake */
        CHECK_INT(tls_ctl(e, &t, "other-ca.pem", &out, "status", NULL, NULL), 3);
        error_holds(out, "The certificate issuer is unknown");
        CHECK(ctl(e, &out, "--connect", t.addr, "--token-file", t.token_file, "status", NULL));
        error_holds(out, "this port of goniod takes TLS connections only");
        status_by_env(e, &t);
        doctor(e, &t);
        close(stalled);
}

static void case_netns(struct rigenv *e)
{
        struct tcp_env t;
        json_t *out = NULL;

        tcp_env_init(&t, e, "10.77.0.1", 7777);
        start_refused(e, &t, "not a loopback address");
        make_certs(e, &t, "IP:10.77.0.1");
        rigenv_spawn_daemon(e, e->sock, tcp_env, &t);
        close(tcp_connect(t.ip, t.port));
        CHECK_INT(tls_ctl(e, &t, "ca.pem", &out, "status", NULL, NULL), 0);
        CHECK(json_object_get(out, "state"));
        json_decref(out);
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc >= 5);
        certs_script = argc > 5 ? argv[5] : NULL;
        if (strcmp(argv[4], "netns") == 0)
                enter_netns("10.77.0.1"); /* before any process starts: they all live in it */
        CHECK(strcmp(argv[4], "token") == 0 || certs_script);
        rigenv_start_sim(&e, argv, 10);
        if (strcmp(argv[4], "token") == 0)
                case_token(&e);
        else if (strcmp(argv[4], "tls") == 0)
                case_tls(&e);
        else if (strcmp(argv[4], "netns") == 0)
                case_netns(&e);
        else
                CHECK(!"unknown case");
        rigenv_stop(&e);
        return 0;
}
