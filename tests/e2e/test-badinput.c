/* test-badinput.c - malformed and hostile input to goniod: each gets a clear
 * error, nothing moves, and the daemon keeps serving every client. A bad rig
 * file stops goniod at start with file, line and key. Moves can be stopped, and
 * the socket answers while axes move. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "common/cleanup.h"
#include "harness.h"
#include "tests/test.h"

static long error_code(json_t *reply)
{
        return json_integer_value(json_object_get(json_object_get(reply, "error"), "code"));
}

static void expect_error(int fd, const char *text, long code, const char *msg_part)
{
        json_t *r = raw_call(fd, text);
        const char *msg =
                json_string_value(json_object_get(json_object_get(r, "error"), "message"));

        if (error_code(r) != code || !msg || !strstr(msg, msg_part))
                fprintf(stderr, "for %s got %s\n", text, json_dumps(r, 0));
        CHECK_INT(error_code(r), code);
        CHECK_STR_CONTAINS(msg, msg_part);
        json_decref(r);
}

static void test_malformed(struct rigenv *e)
{
        int fd = raw_connect(e), other = raw_connect(e);
        size_t big = 70000;
        char *line = malloc(big + 2);
        json_t *r;

        CHECK(fd >= 0 && other >= 0 && line);
        expect_error(fd, "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\n", -32700, "");
        expect_error(fd, "[1,2]\n", -32600, "");
        expect_error(fd, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"warp\"}\n", -32601, "warp");
        /* a notification (no id) with an unknown method gets no response at all: the next
         * reply on the connection is that of the request after it */
        expect_error(fd,
                     "{\"jsonrpc\":\"2.0\",\"method\":\"warp\"}\n"
                     "{\"jsonrpc\":\"2.0\",\"id\":22,\"method\":\"warp2\"}\n",
                     -32601, "warp2");
        expect_error(fd,
                     "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"move\",\"params\":"
                     "{\"axis\":\"turntable\",\"position\":\"ninety\"}}\n",
                     -32602, "position");
        expect_error(fd,
                     "{\"jsonrpc\":\"2.0\",\"id\":4,\"method\":\"move\",\"params\":"
                     "{\"axis\":5,\"position\":1}}\n",
                     -32602, "axis");
        expect_error(fd,
                     "{\"jsonrpc\":\"2.0\",\"id\":5,\"method\":\"lamp.set\",\"params\":"
                     "{\"lamp\":\"lamp0\",\"on\":\"yes\"}}\n",
                     -32602, "on");
        expect_error(fd,
                     "{\"jsonrpc\":\"2.0\",\"id\":6,\"method\":\"move\",\"params\":"
                     "{\"axis\":\"camera_arm\",\"position\":400}}\n",
                     -32002, "soft limits");
        memset(line, 'x', big);
        line[big] = '\n';
        line[big + 1] = 0;
        expect_error(fd, line, -32009, "line");
        /* the same connection and another one still work */
        r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":7,\"method\":\"status\"}\n");
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        r = raw_call(other, "{\"jsonrpc\":\"2.0\",\"id\":8,\"method\":\"status\"}\n");
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        free(line);
        close(fd);
        close(other);
}

/* A long move is stopped from another client; status answers during the move. */
static void test_stop_and_responsive(struct rigenv *e)
{
        int mover = raw_connect(e), fd = raw_connect(e);
        json_t *r, *st;
        const char *move = "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"move\",\"params\":"
                           "{\"axis\":\"camera_arm\",\"position\":160}}\n";

        CHECK(write(mover, move, strlen(move)) == (ssize_t)strlen(move));
        usleep(100000);
        st = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"status\"}\n");
        CHECK(strcmp(json_string_value(json_object_get(json_object_get(st, "result"), "state")),
                     "moving") == 0);
        json_decref(st);
        r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"stop\"}\n");
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        r = raw_call(mover, "");
        CHECK_INT(error_code(r), -32007); /* canceled */
        json_decref(r);
        /* both clients were told: moving, then idle again */
        CHECK_STR_CONTAINS(raw_seen(), "state.changed");
        close(mover);
        close(fd);
}

/* goniod refuses a bad rig file with file, line and key, also for a key inside a backend's
 * map and a profile it does not define (both parsed by the backend when the file loads). */
static void test_bad_rig_file(struct rigenv *e)
{
        static const struct {
                const char *axes, *want;
        } rows[] = {
                {"  - { name: a, modbus: { bus: b }, accel: -5 }\n", ":5: key 'accel'"},
                {"  - name: a\n    modbus:\n      bus: b\n      unti: 2\n",
                 ":8: key 'unti': unknown key"},
                {"  - { name: a, modbus: { bus: b, profile: nope } }\n",
                 ":5: key 'profile': no register profile named 'nope'"},
        };
        char path[400], err[4096];

        snprintf(path, sizeof(path), "%s/bad.yaml", e->dir);
        for (size_t i = 0; i < ELEMENTSOF(rows); i++) {
                FILE *f = fopen(path, "we");

                CHECK(f);
                fprintf(f,
                        "rig: bad\nbuses:\n  - { name: b, type: modbus-rtu, port: /dev/null }\n"
                        "axes:\n%s",
                        rows[i].axes);
                fclose(f);
                CHECK_INT(run_capture((char *[]){(char *)e->goniod, "--rig", path, "--socket",
                                                 "/tmp/never.sock", NULL},
                                      NULL, 0, err, sizeof(err)),
                          1);
                CHECK_STR_CONTAINS(err, path);
                CHECK_STR_CONTAINS(err, rows[i].want);
        }
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 4);
        rigenv_start(&e, argv, 1);
        json_decref(ctl_ok(&e, "home", NULL));
        test_malformed(&e);
        test_stop_and_responsive(&e);
        test_bad_rig_file(&e);
        rigenv_stop(&e);
        return 0;
}
