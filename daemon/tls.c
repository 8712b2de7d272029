/* tls.c - TLS over a non-blocking stream socket with GnuTLS (see tls.h).
 *
 * DESIGN: GnuTLS reads and writes the socket itself (gnutls_transport_set_int, sends with
 * MSG_NOSIGNAL), each session non-blocking; its GNUTLS_E_AGAIN becomes -EAGAIN and
 * gnutls_record_get_direction() says which way to wait. GnuTLS's own handshake timeout is
 * off: the caller's loop owns time (tls_conn_set_deadline). Every credential holds a
 * reference on GnuTLS's global state (gnutls_global_init/deinit), so that nothing of it is
 * left once the last one is freed. */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <gnutls/gnutls.h>
#include <gnutls/x509.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>

#include "common/cleanup.h"
#include "common/fileio.h"
#include "daemon/tls.h"

/* TLS 1.3 first, 1.2 where the peer has nothing newer; GnuTLS's default suites otherwise. */
#define TLS_PRIORITY     "NORMAL:-VERS-ALL:+VERS-TLS1.3:+VERS-TLS1.2"
#define TLS_RECORD_BYTE0 0x16 /* the content type of a handshake record */
/* Calls of GnuTLS after a non-fatal error (a warning alert...) per call of ours: a peer that
 * sends nothing else cannot keep the loop in one call. */
#define TLS_RETRIES 16

struct tls_creds {
        gnutls_certificate_credentials_t cred;
        gnutls_priority_t priority;
        bool server;
};

struct tls_conn {
        gnutls_session_t session;
        int fd;
        bool server;
        bool looked;         /* server: the client's first byte was a handshake record */
        bool ready;          /* the handshake has ended */
        size_t send_pending; /* bytes of the tls_write that returned -EAGAIN, 0: none */
        sd_event_source *deadline;
        char error[256];
};

/* The file's bytes into *d (free(d->data)), err naming it and what (a certificate...) on
 * failure. Returns 0 or -errno. */
static int load(const char *path, const char *what, gnutls_datum_t *d, char *err, size_t errlen)
{
        void *buf = NULL;
        size_t len = 0;
        int r = gn_read_file_at(AT_FDCWD, path, TLS_MAX_FILE, &buf, &len);

        if (r < 0) {
                snprintf(err, errlen, "cannot read the %s %s: %s", what, path, strerror(-r));
                return r;
        }
        d->data = buf;
        d->size = (unsigned)len;
        return 0;
}

/* Checks that d holds a PEM certificate and that key holds a PEM private key, naming the
 * file that does not in err. Returns 0 or -EBADMSG. */
static int check_pem(const gnutls_datum_t *cert, const char *cert_file, const gnutls_datum_t *key,
                     const char *key_file, char *err, size_t errlen)
{
        gnutls_x509_crt_t *crts = NULL;
        gnutls_x509_privkey_t pk = NULL;
        unsigned n = 0;
        int r = gnutls_x509_crt_list_import2(&crts, &n, cert, GNUTLS_X509_FMT_PEM, 0);

        for (unsigned i = 0; r >= 0 && i < n; i++)
                gnutls_x509_crt_deinit(crts[i]);
        gnutls_free(crts);
        if (r < 0) {
                snprintf(err, errlen, "%s: no PEM certificate in it (%s)", cert_file,
                         gnutls_strerror(r));
                return -EBADMSG;
        }
        r = gnutls_x509_privkey_init(&pk);
        if (r >= 0)
                r = gnutls_x509_privkey_import2(pk, key, GNUTLS_X509_FMT_PEM, NULL, 0);
        gnutls_x509_privkey_deinit(pk);
        if (r < 0) {
                snprintf(err, errlen, "%s: no PEM private key in it (%s)", key_file,
                         gnutls_strerror(r));
                return -EBADMSG;
        }
        return 0;
}

/* New credentials with GnuTLS's global state referenced; *err set on failure. */
static int creds_alloc(bool server, struct tls_creds **ret, char *err, size_t errlen)
{
        struct tls_creds *c;
        int r = gnutls_global_init();

        if (r < 0) {
                snprintf(err, errlen, "GnuTLS: %s", gnutls_strerror(r));
                return -ENOMEM;
        }
        c = calloc(1, sizeof(*c));
        if (c)
                c->server = server;
        if (!c || gnutls_certificate_allocate_credentials(&c->cred) < 0 ||
            gnutls_priority_init(&c->priority, TLS_PRIORITY, NULL) < 0) {
                tls_creds_free(c);
                if (!c)
                        gnutls_global_deinit();
                snprintf(err, errlen, "GnuTLS: cannot allocate credentials");
                return -ENOMEM;
        }
        *ret = c;
        return 0;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct tls_creds *, tls_creds_free);

int tls_creds_new_server(const char *cert_file, const char *key_file, struct tls_creds **ret,
                         char *err, size_t errlen)
{
        _cleanup_(tls_creds_freep) struct tls_creds *c = NULL;
        gnutls_datum_t cert = {0}, key = {0};
        int r = load(cert_file, "certificate", &cert, err, errlen);

        if (r >= 0)
                r = load(key_file, "key", &key, err, errlen);
        if (r >= 0)
                r = check_pem(&cert, cert_file, &key, key_file, err, errlen);
        if (r >= 0)
                r = creds_alloc(true, &c, err, errlen);
        if (r >= 0) {
                int g = gnutls_certificate_set_x509_key_mem2(c->cred, &cert, &key,
                                                             GNUTLS_X509_FMT_PEM, NULL, 0);
                if (g == GNUTLS_E_CERTIFICATE_KEY_MISMATCH)
                        r = -EKEYREJECTED;
                else if (g < 0)
                        r = -EBADMSG;
                if (g < 0)
                        snprintf(err, errlen, "%s and %s: %s", cert_file, key_file,
                                 g == GNUTLS_E_CERTIFICATE_KEY_MISMATCH
                                         ? "the key is not the certificate's"
                                         : gnutls_strerror(g));
        }
        if (key.data) /* the key's bytes do not stay in memory we no longer use */
                gnutls_memset(key.data, 0, key.size);
        free(key.data);
        free(cert.data);
        if (r < 0)
                return r;
        *ret = TAKE_PTR(c);
        return 0;
}

int tls_creds_new_client(const char *ca_file, struct tls_creds **ret, char *err, size_t errlen)
{
        _cleanup_(tls_creds_freep) struct tls_creds *c = NULL;
        gnutls_datum_t ca = {0};
        int r = ca_file ? load(ca_file, "CA file", &ca, err, errlen) : 0, n;

        if (r >= 0)
                r = creds_alloc(false, &c, err, errlen);
        if (r < 0) {
                free(ca.data);
                return r;
        }
        n = ca_file ? gnutls_certificate_set_x509_trust_mem(c->cred, &ca, GNUTLS_X509_FMT_PEM)
                    : gnutls_certificate_set_x509_system_trust(c->cred);
        free(ca.data);
        if (n <= 0) {
                snprintf(err, errlen, "%s: no PEM certificate in it%s%s",
                         ca_file ? ca_file : "the system's trust store", n < 0 ? ": " : "",
                         n < 0 ? gnutls_strerror(n) : "");
                return -EBADMSG;
        }
        *ret = TAKE_PTR(c);
        return 0;
}

struct tls_creds *tls_creds_free(struct tls_creds *creds)
{
        if (!creds)
                return NULL;
        if (creds->priority)
                gnutls_priority_deinit(creds->priority);
        if (creds->cred)
                gnutls_certificate_free_credentials(creds->cred);
        free(creds);
        gnutls_global_deinit();
        return NULL;
}

/* Sets up t's session as a client that verifies the server's certificate against peer. */
static int client_setup(struct tls_conn *t, const char *peer)
{
        unsigned char ip[16];
        bool is_ip =
                peer && (inet_pton(AF_INET, peer, ip) == 1 || inet_pton(AF_INET6, peer, ip) == 1);

        /* SNI carries names only (RFC 6066, 3); an address is checked against the
         * certificate's IP address entries all the same */
        if (peer && !is_ip &&
            gnutls_server_name_set(t->session, GNUTLS_NAME_DNS, peer, strlen(peer)) < 0)
                return -EINVAL;
        gnutls_session_set_verify_cert(t->session, peer, 0);
        return 0;
}

int tls_conn_new(const struct tls_creds *creds, int fd, const char *peer, struct tls_conn **ret)
{
        unsigned flags = GNUTLS_NONBLOCK | GNUTLS_NO_SIGNAL | GNUTLS_NO_TICKETS; /* no resumption */
        struct tls_conn *t = calloc(1, sizeof(*t));
        int r;

        if (!t)
                return -ENOMEM;
        t->fd = fd;
        t->server = creds->server;
        r = gnutls_init(&t->session, flags | (t->server ? GNUTLS_SERVER : GNUTLS_CLIENT));
        if (r < 0) {
                free(t);
                return -ENOMEM;
        }
        r = gnutls_priority_set(t->session, creds->priority) < 0 ||
                            gnutls_credentials_set(t->session, GNUTLS_CRD_CERTIFICATE,
                                                   creds->cred) < 0
                    ? -ENOMEM
                    : 0;
        if (r >= 0 && !t->server)
                r = client_setup(t, peer);
        if (r < 0) {
                tls_conn_free(t);
                return r;
        }
        gnutls_handshake_set_timeout(t->session, GNUTLS_INDEFINITE_TIMEOUT);
        gnutls_transport_set_int(t->session, fd);
        *ret = t;
        return 0;
}

struct tls_conn *tls_conn_free(struct tls_conn *t)
{
        if (!t)
                return NULL;
        t->deadline = sd_event_source_disable_unref(t->deadline);
        if (t->ready)
                (void)gnutls_bye(t->session, GNUTLS_SHUT_WR); /* non-blocking: may not go out */
        gnutls_deinit(t->session);
        free(t);
        return NULL;
}

int tls_conn_set_deadline(struct tls_conn *t, sd_event *event, uint64_t usec,
                          sd_event_time_handler_t fn, void *ud)
{
        int r;

        if (t->ready)
                return 0;
        t->deadline = sd_event_source_disable_unref(t->deadline);
        r = sd_event_add_time_relative(event, &t->deadline, CLOCK_MONOTONIC, usec, 0, fn, ud);
        if (r >= 0)
                (void)sd_event_source_set_description(t->deadline, "tls-handshake");
        return r;
}

/* Records why GnuTLS failed with g in t->error; returns the -errno for it. */
static int fail(struct tls_conn *t, int g)
{
        gnutls_datum_t out = {0};

        if (g == GNUTLS_E_CERTIFICATE_VERIFICATION_ERROR) {
                bool said = gnutls_certificate_verification_status_print(
                                    gnutls_session_get_verify_cert_status(t->session),
                                    gnutls_certificate_type_get(t->session), &out, 0) >= 0;

                snprintf(t->error, sizeof(t->error), "%s",
                         said ? (const char *)out.data : gnutls_strerror(g));
                gnutls_free(out.data);
                return -EKEYREJECTED;
        }
        if (g == GNUTLS_E_FATAL_ALERT_RECEIVED)
                snprintf(t->error, sizeof(t->error), "the peer refused: %s",
                         gnutls_alert_get_name(gnutls_alert_get(t->session)));
        else
                snprintf(t->error, sizeof(t->error), "%s", gnutls_strerror(g));
        if (g == GNUTLS_E_PREMATURE_TERMINATION || g == GNUTLS_E_PUSH_ERROR ||
            g == GNUTLS_E_PULL_ERROR)
                return -ECONNRESET;
        return -EPROTO;
}

/* Server: whether the client's first byte opens a TLS handshake, without reading it.
 * Returns 0, -EAGAIN (nothing yet), -EPROTONOSUPPORT, -ECONNRESET. */
static int look_first(struct tls_conn *t)
{
        unsigned char b;
        ssize_t n = recv(t->fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);

        if (n < 0 && (errno == EAGAIN || errno == EINTR))
                return -EAGAIN;
        if (n <= 0) {
                snprintf(t->error, sizeof(t->error), "the peer closed before the handshake");
                return -ECONNRESET;
        }
        if (b != TLS_RECORD_BYTE0) {
                snprintf(t->error, sizeof(t->error), "not a TLS client (first byte 0x%02x)", b);
                return -EPROTONOSUPPORT;
        }
        t->looked = true;
        return 0;
}

int tls_handshake(struct tls_conn *t)
{
        int g;

        if (t->ready)
                return 0;
        if (t->server && !t->looked) {
                int r = look_first(t);
                if (r < 0)
                        return r;
        }
        for (int i = 0; i < TLS_RETRIES; i++) {
                g = gnutls_handshake(t->session);
                if (g >= 0 || g == GNUTLS_E_AGAIN || gnutls_error_is_fatal(g))
                        break;
        }
        if (g == GNUTLS_E_AGAIN || (g < 0 && !gnutls_error_is_fatal(g)))
                return -EAGAIN;
        if (g < 0)
                return fail(t, g);
        t->ready = true;
        t->deadline = sd_event_source_disable_unref(t->deadline);
        return 0;
}

bool tls_ready(const struct tls_conn *t)
{
        return t->ready;
}

bool tls_wants_write(const struct tls_conn *t)
{
        return gnutls_record_get_direction(t->session) == 1;
}

ssize_t tls_read(struct tls_conn *t, void *buf, size_t len)
{
        ssize_t n;

        for (int i = 0; i < TLS_RETRIES; i++) {
                n = gnutls_record_recv(t->session, buf, len);
                if (n >= 0 || n == GNUTLS_E_AGAIN || gnutls_error_is_fatal((int)n))
                        break;
        }
        if (n == GNUTLS_E_AGAIN || (n < 0 && !gnutls_error_is_fatal((int)n)))
                return -EAGAIN;
        if (n == GNUTLS_E_PREMATURE_TERMINATION)
                return 0; /* closed without close_notify: the end all the same for lines */
        return n < 0 ? fail(t, (int)n) : n;
}

ssize_t tls_write(struct tls_conn *t, const void *buf, size_t len)
{
        size_t size = t->send_pending ? MIN(t->send_pending, len) : len;
        ssize_t n;

        do
                n = gnutls_record_send(t->session, buf, size);
        while (n == GNUTLS_E_INTERRUPTED);
        t->send_pending = n == GNUTLS_E_AGAIN ? size : 0;
        if (n == GNUTLS_E_AGAIN)
                return -EAGAIN;
        return n < 0 ? fail(t, (int)n) : n;
}

size_t tls_pending(const struct tls_conn *t)
{
        return gnutls_record_check_pending(t->session);
}

const char *tls_conn_error(const struct tls_conn *t)
{
        return t->error;
}

const char *tls_conn_describe(const struct tls_conn *t, char *buf, size_t len)
{
        const char *cipher = gnutls_cipher_get_name(gnutls_cipher_get(t->session));

        snprintf(buf, len, "%s/%s",
                 gnutls_protocol_get_name(gnutls_protocol_get_version(t->session)),
                 cipher ? cipher : "?");
        return buf;
}
