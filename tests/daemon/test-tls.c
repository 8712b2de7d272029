/* test-tls.c - daemon/tls (TLS over non-blocking sockets, GnuTLS) in process, both ends on a
 * socketpair, with certificates tests/tls-certs.sh makes at test time:
 *   creds     a missing, non-PEM or mismatched certificate or key is refused with its errno
 *             and a message naming the file; a CA file without a certificate too;
 *   exchange  a handshake (TLS 1.3), 1 MiB each way through -EAGAIN on both sides, data
 *             GnuTLS decrypted ahead (tls_pending), the end of the stream after close_notify;
 *   verify    a server certificate of another CA, or naming another address, is rejected
 *             (-EKEYREJECTED, saying why); the right CA and address pass;
 *   plain     a client without TLS is told apart at its first byte (-EPROTONOSUPPORT);
 *   deadline  the deadline fires on a stalled handshake, and never after one that ended.
 * Usage: test-tls CERTS-SCRIPT CASE (77 without openssl). */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "daemon/tls.h"
#include "tests/test.h"

#define BIG (1024 * 1024)

static char dir[64], path_buf[8][200];
static int n_paths;

/* dir/name, in a buffer that stays valid for the test. */
static const char *in_dir(const char *name)
{
        char *p = path_buf[n_paths++ % 8];

        snprintf(p, sizeof(path_buf[0]), "%s/%s", dir, name);
        return p;
}

static void make_certs(const char *script)
{
        char cmd[400];
        int r;

        snprintf(dir, sizeof(dir), "/tmp/test-tls-XXXXXX");
        CHECK(mkdtemp(dir));
        snprintf(cmd, sizeof(cmd), "%s %s IP:127.0.0.1,DNS:goniod.test", script, dir);
        r = system(cmd);
        if (WIFEXITED(r) && WEXITSTATUS(r) == TEST_SKIP)
                exit(TEST_SKIP);
        CHECK(r == 0);
}

static void remove_certs(void)
{
        char cmd[100];

        snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
        (void)!system(cmd);
}

static struct tls_creds *server_creds(void)
{
        struct tls_creds *c = NULL;
        char err[600];

        CHECK_INT(tls_creds_new_server(in_dir("server.pem"), in_dir("server.key"), &c, err,
                                       sizeof(err)),
                  0);
        return c;
}

static struct tls_creds *client_creds(const char *ca)
{
        struct tls_creds *c = NULL;
        char err[600];

        CHECK_INT(tls_creds_new_client(in_dir(ca), &c, err, sizeof(err)), 0);
        return c;
}

/* Expects tls_creds_new_server(cert, key) to fail with want, its message holding what and
 * not innocent (the file that is not at fault; NULL: both are). */
static void server_refused(const char *cert, const char *key, int want, const char *what,
                           const char *innocent)
{
        struct tls_creds *c = NULL;
        char err[600] = "";

        CHECK_INT(tls_creds_new_server(cert, key, &c, err, sizeof(err)), want);
        CHECK(!c);
        CHECK_STR_CONTAINS(err, what);
        CHECK(!innocent || !strstr(err, innocent));
}

static void test_creds(void)
{
        const char *cert = in_dir("server.pem"), *key = in_dir("server.key");
        const char *junk = in_dir("junk.pem"), *none = in_dir("none.pem");
        struct tls_creds *c = NULL;
        char err[600] = "";
        FILE *f = fopen(junk, "w");

        CHECK(f);
        fputs("not PEM at all\n", f);
        fclose(f);
        server_refused(none, key, -ENOENT, none, key);
        server_refused(cert, none, -ENOENT, none, cert);
        server_refused(junk, key, -EBADMSG, junk, key);
        server_refused(cert, junk, -EBADMSG, junk, cert);
        server_refused(cert, in_dir("other-ca.key"), -EKEYREJECTED,
                       "the key is not the certificate's", NULL);
        CHECK_INT(tls_creds_new_client(none, &c, err, sizeof(err)), -ENOENT);
        CHECK_STR_CONTAINS(err, none);
        CHECK_INT(tls_creds_new_client(junk, &c, err, sizeof(err)), -EBADMSG);
        CHECK_STR_CONTAINS(err, junk);
        c = server_creds();
        CHECK(!tls_creds_free(c));
}

/* Runs the handshakes of s (server) and c (client) to their end; returns the client's
 * result (the server's is checked to end too, with an error when the client's is one). */
static int handshake(struct tls_conn *s, int sfd, struct tls_conn *c, int cfd)
{
        int rs = -EAGAIN, rc = -EAGAIN;

        for (int i = 0; i < 1000 && (rs == -EAGAIN || rc == -EAGAIN); i++) {
                struct pollfd p[2] = {{.fd = sfd, .events = POLLIN}, {.fd = cfd, .events = POLLIN}};

                if (rs == -EAGAIN)
                        rs = tls_handshake(s);
                if (rc == -EAGAIN)
                        rc = tls_handshake(c);
                if (rs == -EAGAIN && rc == -EAGAIN)
                        CHECK(poll(p, 2, 5000) > 0);
                if (rc < 0 && rc != -EAGAIN)
                        break; /* the server is told by the client's alert, or never */
        }
        CHECK(rc != -EAGAIN);
        CHECK_INT(rs == 0, rc == 0);
        return rc;
}

struct pair {
        int fd[2]; /* server, client */
        struct tls_creds *sc, *cc;
        struct tls_conn *s, *c;
};

static void pair_open(struct pair *p, const char *ca, const char *peer)
{
        CHECK(socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, p->fd) == 0);
        p->sc = server_creds();
        p->cc = client_creds(ca);
        CHECK_INT(tls_conn_new(p->sc, p->fd[0], NULL, &p->s), 0);
        CHECK_INT(tls_conn_new(p->cc, p->fd[1], peer, &p->c), 0);
}

static void pair_close(struct pair *p)
{
        tls_conn_free(p->s);
        tls_conn_free(p->c);
        close(p->fd[0]);
        close(p->fd[1]);
        tls_creds_free(p->sc);
        tls_creds_free(p->cc);
}

/* Sends BIG bytes from a to b through a socket that takes less at a time. */
static void transfer(struct tls_conn *a, struct tls_conn *b)
{
        static char out[BIG], in[16384];
        size_t sent = 0, got = 0;
        int eagain = 0;

        for (size_t i = 0; i < BIG; i++)
                out[i] = (char)(i * 7 + i / 4096);
        while (got < BIG) {
                ssize_t n;

                while (sent < BIG && (n = tls_write(a, out + sent, BIG - sent)) > 0)
                        sent += (size_t)n; /* until the socket is full */
                CHECK(sent == BIG || n == -EAGAIN);
                eagain += sent < BIG;
                while ((n = tls_read(b, in, sizeof(in))) > 0) {
                        CHECK(memcmp(in, out + got, (size_t)n) == 0);
                        got += (size_t)n;
                }
                CHECK(n == -EAGAIN || got == BIG);
        }
        CHECK(eagain > 0); /* the socket's buffer was full at least once */
}

static void test_exchange(void)
{
        struct pair p;
        char what[64], buf[8];

        pair_open(&p, "ca.pem", "127.0.0.1");
        CHECK(!tls_ready(p.s));
        CHECK_INT(handshake(p.s, p.fd[0], p.c, p.fd[1]), 0);
        CHECK(tls_ready(p.s) && tls_ready(p.c));
        CHECK_STR_CONTAINS(tls_conn_describe(p.s, what, sizeof(what)), "TLS1.3");
        transfer(p.c, p.s);
        transfer(p.s, p.c);
        CHECK_INT(tls_write(p.c, "ab\n", 3), 3);
        CHECK_INT(tls_read(p.s, buf, 1), 1);
        CHECK_INT(tls_pending(p.s), 2); /* decrypted, not read: the socket is not readable */
        CHECK_INT(recv(p.fd[0], buf, 1, MSG_PEEK | MSG_DONTWAIT), -1);
        CHECK_INT(tls_read(p.s, buf, sizeof(buf)), 2);
        CHECK_INT(tls_read(p.s, buf, sizeof(buf)), -EAGAIN);
        p.c = tls_conn_free(p.c); /* close_notify */
        CHECK_INT(tls_read(p.s, buf, sizeof(buf)), 0);
        pair_close(&p);
}

/* A handshake of a client trusting ca and expecting peer: its result and error text. */
static int verify(const char *ca, const char *peer, char *err, size_t len)
{
        struct pair p;
        int r;

        pair_open(&p, ca, peer);
        r = handshake(p.s, p.fd[0], p.c, p.fd[1]);
        snprintf(err, len, "%s", tls_conn_error(p.c));
        pair_close(&p);
        return r;
}

static void test_verify(void)
{
        char err[256];

        CHECK_INT(verify("other-ca.pem", "127.0.0.1", err, sizeof(err)), -EKEYREJECTED);
        CHECK_STR_CONTAINS(err, "issuer is unknown");
        CHECK_INT(verify("ca.pem", "10.77.0.1", err, sizeof(err)), -EKEYREJECTED);
        CHECK_STR_CONTAINS(err, "does not match");
        CHECK_INT(verify("ca.pem", "goniod.test", err, sizeof(err)), 0);
        CHECK_INT(verify("ca.pem", NULL, err, sizeof(err)), 0);
}

static void test_plain(void)
{
        static const char hello[] = "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"hello\"}\n";
        struct pair p;
        char buf[64];

        pair_open(&p, "ca.pem", NULL);
        CHECK_INT(tls_handshake(p.s), -EAGAIN); /* nothing yet */
        CHECK(!tls_wants_write(p.s));
        CHECK_INT(write(p.fd[1], hello, strlen(hello)), (long long)strlen(hello));
        CHECK_INT(tls_handshake(p.s), -EPROTONOSUPPORT);
        CHECK_STR_CONTAINS(tls_conn_error(p.s), "not a TLS client (first byte 0x7b)");
        /* nothing was read: the caller may answer in plain text */
        CHECK_INT(recv(p.fd[0], buf, sizeof(buf), MSG_DONTWAIT), (long long)strlen(hello));
        pair_close(&p);
}

static int on_deadline(sd_event_source *es, uint64_t usec, void *ud)
{
        (*(int *)ud)++;
        return 0;
}

/* Runs event for usec; returns how many times the deadline fired meanwhile. */
static int run_for(sd_event *event, uint64_t usec, int *fired)
{
        uint64_t start, now;

        CHECK(sd_event_now(event, CLOCK_MONOTONIC, &start) >= 0);
        do {
                CHECK(sd_event_run(event, usec / 10) >= 0);
                CHECK(sd_event_now(event, CLOCK_MONOTONIC, &now) >= 0);
        } while (now < start + usec && !*fired);
        return *fired;
}

static void test_deadline(void)
{
        sd_event *event = NULL;
        struct pair p;
        int fired = 0;

        CHECK(sd_event_new(&event) >= 0);
        pair_open(&p, "ca.pem", NULL); /* a client that never starts its handshake */
        CHECK_INT(tls_conn_set_deadline(p.s, event, 100000, on_deadline, &fired), 0);
        CHECK_INT(tls_handshake(p.s), -EAGAIN);
        CHECK_INT(run_for(event, 2000000, &fired), 1);
        pair_close(&p);
        fired = 0;
        pair_open(&p, "ca.pem", NULL); /* one that ends it in time */
        CHECK_INT(tls_conn_set_deadline(p.s, event, 100000, on_deadline, &fired), 0);
        CHECK_INT(handshake(p.s, p.fd[0], p.c, p.fd[1]), 0);
        CHECK_INT(run_for(event, 300000, &fired), 0);
        pair_close(&p);
        sd_event_unref(event);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"creds", test_creds}, {"exchange", test_exchange}, {"verify", test_verify},
                {"plain", test_plain}, {"deadline", test_deadline},
        };
        CHECK(argc >= 2);
        make_certs(argv[1]);
        atexit(remove_certs);
        return TEST_RUN_CASES(cases, argc - 1, argv + 1);
}
