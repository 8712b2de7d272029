/* main.c - goniod: the gonio capture daemon (see docs/goniod.md). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/log.h"
#include "gonio_version.h"
#include "manager.h"
#include "protocol/proto.h"
#include "preview.h"
#include "tls.h"
#include "web.h"

static void usage(FILE *f)
{
        fprintf(f,
                "Usage: goniod --rig FILE [--socket PATH] [--admin-socket PATH] [--data DIR]\n"
                "              [--verbose]\n"
                "\n"
                "  --rig FILE     rig file (YAML) describing the devices\n"
                "  --socket PATH  control socket (default $GONIO_SOCKET, else\n"
                "                 $XDG_RUNTIME_DIR/gonio/goniod.sock, else "
                "/run/gonio/goniod.sock)\n"
                "  --admin-socket PATH\n"
                "                 admin socket, mode 0600 (default admin.sock beside the\n"
                "                 control socket)\n"
                "                 (both taken from systemd instead when socket-activated)\n"
                "  --data DIR     directory of datasets (default $GONIO_DATA or /var/lib/gonio)\n"
                "  --listen-tcp HOST:PORT\n"
                "                 also listen on TCP (loopback only without TLS;\n"
                "                 $GONIO_LISTEN_TCP)\n"
                "  --tls-cert FILE, --tls-key FILE\n"
                "                 TLS only on TCP and HTTPS only for the dashboard, with this\n"
                "                 certificate and key (PEM; $GONIO_TLS_CERT, $GONIO_TLS_KEY)\n"
                "  --listen-http HOST:PORT\n"
                "                 serve the dashboard over HTTP (loopback only without TLS;\n"
                "                 $GONIO_LISTEN_HTTP)\n"
                "  --preview-fps N\n"
                "                 live pictures a second per camera, 1 to 10 (default 4;\n"
                "                 $GONIO_PREVIEW_FPS)\n"
                "  --token-file FILE\n"
                "                 the token a TCP client gives in hello, and the\n"
                "                 dashboard's ($GONIO_TOKEN_FILE)\n"
                "  --verbose      debug logging\n"
                "  --version      print the version and exit\n");
}

/* Picks the default socket path (protocol/proto.h) and creates its directory. */
static void default_socket(char *out, size_t len)
{
        char *slash;

        proto_socket_path(out, len);
        slash = strrchr(out, '/');
        if (slash && slash != out) {
                *slash = 0;
                (void)mkdir(out, 0770);
                *slash = '/';
        }
}

/* The admin socket beside the control socket sock: "DIR/admin.sock". */
static void default_admin(const char *sock, char *out, size_t len)
{
        const char *slash = strrchr(sock, '/');

        snprintf(out, len, "%.*sadmin.sock", slash ? (int)(slash - sock + 1) : 0, sock);
}

/* The token of token_file (its first line) into token (len bytes) for the listener what at
 * addr. Returns 0 or -errno (logged). */
static int read_token(const char *what, const char *addr, const char *token_file, char *token,
                      size_t len)
{
        FILE *f = token_file && *token_file ? fopen(token_file, "re") : NULL;

        if (!token_file || !*token_file)
                return log_error_errno(EINVAL, "%s %s needs a token: --token-file FILE", what,
                                       addr);
        if (!f)
                return log_error_errno(errno, "%s %s: token file %s: %m", what, addr, token_file);
        if (!fgets(token, len, f))
                token[0] = 0;
        fclose(f);
        token[strcspn(token, "\r\n")] = 0;
        return 0;
}

/* What goniod serves beyond its Unix sockets (options and environment). */
struct remote {
        const char *tcp, *token_file, *cert, *key; /* the TCP listener */
        const char *http, *fps;                    /* the dashboard */
};

/* The server credentials of --tls-cert and --tls-key into *ret, loaded once for both
 * listeners of o (NULL: no TLS asked for, or no listener to use it). Returns 0 or -errno
 * (logged, naming the file at fault). */
static int load_creds(const struct remote *o, struct tls_creds **ret)
{
        bool tcp = o->tcp && *o->tcp, http = o->http && *o->http;
        const char *what = tcp ? "TCP listener" : "HTTP listener", *addr = tcp ? o->tcp : o->http;
        char err[600];
        int r;

        *ret = NULL;
        if ((!o->cert || !*o->cert) && (!o->key || !*o->key))
                return 0;
        if (!tcp && !http) {
                log_notice("a TLS certificate or key without --listen-tcp or --listen-http: "
                           "nothing listens on TCP, ignoring them");
                return 0;
        }
        if (!o->cert || !*o->cert || !o->key || !*o->key)
                return log_error_errno(EINVAL,
                                       "%s %s: TLS needs both a certificate (--tls-cert FILE) "
                                       "and its key (--tls-key FILE)",
                                       what, addr);
        r = tls_creds_new_server(o->cert, o->key, ret, err, sizeof(err));
        return r < 0 ? log_error_errno(r, "%s %s: TLS: %s", what, addr, err) : 0;
}

/* The TCP listener and the dashboard, where asked for, with TLS when o has credentials (into
 * *tls: the caller frees them after m). Returns 0 or -errno (logged). */
static int listen_remote(struct manager *m, const struct remote *o, struct tls_creds **tls)
{
        const char *timeout = getenv("GONIO_HTTP_TIMEOUT_MS");
        char token[256] = "";
        int r = load_creds(o, tls);

        if (r >= 0 && o->tcp && *o->tcp &&
            (r = read_token("TCP listener", o->tcp, o->token_file, token, sizeof(token))) >= 0)
                r = server_listen_tcp(m->server, o->tcp, token, *tls);
        if (o->fps && (atoi(o->fps) < 1 || atoi(o->fps) > PREVIEW_MAX_FPS))
                return log_error_errno(EINVAL, "--preview-fps %s: expected 1 to %d", o->fps,
                                       PREVIEW_MAX_FPS);
        if (r >= 0 && o->http && *o->http &&
            (r = read_token("HTTP listener", o->http, o->token_file, token, sizeof(token))) >= 0)
                r = web_new(m, o->http, token, *tls, o->fps ? (unsigned)atoi(o->fps) : 0,
                            timeout ? strtoull(timeout, NULL, 10) * 1000 : 0, &m->web);
        return r;
}

int main(int argc, char **argv)
{
        static const struct option opts[] = {
                {"rig", required_argument, NULL, 'r'},
                {"socket", required_argument, NULL, 's'},
                {"admin-socket", required_argument, NULL, 'a'},
                {"data", required_argument, NULL, 'd'},
                {"verbose", no_argument, NULL, 'v'},
                {"help", no_argument, NULL, 'h'},
                {"version", no_argument, NULL, 'V'},
                {"listen-tcp", required_argument, NULL, 't'},
                {"token-file", required_argument, NULL, 'k'},
                {"tls-cert", required_argument, NULL, 'C'},
                {"tls-key", required_argument, NULL, 'K'},
                {"listen-http", required_argument, NULL, 'H'},
                {"preview-fps", required_argument, NULL, 'F'},
                {},
        };
        struct remote o = {.tcp = getenv("GONIO_LISTEN_TCP"),
                           .token_file = getenv("GONIO_TOKEN_FILE"),
                           .cert = getenv("GONIO_TLS_CERT"),
                           .key = getenv("GONIO_TLS_KEY"),
                           .http = getenv("GONIO_LISTEN_HTTP"),
                           .fps = getenv("GONIO_PREVIEW_FPS")};
        const char *rig = NULL, *data = getenv("GONIO_DATA");
        char sock[PATH_MAX] = "", admin[PATH_MAX] = "";
        struct manager *m = NULL;
        struct tls_creds *tls = NULL;
        int c, r;

        gn_log_set_ident("goniod");
        while ((c = getopt_long(argc, argv, "r:s:a:d:vhVt:k:C:K:H:F:", opts, NULL)) >= 0) {
                switch (c) {
                case 'r':
                        rig = optarg;
                        break;
                case 's':
                        snprintf(sock, sizeof(sock), "%s", optarg);
                        break;
                case 'a':
                        snprintf(admin, sizeof(admin), "%s", optarg);
                        break;
                case 'd':
                        data = optarg;
                        break;
                case 't':
                        o.tcp = optarg;
                        break;
                case 'k':
                        o.token_file = optarg;
                        break;
                case 'C':
                        o.cert = optarg;
                        break;
                case 'K':
                        o.key = optarg;
                        break;
                case 'H':
                        o.http = optarg;
                        break;
                case 'F':
                        o.fps = optarg;
                        break;
                case 'v':
                        gn_log_set_level(GN_LOG_DEBUG);
                        break;
                case 'h':
                        usage(stdout);
                        return 0;
                case 'V':
                        printf("goniod %s (protocol %d)\n", GONIO_VERSION, PROTO_VERSION);
                        return 0;
                default:
                        usage(stderr);
                        return 2;
                }
        }
        if (!rig || optind < argc) {
                usage(stderr);
                return 2;
        }
        if (!sock[0])
                default_socket(sock, sizeof(sock));
        if (!admin[0])
                default_admin(sock, admin, sizeof(admin));
        r = manager_new(rig, sock, admin, data && *data ? data : "/var/lib/gonio", &m);
        if (r < 0) {
                log_error_errno(r, "cannot start: %m");
                return 1;
        }
        if ((r = listen_remote(m, &o, &tls)) < 0) {
                manager_free(m);
                tls_creds_free(tls);
                return 1;
        }
        r = manager_run(m);
        if (r < 0)
                log_error_errno(r, "the event loop failed: %m");
        manager_free(m);
        tls_creds_free(tls); /* after the listeners that use them */
        log_info("stopped");
        return r < 0 ? 1 : 0;
}
