/* test-gonioctl.c - runs the real gonioctl binary and checks its exit code, stdout and
 * stderr. Group "usage": command-line errors (exit 2) and connection failures (exit 3).
 * Group "peer": gonioctl against a scripted peer that speaks the wire protocol through
 * protocol/ (hello, request params, replies, notifications, error codes -> exit codes,
 * timeouts, over-long and malformed replies, replies that do not carry the request's id;
 * Ctrl-C, SIGTERM and --timeout during a waiting move or home send `stop`).
 * Usage: test-gonioctl GONIOCTL usage|peer */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include "protocol/proto.h"
#include "tests/test.h"

#define IO_TIMEOUT_MS 10000 /* generous: a loaded machine under sanitizers */

struct srv {
        int fd;
        struct proto_lines lines;
        json_int_t requests; /* requests received: gonioctl numbers them from 1 */
};

struct scenario;
typedef void (*serve_fn)(struct srv *s, const struct scenario *sc);

struct scenario {
        const char *name;
        const char *argv[10];
        serve_fn serve; /* NULL: nobody listens */
        int code;       /* error code for serve_error; signal for serve_*_interrupted */
        int want_exit;
        const char *want_out; /* exact stdout, or NULL */
        const char *want_err; /* substring of stderr, or NULL */
        const char *reply_id; /* for serve_reply_id: the id (JSON text) the peer answers with */
};

static char tmpdir[64], sock_path[96];
static const char *ctl_path; /* the gonioctl binary under test */
static pid_t client_pid; /* the running gonioctl */

static json_t *recv_msg(struct srv *s)
{
        for (;;) {
                struct pollfd p = {.fd = s->fd, .events = POLLIN};
                struct proto_msg m;
                char buf[4096], *line, err[128];
                size_t len;
                ssize_t n;

                if (proto_lines_next(&s->lines, &line, &len) == 1) {
                        CHECK_INT(proto_parse(line, len, &m, NULL, err, sizeof(err)), 0);
                        return m.root;
                }
                CHECK_INT(poll(&p, 1, IO_TIMEOUT_MS), 1);
                n = read(s->fd, buf, sizeof(buf));
                if (n <= 0)
                        return NULL; /* the client closed the connection */
                CHECK_INT(proto_lines_feed(&s->lines, buf, (size_t)n), 0);
        }
}

/* Receives the next message and checks it is a request for method with the next id. */
static json_t *recv_request(struct srv *s, const char *method)
{
        json_t *m = recv_msg(s);

        CHECK(m);
        CHECK_STR(json_string_value(json_object_get(m, "method")), method);
        CHECK(json_is_integer(json_object_get(m, "id")));
        CHECK_INT(json_integer_value(json_object_get(m, "id")), ++s->requests);
        return m;
}

/* Writes all of data; a client that already hung up (EPIPE) is not an error here. */
static void send_raw(struct srv *s, const char *data, size_t n)
{
        while (n > 0) {
                ssize_t k = write(s->fd, data, n);

                if (k < 0 && errno == EPIPE)
                        return;
                CHECK(k > 0);
                data += k;
                n -= (size_t)k;
        }
}

static void send_msg(struct srv *s, json_t *m)
{
        size_t n;
        char *line = proto_dump(m, &n);

        CHECK(line);
        send_raw(s, line, n);
        free(line);
        json_decref(m);
}

/* Replies to req (consumed) with result (stolen). */
static void reply(struct srv *s, json_t *req, json_t *result)
{
        send_msg(s, proto_result(json_object_get(req, "id"), result));
        json_decref(req);
}

static void expect_params(json_t *req, const char *want)
{
        char *got = json_dumps(json_object_get(req, "params"), JSON_COMPACT | JSON_SORT_KEYS);

        CHECK_STR(got, want);
        free(got);
}

/* Answers hello with the given protocol version after checking what the client sent. */
static void hello(struct srv *s, int protocol)
{
        json_t *req = recv_request(s, "hello"), *p = json_object_get(req, "params");

        CHECK_INT(json_integer_value(json_object_get(p, "protocol")), PROTO_VERSION);
        CHECK(strncmp(json_string_value(json_object_get(p, "client")), "gonioctl/", 9) == 0);
        reply(s, req,
              json_pack("{s:s,s:s,s:i,s:s}", "server", "goniod", "version", "test", "protocol",
                        protocol, "rig", "test-rig"));
}

static void wait_eof(struct srv *s)
{
        json_t *m = recv_msg(s);

        CHECK(m == NULL);
}

static void serve_status(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "status");
        expect_params(req, "{}");
        /* Notifications before the reply are not printed. */
        send_msg(s, proto_notification("axis.moved", json_pack("{s:s,s:f,s:b}", "axis", "turntable",
                                                               "position", 1.5, "moving", 1)));
        reply(s, req, json_pack("{s:s,s:b}", "state", "idle", "homed", 1));
}

static void serve_move_nowait(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "move");
        expect_params(req, "{\"axis\":\"camera_arm\",\"position\":-10.5,\"relative\":true,"
                           "\"wait\":false}");
        reply(s, req, json_pack("{s:s,s:f}", "axis", "camera_arm", "target", -20.5));
}

static void serve_move(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "move");
        expect_params(req, "{\"axis\":\"turntable\",\"position\":90.0,\"relative\":false,"
                           "\"wait\":true}");
        send_msg(s, proto_notification("move.done", json_pack("{s:s,s:f}", "axis", "turntable",
                                                              "position", 90.0)));
        reply(s, req, json_pack("{s:s,s:f}", "axis", "turntable", "position", 90.0));
}

static void serve_home(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "home");
        expect_params(req, "{\"axes\":[\"turntable\",\"light_arm\"]}");
        reply(s, req,
              json_pack("{s:[{s:s,s:f},{s:s,s:f}]}", "axes", "name", "turntable", "position", 0.0,
                        "name", "light_arm", "position", -12.25));
}

static void serve_capture(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "capture");
        expect_params(req, "{\"bits\":16,\"camera\":\"cam1\",\"exposure_us\":5000,\"gain\":2.0}");
        reply(s, req, json_pack("{s:[]}", "captures"));
}

static void serve_dataset_create(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "dataset.open");
        expect_params(req, "{\"create\":true,\"name\":\"gem1\"}");
        reply(s, req, json_pack("{s:s,s:s,s:i}", "path", "/data/gem1", "name", "gem1", "count", 0));
}

static void serve_call(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "dataset.info");
        expect_params(req, "{\"name\":\"x\"}");
        reply(s, req, json_pack("{s:s,s:i}", "name", "x", "count", 3));
}

/* lamp lamp9 on -> the scenario's error code. */
static void serve_error(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "lamp.set");
        expect_params(req, "{\"lamp\":\"lamp9\",\"on\":true}");
        send_msg(s, proto_error(json_object_get(req, "id"), sc->code, "boom", NULL));
        json_decref(req);
}

static void serve_lamp_index(struct srv *s, const struct scenario *sc)
{
        json_t *req;

        hello(s, PROTO_VERSION);
        req = recv_request(s, "lamp.set");
        expect_params(req, "{\"lamp\":2,\"on\":false}");
        reply(s, req, json_pack("{s:s,s:b}", "lamp", "lamp2", "on", 0));
}

static void serve_bad_protocol(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION + 1);
        wait_eof(s);
}

/* Takes the request and never answers: the client must give up on its own. */
static void serve_silent(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        json_decref(recv_request(s, "status"));
        wait_eof(s);
}

static void serve_hangup(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        json_decref(recv_request(s, "status"));
}

static void serve_overlong(struct srv *s, const struct scenario *sc)
{
        size_t n = PROTO_MAX_LINE + 100;
        char *junk = malloc(n);

        CHECK(junk);
        hello(s, PROTO_VERSION);
        json_decref(recv_request(s, "status"));
        memset(junk, ' ', n);
        junk[n - 1] = '\n';
        send_raw(s, junk, n);
        free(junk);
        wait_eof(s);
}

static void serve_garbage(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        json_decref(recv_request(s, "status"));
        send_raw(s, "{\"jsonrpc\":\"2.0\",\"id\":2,\"result\n", 33);
        wait_eof(s);
}

/* Answers status with the scenario's reply_id instead of the request's: an error with
 * the scenario's code, or a result when the code is 0. */
static void serve_reply_id(struct srv *s, const struct scenario *sc)
{
        json_t *id = json_loads(sc->reply_id, JSON_DECODE_ANY, NULL);

        CHECK(id);
        hello(s, PROTO_VERSION);
        json_decref(recv_request(s, "status"));
        if (sc->code)
                send_msg(s, proto_error(id, sc->code, "line unreadable", NULL));
        else
                send_msg(s, proto_result(id, json_pack("{s:s}", "state", "idle")));
        json_decref(id);
        wait_eof(s);
}

static void serve_watch(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        send_msg(s, proto_notification("state.changed", json_pack("{s:s}", "state", "moving")));
        send_msg(s, proto_notification("axis.moved", json_pack("{s:s,s:f,s:b}", "axis", "turntable",
                                                               "position", 2.5, "moving", 1)));
        send_msg(s, proto_notification("state.changed", json_pack("{s:s}", "state", "idle")));
        wait_eof(s);
}

/* A reply arrives while watch has no request outstanding (hello's id, answered twice). */
static void serve_watch_stray_reply(struct srv *s, const struct scenario *sc)
{
        json_t *id = json_integer(1);

        hello(s, PROTO_VERSION);
        send_msg(s, proto_result(id, NULL));
        json_decref(id);
        wait_eof(s);
}

/* After the waiting request req was interrupted (by signal sc->code sent here, or by the
 * client's --timeout when 0): expects `stop`, answers it and cancels req as goniod does
 * (the cancel before or after stop's reply), then answers `status` with the positions. */
static void expect_stop(struct srv *s, const struct scenario *sc, json_t *req, bool cancel_first)
{
        json_t *stop, *cancel;

        if (sc->code)
                CHECK_INT(kill(client_pid, sc->code), 0);
        stop = recv_request(s, "stop");
        expect_params(stop, "{}");
        cancel =
                proto_error(json_object_get(req, "id"), PROTO_E_CANCELED, "canceled by stop", NULL);
        if (cancel_first)
                send_msg(s, cancel);
        reply(s, stop, json_pack("{s:[s]}", "stopped", "turntable"));
        if (!cancel_first)
                send_msg(s, cancel);
        json_decref(req);
        reply(s, recv_request(s, "status"),
              json_pack("{s:s,s:[{s:s,s:f},{s:s,s:f}]}", "state", "idle", "axes", "name",
                        "turntable", "position", 42.125, "name", "light_arm", "position", 2.5));
        wait_eof(s);
}

static void serve_move_interrupted(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        expect_stop(s, sc, recv_request(s, "move"), false);
}

static void serve_home_interrupted(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        expect_stop(s, sc, recv_request(s, "home"), true);
}

/* The client's --timeout expires, and its stop is never answered either. */
static void serve_stop_unanswered(struct srv *s, const struct scenario *sc)
{
        hello(s, PROTO_VERSION);
        json_decref(recv_request(s, "move"));
        json_decref(recv_request(s, "stop"));
        wait_eof(s);
}

#define ERR(c, e)                                                                                  \
        {                                                                                          \
                "error " #c, {"lamp", "lamp9", "on"}, serve_error, c, e, "",                       \
                        "gonioctl: lamp.set: boom\n"                                               \
        }

/* status answered with id (JSON text) and error code c (0: a result): exit 4, stderr e */
#define REPLY_ID(what, c, id, e)                                                                   \
        {                                                                                          \
                "reply id " what, {"status"}, serve_reply_id, c, 4, "", e, id                      \
        }

static const struct scenario usage_scenarios[] = {
        {"no command", {NULL}, NULL, 0, 2, "", "missing command"},
        {"unknown command", {"frobnicate"}, NULL, 0, 2, "", "frobnicate: unknown command"},
        {"unknown option", {"--frob", "status"}, NULL, 0, 2, "", "unknown option"},
        {"missing subcommand", {"dataset"}, NULL, 0, 2, "", "missing subcommand"},
        {"unknown subcommand", {"fault", "raise"}, NULL, 0, 2, "", "unknown subcommand"},
        {"move without DEG", {"move", "turntable"}, NULL, 0, 2, "", "missing arguments"},
        {"move bad DEG", {"move", "turntable", "ten"}, NULL, 0, 2, "", "invalid position"},
        {"move extra arg", {"move", "t", "1", "2"}, NULL, 0, 2, "", "unexpected argument"},
        {"option not taken", {"status", "--relative"}, NULL, 0, 2, "", "does not take"},
        {"lamp bad state", {"lamp", "0", "dim"}, NULL, 0, 2, "", "expected on or off"},
        {"laser missing", {"laser"}, NULL, 0, 2, "", "missing arguments"},
        {"bits 12", {"capture", "--bits", "12"}, NULL, 0, 2, "", "invalid value"},
        {"exposure 0", {"capture", "--exposure=0"}, NULL, 0, 2, "", "invalid value"},
        {"timeout -1", {"--timeout", "-1", "status"}, NULL, 0, 2, "", "invalid value"},
        {"timeout no value", {"status", "--timeout"}, NULL, 0, 2, "", "needs a value"},
        {"json takes no value", {"--json=1", "status"}, NULL, 0, 2, "", "takes no value"},
        {"call bad JSON", {"call", "status", "{"}, NULL, 0, 2, "", "JSON object or array"},
        {"watch count 0", {"watch", "--count", "0"}, NULL, 0, 2, "", "invalid value"},
        {"help", {"--help"}, NULL, 0, 0, NULL, NULL},
        {"no socket", {"status"}, NULL, 0, 3, "", "gonioctl: connect: "},
        {"negative DEG is not an option",
         {"move", "camera_arm", "-10"},
         NULL,
         0,
         3,
         "",
         "gonioctl: connect: "},
};

static const struct scenario peer_scenarios[] = {
        {"status --json",
         {"--json", "status"},
         serve_status,
         0,
         0,
         "{\"state\":\"idle\",\"homed\":true}\n",
         NULL},
        {"move --no-wait",
         {"--json", "move", "camera_arm", "-10.5", "--relative", "--no-wait"},
         serve_move_nowait,
         0,
         0,
         "{\"axis\":\"camera_arm\",\"target\":-20.5}\n",
         NULL},
        {"move human", {"move", "turntable", "90"}, serve_move, 0, 0, "turntable 90.000\n", NULL},
        {"home human",
         {"home", "turntable", "light_arm"},
         serve_home,
         0,
         0,
         "AXIS       POSITION\nturntable     0.000\nlight_arm   -12.250\n",
         NULL},
        {"capture options",
         {"--quiet", "capture", "--camera", "cam1", "--exposure", "5000", "--gain=2", "--bits",
          "16"},
         serve_capture,
         0,
         0,
         "",
         NULL},
        {"dataset create",
         {"dataset", "create", "gem1"},
         serve_dataset_create,
         0,
         0,
         "dataset gem1: 0 captures in /data/gem1\n",
         NULL},
        {"call",
         {"--json", "call", "dataset.info", "{\"name\":\"x\"}"},
         serve_call,
         0,
         0,
         "{\"name\":\"x\",\"count\":3}\n",
         NULL},
        {"lamp index", {"lamp", "2", "off"}, serve_lamp_index, 0, 0, "lamp2 off\n", NULL},
        ERR(PROTO_E_DEVICE, 5),
        ERR(PROTO_E_TIMEOUT, 5),
        ERR(PROTO_INVALID_PARAMS, 6),
        ERR(PROTO_E_RANGE, 6),
        ERR(PROTO_E_NOT_FOUND, 6),
        ERR(PROTO_METHOD_NOT_FOUND, 6),
        ERR(PROTO_E_STORAGE, 7),
        ERR(PROTO_E_CANCELED, 8),
        ERR(PROTO_E_BUSY, 9),
        ERR(PROTO_E_STATE, 9),
        ERR(PROTO_INTERNAL_ERROR, 4),
        ERR(PROTO_INVALID_REQUEST, 4),
        {"protocol mismatch",
         {"status"},
         serve_bad_protocol,
         0,
         4,
         "",
         "gonioctl: hello: goniod speaks protocol 2"},
        {"reply timeout",
         {"--timeout", "0.5", "status"},
         serve_silent,
         0,
         4,
         "",
         "gonioctl: status: timed out"},
        {"hangup", {"status"}, serve_hangup, 0, 4, "", "gonioctl: status: connection closed"},
        {"over-long reply", {"status"}, serve_overlong, 0, 4, "", "longer than 65536"},
        {"malformed reply", {"status"}, serve_garbage, 0, 4, "", "bad message"},
        /* documented: an error the server sends with id null when it cannot read a request */
        REPLY_ID("null, line too long", PROTO_E_LINE_TOO_LONG, "null", "status: line unreadable"),
        REPLY_ID("null, parse error", PROTO_PARSE_ERROR, "null", "status: line unreadable"),
        REPLY_ID("null, invalid request", PROTO_INVALID_REQUEST, "null", "status: line unreadable"),
        /* anything else that does not carry the request's id (2) is a protocol error */
        REPLY_ID("null, result", 0, "null", "reply with id null to request 2"),
        REPLY_ID("null, device error", PROTO_E_DEVICE, "null", "reply with id null to request 2"),
        REPLY_ID("null, not found", PROTO_E_NOT_FOUND, "null", "reply with id null to request 2"),
        REPLY_ID("1, result", 0, "1", "reply with id 1 to request 2"),
        REPLY_ID("3, result", 0, "3", "reply with id 3 to request 2"),
        REPLY_ID("3, range error", PROTO_E_RANGE, "3", "reply with id 3 to request 2"),
        REPLY_ID("\"2\", result", 0, "\"2\"", "reply with id \"2\" to request 2"),
        REPLY_ID("\"2\", busy error", PROTO_E_BUSY, "\"2\"", "reply with id \"2\" to request 2"),
        {"watch: a reply with no request outstanding",
         {"watch"},
         serve_watch_stray_reply,
         0,
         4,
         "",
         "reply with id 1, no request outstanding"},
        {"move Ctrl-C",
         {"move", "turntable", "90"},
         serve_move_interrupted,
         SIGINT,
         10,
         "",
         "gonioctl: move: interrupted: stopped turntable at 42.125 (Ctrl-C; stop halts every "
         "axis of the rig)\n"},
        {"move --timeout",
         {"--timeout", "0.3", "move", "turntable", "90"},
         serve_move_interrupted,
         0,
         10,
         "",
         "gonioctl: move: interrupted: stopped turntable at 42.125 (no reply within 0.3 s; "},
        {"move Ctrl-C --json",
         {"--json", "move", "turntable", "90"},
         serve_move_interrupted,
         SIGINT,
         10,
         "{\"error\":{\"code\":\"interrupted\",\"message\":\"interrupted: stopped turntable at "
         "42.125 (Ctrl-C; stop halts every axis of the rig)\",\"cause\":\"SIGINT\",\"stopped\":"
         "[{\"axis\":\"turntable\",\"position\":42.125}]}}\n",
         "interrupted: stopped turntable"},
        {"home SIGTERM",
         {"home"},
         serve_home_interrupted,
         SIGTERM,
         10,
         "",
         "gonioctl: home: interrupted: stopped turntable at 42.125, light_arm at 2.500 (SIGTERM; "},
        {"stop unanswered",
         {"--timeout", "0.3", "move", "turntable", "90"},
         serve_stop_unanswered,
         0,
         4,
         "",
         "gonioctl: move: interrupted (no reply within 0.3 s), but stop failed: no reply; the "
         "axes may still be moving"},
        {"watch --count",
         {"--json", "watch", "--count", "2"},
         serve_watch,
         0,
         0,
         "{\"method\":\"state.changed\",\"params\":{\"state\":\"moving\"}}\n"
         "{\"method\":\"axis.moved\",\"params\":{\"axis\":\"turntable\",\"position\":2.5,"
         "\"moving\":true}}\n",
         NULL},
};

static char *slurp(const char *path)
{
        FILE *f = fopen(path, "re");
        char *s = calloc(1, 65536);

        CHECK(f && s);
        CHECK(fread(s, 1, 65535, f) < 65535);
        fclose(f);
        return s;
}

static pid_t spawn(const char *gonioctl, const struct scenario *sc, const char *out,
                   const char *err)
{
        const char *argv[16] = {gonioctl, "--socket", sock_path};
        posix_spawn_file_actions_t fa;
        extern char **environ;
        int n = 3;
        pid_t pid;

        for (int i = 0; sc->argv[i]; i++)
                argv[n++] = sc->argv[i];
        CHECK_INT(posix_spawn_file_actions_init(&fa), 0);
        CHECK_INT(posix_spawn_file_actions_addopen(&fa, 1, out, O_WRONLY | O_CREAT | O_TRUNC, 0600),
                  0);
        CHECK_INT(posix_spawn_file_actions_addopen(&fa, 2, err, O_WRONLY | O_CREAT | O_TRUNC, 0600),
                  0);
        CHECK_INT(posix_spawn(&pid, gonioctl, &fa, NULL, (char **)argv, environ), 0);
        posix_spawn_file_actions_destroy(&fa);
        return pid;
}

static void serve_one(int lfd, const struct scenario *sc)
{
        struct pollfd p = {.fd = lfd, .events = POLLIN};
        struct srv s = {};

        CHECK_INT(poll(&p, 1, IO_TIMEOUT_MS), 1);
        s.fd = accept4(lfd, NULL, NULL, SOCK_CLOEXEC);
        CHECK(s.fd >= 0);
        sc->serve(&s, sc);
        close(s.fd);
        proto_lines_done(&s.lines);
}

static void run(const char *gonioctl, const struct scenario *sc, int lfd)
{
        char out[96], err[96], *o, *e;
        int status;
        pid_t pid;

        snprintf(out, sizeof(out), "%s/out", tmpdir);
        snprintf(err, sizeof(err), "%s/err", tmpdir);
        pid = spawn(gonioctl, sc, out, err);
        client_pid = pid;
        if (sc->serve)
                serve_one(lfd, sc);
        CHECK_INT(waitpid(pid, &status, 0), pid);
        o = slurp(out);
        e = slurp(err);
        if (!WIFEXITED(status) || WEXITSTATUS(status) != sc->want_exit ||
            (sc->want_out && strcmp(o, sc->want_out) != 0) ||
            (sc->want_err && !strstr(e, sc->want_err))) {
                fprintf(stderr, "scenario '%s': status 0x%x\nstdout:\n%s\nstderr:\n%s\n", sc->name,
                        status, o, e);
                CHECK_INT(WIFEXITED(status) ? WEXITSTATUS(status) : -1, sc->want_exit);
                CHECK(!"output differs");
        }
        printf("ok - %s\n", sc->name);
        free(o);
        free(e);
}

/* A socket bound at sock_path, listening when listening is set. */
static int bound_socket(bool listening)
{
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

        CHECK(fd >= 0);
        snprintf(sa.sun_path, sizeof(sa.sun_path), "%s", sock_path);
        CHECK_INT(bind(fd, (struct sockaddr *)&sa, sizeof(sa)), 0);
        if (listening)
                CHECK_INT(listen(fd, 4), 0);
        return fd;
}

static const struct scenario refused = {"connection refused", {"status"}, NULL, 0, 3, "",
                                        "Connection refused"};

/* The scratch directory for the socket and gonioctl's captured output. */
static void scratch_make(void)
{
        snprintf(tmpdir, sizeof(tmpdir), "/tmp/test-gonioctl-XXXXXX");
        CHECK(mkdtemp(tmpdir));
        snprintf(sock_path, sizeof(sock_path), "%s/goniod.sock", tmpdir);
}

static void scratch_remove(void)
{
        char path[128];

        unlink(sock_path);
        snprintf(path, sizeof(path), "%s/out", tmpdir);
        unlink(path);
        snprintf(path, sizeof(path), "%s/err", tmpdir);
        unlink(path);
        CHECK_INT(rmdir(tmpdir), 0);
}

static void test_usage(void)
{
        int lfd;

        scratch_make();
        for (size_t i = 0; i < sizeof(usage_scenarios) / sizeof(usage_scenarios[0]); i++)
                run(ctl_path, &usage_scenarios[i], -1);
        lfd = bound_socket(false); /* a stale socket file: nobody accepts */
        run(ctl_path, &refused, -1);
        close(lfd);
        scratch_remove();
}

static void test_peer(void)
{
        int lfd;

        scratch_make();
        lfd = bound_socket(true);
        for (size_t i = 0; i < sizeof(peer_scenarios) / sizeof(peer_scenarios[0]); i++)
                run(ctl_path, &peer_scenarios[i], lfd);
        close(lfd);
        scratch_remove();
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"usage", test_usage},
                {"peer", test_peer},
        };

        CHECK(argc >= 2);
        signal(SIGPIPE, SIG_IGN);
        ctl_path = argv[1];
        argv[1] = argv[0]; /* the group, if any, becomes the case name */
        return TEST_RUN_CASES(cases, argc - 1, argv + 1);
}
