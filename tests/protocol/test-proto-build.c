/* test-proto-build.c - the builders and proto_dump round-trip through the framer and
 * proto_parse (results and errors carry the request's id); dump refuses lines over
 * PROTO_MAX_LINE. */
#include <errno.h>

#include "tests/test.h"
#include "protocol/proto.h"

/* Dumps m (consumed), checks it is one '\n'-terminated line, frames and parses it back. */
static struct proto_msg round_trip(json_t *m)
{
        struct proto_lines pl = {};
        struct proto_msg msg;
        char *s, *line, err[128];
        size_t n, len;

        CHECK(m);
        s = proto_dump(m, &n);
        json_decref(m);
        CHECK(s);
        CHECK_INT(n, strlen(s));
        CHECK(s[n - 1] == '\n');
        CHECK(memchr(s, '\n', n - 1) == NULL);
        CHECK_INT(proto_lines_feed(&pl, s, n), 0);
        CHECK_INT(proto_lines_next(&pl, &line, &len), 1);
        CHECK_INT(proto_parse(line, len, &msg, NULL, err, sizeof(err)), 0);
        proto_lines_done(&pl);
        free(s);
        return msg;
}

static void test_request_notification(void)
{
        struct proto_msg m;

        m = round_trip(proto_request(
                42, "move", json_pack("{s:s,s:f}", "axis", "turntable", "position", 12.5)));
        CHECK_INT(m.kind, PROTO_REQUEST);
        CHECK_INT(json_integer_value(m.id), 42);
        CHECK_STR(m.method, "move");
        CHECK(json_real_value(json_object_get(m.params, "position")) == 12.5);
        json_decref(m.root);

        m = round_trip(proto_request(1, "status", NULL));
        CHECK(m.params == NULL);
        json_decref(m.root);

        m = round_trip(proto_notification("state.changed", json_pack("{s:s}", "state", "moving")));
        CHECK_INT(m.kind, PROTO_NOTIFICATION);
        CHECK_STR(json_string_value(json_object_get(m.params, "state")), "moving");
        json_decref(m.root);
}

static void test_result_error(void)
{
        json_t *id = json_string("req-1");
        struct proto_msg m;

        m = round_trip(proto_result(id, json_pack("{s:b}", "on", 1)));
        CHECK_INT(m.kind, PROTO_RESPONSE);
        CHECK_STR(json_string_value(m.id), "req-1");
        CHECK(json_is_true(json_object_get(m.result, "on")));
        json_decref(m.root);

        m = round_trip(proto_result(id, NULL));
        CHECK(json_is_object(m.result) && json_object_size(m.result) == 0);
        json_decref(m.root);

        m = round_trip(proto_error(NULL, PROTO_E_LINE_TOO_LONG, "line too long", NULL));
        CHECK(json_is_null(m.id));
        CHECK_INT(json_integer_value(json_object_get(m.error, "code")), PROTO_E_LINE_TOO_LONG);
        CHECK_STR(json_string_value(json_object_get(m.error, "message")), "line too long");
        CHECK(json_object_get(m.error, "data") == NULL);
        json_decref(m.root);

        /* error replies carry the request's id, string or integer */
        m = round_trip(proto_error(id, PROTO_E_BUSY, "busy", json_pack("{s:i}", "n", 1)));
        CHECK_STR(json_string_value(m.id), "req-1");
        CHECK(proto_answers(&m, 1) == false);
        json_decref(m.root);

        m = round_trip(proto_error_errno(id, -ENOENT, "no axis 'foo'"));
        CHECK_STR(json_string_value(m.id), "req-1");
        CHECK_INT(json_integer_value(json_object_get(m.error, "code")), PROTO_E_NOT_FOUND);
        CHECK_STR(json_string_value(json_object_get(json_object_get(m.error, "data"), "errno")),
                  "ENOENT");
        json_decref(m.root);
        CHECK_INT(id->refcount, 1); /* borrowed, never stolen */
        json_decref(id);

        id = json_integer(7);
        m = round_trip(proto_result(id, NULL));
        CHECK_INT(json_integer_value(m.id), 7);
        CHECK(proto_answers(&m, 7));
        json_decref(m.root);
        m = round_trip(proto_error_errno(id, -ERANGE, "outside [-90, 90]"));
        CHECK_INT(json_integer_value(m.id), 7);
        CHECK(proto_answers(&m, 7));
        json_decref(m.root);
        CHECK_INT(id->refcount, 1);
        json_decref(id);
}

static void test_dump_limit(void)
{
        size_t n = PROTO_MAX_LINE;
        char *big = malloc(n + 1);
        json_t *m;

        CHECK(big);
        memset(big, 'x', n);
        big[n] = '\0';
        m = proto_notification("big", json_pack("{s:s}", "s", big));
        CHECK(m);
        errno = 0;
        CHECK(proto_dump(m, NULL) == NULL);
        CHECK_INT(errno, EMSGSIZE);
        json_decref(m);
        free(big);
}

int main(void)
{
        test_request_notification();
        test_result_error();
        test_dump_limit();
        return 0;
}
