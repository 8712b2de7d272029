/* test-proto-lines.c - line framing: split reads, several lines per read, CRLF and empty
 * lines, over-long lines reported once with -EMSGSIZE and the stream recovering after. */
#include <errno.h>

#include "tests/test.h"
#include "protocol/proto.h"

/* Feeds the string s and expects exactly the lines in want (NULL-terminated), then "none". */
static void feed_expect(struct proto_lines *pl, const char *s, const char *const *want)
{
        char *line;
        size_t len;

        CHECK_INT(proto_lines_feed(pl, s, strlen(s)), 0);
        for (; *want; want++) {
                CHECK_INT(proto_lines_next(pl, &line, &len), 1);
                CHECK_STR(line, *want);
                CHECK_INT(len, strlen(*want));
        }
        CHECK_INT(proto_lines_next(pl, &line, &len), 0);
}

static void test_split_and_batched(void)
{
        struct proto_lines pl = {};
        const char *none[] = {NULL};
        const char *one[] = {"{\"a\":1}", NULL};
        const char *three[] = {"{\"b\":2}", "x", "{\"c\":3}", NULL};
        const char *tail[] = {"yz", NULL};

        /* One message split over three reads, byte boundaries inside the line. */
        feed_expect(&pl, "{\"a\"", none);
        feed_expect(&pl, ":1", none);
        feed_expect(&pl, "}\n", one);
        /* Several lines (one with CRLF, an empty one) in one read, plus a partial tail. */
        feed_expect(&pl, "{\"b\":2}\nx\r\n\n{\"c\":3}\ny", three);
        feed_expect(&pl, "z\n", tail);
        CHECK_INT(pl.len, 0);
        proto_lines_done(&pl);
        CHECK(pl.buf == NULL);
}

/* A line of exactly PROTO_MAX_LINE bytes with its '\n' passes; one byte more does not. */
static void test_limit_exact(void)
{
        struct proto_lines pl = {};
        size_t n = PROTO_MAX_LINE - 1;
        char *big = malloc(n + 2), *line;
        size_t len;

        CHECK(big);
        memset(big, 'a', n);
        big[n] = '\n';
        CHECK_INT(proto_lines_feed(&pl, big, n + 1), 0);
        CHECK_INT(proto_lines_next(&pl, &line, &len), 1);
        CHECK_INT(len, n);
        memset(big, 'b', n + 1);
        big[n + 1] = '\n';
        CHECK_INT(proto_lines_feed(&pl, big, n + 2), 0);
        CHECK_INT(proto_lines_next(&pl, &line, &len), -EMSGSIZE);
        CHECK_INT(proto_lines_next(&pl, &line, &len), 0);
        free(big);
        proto_lines_done(&pl);
}

/* An over-long line fed in small chunks: -EMSGSIZE exactly once, memory stays bounded,
 * the line's remainder is dropped and the next line comes through intact. */
static void test_overlong_chunked(void)
{
        struct proto_lines pl = {};
        const char *after[] = {"{\"ok\":true}", NULL};
        char chunk[4096], *line;
        size_t len, total = 0;
        int emsgsize = 0, r;

        memset(chunk, 'z', sizeof(chunk));
        while (total < 3 * PROTO_MAX_LINE) {
                CHECK_INT(proto_lines_feed(&pl, chunk, sizeof(chunk)), 0);
                total += sizeof(chunk);
                while ((r = proto_lines_next(&pl, &line, &len)) != 0) {
                        CHECK_INT(r, -EMSGSIZE);
                        emsgsize++;
                }
                CHECK(pl.cap <= 2 * PROTO_MAX_LINE + sizeof(chunk));
        }
        CHECK_INT(emsgsize, 1);
        feed_expect(&pl, "zzz\n{\"ok\":true}\n", after);
        proto_lines_done(&pl);
}

/* An over-long line whose end arrives in the same read as the next line. */
static void test_overlong_one_read(void)
{
        struct proto_lines pl = {};
        size_t n = PROTO_MAX_LINE + 10;
        const char *next = "{\"id\":1}\n";
        char *buf = malloc(n + 1 + strlen(next)), *line;
        size_t len;

        CHECK(buf);
        memset(buf, 'q', n);
        buf[n] = '\n';
        memcpy(buf + n + 1, next, strlen(next));
        CHECK_INT(proto_lines_feed(&pl, buf, n + 1 + strlen(next)), 0);
        CHECK_INT(proto_lines_next(&pl, &line, &len), -EMSGSIZE);
        CHECK_INT(proto_lines_next(&pl, &line, &len), 1);
        CHECK_STR(line, "{\"id\":1}");
        CHECK_INT(proto_lines_next(&pl, &line, &len), 0);
        free(buf);
        proto_lines_done(&pl);
}

int main(void)
{
        test_split_and_batched();
        test_limit_exact();
        test_overlong_chunked();
        test_overlong_one_read();
        return 0;
}
