/* tls.h - TLS (1.2 or 1.3, 1.3 preferred) over a non-blocking stream socket, with GnuTLS:
 * the transport of goniod's TCP listener (daemon/server.c) and of gonioctl's --connect
 * (client/conn.c). It knows nothing of what it carries, so any listener (a web one too)
 * can use it.
 *
 * Credentials (struct tls_creds) come first: a server's certificate and key, or the CAs a
 * client trusts. Each connection (struct tls_conn) wraps a socket the caller owns and
 * polls: tls_handshake, tls_read and tls_write never block; after -EAGAIN the caller waits
 * for the socket to be writable when tls_wants_write() says so, else readable, and calls
 * again. Data GnuTLS has already decrypted (tls_pending) does not make the socket readable:
 * read it before waiting. A server connection whose handshake does not end in time is the
 * caller's to close, on the timer tls_conn_set_deadline arms. Errors are -errno; the text
 * of the last one is tls_conn_error(). Single-threaded: one connection per thread at a time. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>
#include <systemd/sd-event.h>

/* How long a server gives a client to end its handshake (a client that stalls, or trickles
 * bytes, is dropped then). */
#define TLS_HANDSHAKE_USEC (10 * 1000000ULL)
/* Bytes of a certificate, key or CA file at most. */
#define TLS_MAX_FILE (1024 * 1024)

struct tls_creds;
struct tls_conn;

/* A server's credentials from cert_file (PEM: the certificate, then its chain) and key_file
 * (PEM private key). Returns 0 and *ret (tls_creds_free it), or -errno of reading a file
 * (-ENOENT, -EACCES...), -EBADMSG (no PEM certificate or key in it), -EKEYREJECTED (the key
 * is not the certificate's), -ENOMEM; err (errlen bytes) then names the file and the cause. */
int tls_creds_new_server(const char *cert_file, const char *key_file, struct tls_creds **ret,
                         char *err, size_t errlen);

/* A client's credentials: the certificates of ca_file (PEM) are trusted, or the system's
 * trust store when ca_file is NULL. Returns 0 and *ret, or -errno of reading the file,
 * -EBADMSG (no certificate in it), -ENOMEM, with err saying why as above. */
int tls_creds_new_client(const char *ca_file, struct tls_creds **ret, char *err, size_t errlen);

/* Frees creds (no connection may use them any more). NULL is a no-op. Returns NULL. */
struct tls_creds *tls_creds_free(struct tls_creds *creds);

/* A connection over fd (borrowed: a connected, non-blocking stream socket, closed by the
 * caller after tls_conn_free), server or client side as creds are. A client checks that the
 * server's certificate chains to its CAs and names peer (a host name or an IP address;
 * NULL: any name). Returns 0 and *ret, or -ENOMEM / -EINVAL. */
int tls_conn_new(const struct tls_creds *creds, int fd, const char *peer, struct tls_conn **ret);

/* Frees t after a best-effort close_notify (never blocks); its deadline goes too. NULL is a
 * no-op. Returns NULL. */
struct tls_conn *tls_conn_free(struct tls_conn *t);

/* Arms a timer on event that calls fn(source, usec, ud) usec from now unless the handshake
 * of t ended before (then, or at tls_conn_free, the timer is removed). fn typically closes
 * the connection: it may free t. Returns 0 or -errno of sd-event. */
int tls_conn_set_deadline(struct tls_conn *t, sd_event *event, uint64_t usec,
                          sd_event_time_handler_t fn, void *ud);

/* Runs the handshake as far as the socket allows. Returns 0 once it has ended (at once
 * after that), -EAGAIN to be called again when the socket is ready (tls_wants_write),
 * -EPROTONOSUPPORT on a server when the client's first byte is not a TLS handshake (a
 * client without TLS; nothing was read: the caller may answer it in plain text),
 * -EKEYREJECTED on a client when the server's certificate is not trusted or does not name
 * peer, -ECONNRESET when the peer closed, -EPROTO for any other failure of TLS. */
int tls_handshake(struct tls_conn *t);

/* Whether the handshake has ended. */
bool tls_ready(const struct tls_conn *t);

/* After -EAGAIN: whether the call waits for the socket to be writable (else readable). */
bool tls_wants_write(const struct tls_conn *t);

/* Reads up to len bytes of data (after the handshake). Returns how many, 0 at the end of
 * the stream (the peer closed, with close_notify or without), -EAGAIN, -ECONNRESET or
 * -EPROTO. */
ssize_t tls_read(struct tls_conn *t, void *buf, size_t len);

/* Writes up to len bytes (after the handshake). Returns how many were taken (a record at
 * most: call again for the rest), -EAGAIN, -ECONNRESET or -EPROTO. After -EAGAIN the
 * next call must start with the same bytes (more may follow them): GnuTLS holds their
 * record, and returns their count once it went out. */
ssize_t tls_write(struct tls_conn *t, const void *buf, size_t len);

/* Bytes decrypted and not read yet: readable with tls_read though the socket may not be. */
size_t tls_pending(const struct tls_conn *t);

/* What the last failure of t was ("" before any), e.g. "The certificate is NOT trusted.
 * The certificate issuer is unknown." Valid until the next call on t. */
const char *tls_conn_error(const struct tls_conn *t);

/* The version and cipher suite of t after its handshake, e.g. "TLS1.3/AES-256-GCM". */
const char *tls_conn_describe(const struct tls_conn *t, char *buf, size_t len);
