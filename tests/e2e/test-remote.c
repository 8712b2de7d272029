/* test-remote.c - goniod's TCP listener (docs/goniod.md, "Remote access") on gonio-sim:
 * loopback only, every request refused until hello gives the token, a wrong token refused
 * and the third closes the connection, the token's client then served as any operator
 * (status, a move), the Unix socket unchanged; an address beyond loopback, or no token,
 * stops goniod at its start with the reason. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "harness.h"
#include "tests/test.h"

#define TOKEN "a-token-of-twenty-six-chars"

struct tcp_env {
        char addr[64], token_file[400];
};

static void tcp_env(void *ud)
{
        struct tcp_env *t = ud;

        setenv("GONIO_LISTEN_TCP", t->addr, 1);
        setenv("GONIO_TOKEN_FILE", t->token_file, 1);
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

int main(int argc, char **argv)
{
        static const char status[] = "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"status\"}\n";
        struct rigenv e;
        struct tcp_env t;
        char buf[400];
        int port = 20000 + getpid() % 20000, fd, unix_fd;

        CHECK(argc == 4);
        rigenv_start_sim(&e, argv, 10);
        snprintf(t.token_file, sizeof(t.token_file), "%s/token", e.dir);
        write_file(t.token_file, TOKEN "\n");
        snprintf(t.addr, sizeof(t.addr), "0.0.0.0:%d", port);
        start_refused(&e, &t, "not a loopback address");
        snprintf(t.addr, sizeof(t.addr), "127.0.0.1:%d", port);
        write_file(t.token_file, "short\n");
        start_refused(&e, &t, "the token must be 16 to 127 characters");
        write_file(t.token_file, TOKEN "\n");
        rigenv_spawn_daemon(&e, e.sock, tcp_env, &t);
        fd = tcp_connect(port);
        refused(fd, status, "say hello with the token first");
        refused(fd, hello(NULL, buf, sizeof(buf)), "wrong or missing token");
        ok(fd, hello(TOKEN, buf, sizeof(buf)));
        ok(fd, status);
        ok(fd, "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"home\"}\n");
        close(fd);
        fd = tcp_connect(port); /* three wrong tokens: closed */
        for (int i = 0; i < 2; i++)
                refused(fd, hello("a-wrong-token-of-some-length", buf, sizeof(buf)), "wrong");
        CHECK(write(fd, hello("x", buf, sizeof(buf)), strlen(buf)) > 0);
        usleep(300000);
        CHECK(recv(fd, buf, sizeof(buf), 0) >= 0); /* the error line, then end of file */
        CHECK(recv(fd, buf, sizeof(buf), 0) == 0);
        close(fd);
        unix_fd = raw_connect(&e); /* the Unix socket needs no token */
        ok(unix_fd, status);
        close(unix_fd);
        rigenv_stop(&e);
        return 0;
}
