/* test-proto-parse.c - proto_parse: valid requests, notifications and responses, and
 * every rejection (bad JSON, not an object, batch, jsonrpc version, id types, method,
 * params, malformed responses) with the code and the id a server would echo; which
 * responses answer a request id (proto_answers). */
#include "tests/test.h"
#include "protocol/proto.h"

/* Parses s and expects code r; on failure checks the echoed id as JSON text ("" = none). */
static struct proto_msg parse(const char *s, int r, const char *want_id)
{
        struct proto_msg msg;
        json_t *id = (json_t *)1;
        char err[256] = "";
        int got = proto_parse(s, strlen(s), &msg, &id, err, sizeof(err));

        if (got != r)
                fprintf(stderr, "parsing %s: %d (%s)\n", s, got, err);
        CHECK_INT(got, r);
        if (r == 0) {
                CHECK(id == NULL);
                CHECK(msg.root != NULL);
                return msg;
        }
        CHECK(err[0] != '\0');
        CHECK(msg.root == NULL);
        if (!want_id[0]) {
                CHECK(id == NULL);
        } else {
                char *t = json_dumps(id, JSON_ENCODE_ANY);

                CHECK_STR(t, want_id);
                free(t);
                json_decref(id);
        }
        return msg;
}

static void test_valid(void)
{
        struct proto_msg m;

        m = parse("{\"jsonrpc\":\"2.0\",\"id\":7,\"method\":\"move\",\"params\":{\"axis\":\"t\"}}",
                  0, "");
        CHECK_INT(m.kind, PROTO_REQUEST);
        CHECK_STR(m.method, "move");
        CHECK_INT(json_integer_value(m.id), 7);
        CHECK_STR(json_string_value(json_object_get(m.params, "axis")), "t");
        json_decref(m.root);

        m = parse("{\"jsonrpc\":\"2.0\",\"id\":\"abc\",\"method\":\"status\"}", 0, "");
        CHECK_INT(m.kind, PROTO_REQUEST);
        CHECK_STR(json_string_value(m.id), "abc");
        CHECK(m.params == NULL);
        json_decref(m.root);

        m = parse("{\"jsonrpc\":\"2.0\",\"method\":\"axis.moved\",\"params\":[1,2]}", 0, "");
        CHECK_INT(m.kind, PROTO_NOTIFICATION);
        CHECK(m.id == NULL);
        CHECK(json_is_array(m.params));
        json_decref(m.root);

        m = parse("{\"jsonrpc\":\"2.0\",\"id\":3,\"result\":{\"x\":1.5}}", 0, "");
        CHECK_INT(m.kind, PROTO_RESPONSE);
        CHECK(json_real_value(json_object_get(m.result, "x")) == 1.5);
        CHECK(m.error == NULL);
        json_decref(m.root);

        m = parse("{\"jsonrpc\":\"2.0\",\"id\":null,\"error\":{\"code\":-32700,\"message\":\"x\"}}",
                  0, "");
        CHECK_INT(m.kind, PROTO_RESPONSE);
        CHECK(json_is_null(m.id));
        CHECK_INT(json_integer_value(json_object_get(m.error, "code")), PROTO_PARSE_ERROR);
        json_decref(m.root);
}

static void test_rejected(void)
{
        parse("{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":", PROTO_PARSE_ERROR, "");
        parse("not json", PROTO_PARSE_ERROR, "");
        parse("{\"id\":1,\"id\":2,\"jsonrpc\":\"2.0\",\"method\":\"a\"}", PROTO_PARSE_ERROR, "");
        parse("[{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"a\"}]", PROTO_INVALID_REQUEST, "");
        parse("42", PROTO_INVALID_REQUEST, "");
        parse("\"hello\"", PROTO_INVALID_REQUEST, "");
        /* Wrong or missing version: the id is still echoed. */
        parse("{\"jsonrpc\":\"1.0\",\"id\":5,\"method\":\"a\"}", PROTO_INVALID_REQUEST, "5");
        parse("{\"jsonrpc\":2.0,\"id\":\"k\",\"method\":\"a\"}", PROTO_INVALID_REQUEST, "\"k\"");
        parse("{\"id\":6,\"method\":\"a\"}", PROTO_INVALID_REQUEST, "6");
        /* Invalid id types: no id can be echoed. */
        parse("{\"jsonrpc\":\"2.0\",\"id\":1.5,\"method\":\"a\"}", PROTO_INVALID_REQUEST, "");
        parse("{\"jsonrpc\":\"2.0\",\"id\":true,\"method\":\"a\"}", PROTO_INVALID_REQUEST, "");
        parse("{\"jsonrpc\":\"2.0\",\"id\":{},\"method\":\"a\"}", PROTO_INVALID_REQUEST, "");
        parse("{\"jsonrpc\":\"2.0\",\"id\":[1],\"method\":\"a\"}", PROTO_INVALID_REQUEST, "");
        /* Method and params. */
        parse("{\"jsonrpc\":\"2.0\",\"id\":8,\"method\":3}", PROTO_INVALID_REQUEST, "8");
        parse("{\"jsonrpc\":\"2.0\",\"id\":9,\"method\":\"a\",\"params\":3}", PROTO_INVALID_REQUEST,
              "9");
        parse("{\"jsonrpc\":\"2.0\",\"id\":9,\"method\":\"a\",\"params\":\"s\"}",
              PROTO_INVALID_REQUEST, "9");
        parse("{\"jsonrpc\":\"2.0\",\"id\":9,\"method\":\"a\",\"params\":null}",
              PROTO_INVALID_REQUEST, "9");
        /* Malformed responses. */
        parse("{\"jsonrpc\":\"2.0\",\"result\":{}}", PROTO_INVALID_REQUEST, "");
        parse("{\"jsonrpc\":\"2.0\",\"id\":4}", PROTO_INVALID_REQUEST, "4");
        parse("{\"jsonrpc\":\"2.0\",\"id\":4,\"result\":1,\"error\":{\"code\":1,\"message\":\"m\"}"
              "}",
              PROTO_INVALID_REQUEST, "4");
        parse("{\"jsonrpc\":\"2.0\",\"id\":4,\"error\":{\"code\":\"x\",\"message\":\"m\"}}",
              PROTO_INVALID_REQUEST, "4");
        parse("{\"jsonrpc\":\"2.0\",\"id\":4,\"error\":{\"code\":1}}", PROTO_INVALID_REQUEST, "4");
}

/* Parses the response s and checks whether it answers request 2. */
static void check_answers(const char *s, bool want)
{
        struct proto_msg m = parse(s, 0, "");

        if (proto_answers(&m, 2) != want)
                fprintf(stderr, "%s %s request 2\n", s, want ? "should answer" : "answers");
        CHECK(proto_answers(&m, 2) == want);
        json_decref(m.root);
}

static void test_answers(void)
{
        struct proto_msg m;

        /* success and error replies carry the request's id */
        check_answers("{\"jsonrpc\":\"2.0\",\"id\":2,\"result\":{}}", true);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":2,\"error\":{\"code\":-32003,\"message\":\"m\"}}",
                true);
        /* the documented id-null errors: the server could not read the request */
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":null,\"error\":{\"code\":-32700,\"message\":\"m\"}}",
                true);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":null,\"error\":{\"code\":-32600,\"message\":\"m\"}}",
                true);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":null,\"error\":{\"code\":-32009,\"message\":\"m\"}}",
                true);
        /* any other id does not */
        check_answers("{\"jsonrpc\":\"2.0\",\"id\":null,\"result\":{}}", false);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":null,\"error\":{\"code\":-32003,\"message\":\"m\"}}",
                false);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":null,\"error\":{\"code\":-32603,\"message\":\"m\"}}",
                false);
        check_answers("{\"jsonrpc\":\"2.0\",\"id\":1,\"result\":{}}", false);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":3,\"error\":{\"code\":-32700,\"message\":\"m\"}}",
                false);
        check_answers("{\"jsonrpc\":\"2.0\",\"id\":\"2\",\"result\":{}}", false);
        check_answers(
                "{\"jsonrpc\":\"2.0\",\"id\":\"2\",\"error\":{\"code\":-32001,\"message\":\"m\"}}",
                false);
        /* only responses answer */
        m = parse("{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"status\"}", 0, "");
        CHECK(!proto_answers(&m, 2));
        json_decref(m.root);
}

int main(void)
{
        test_valid();
        test_rejected();
        test_answers();
        return 0;
}
