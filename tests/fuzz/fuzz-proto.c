/* fuzz-proto.c - libFuzzer target of the wire protocol (protocol/proto.c): the bytes a client
 * sends, framed into lines by proto_lines in three feeds, each line parsed by proto_parse; a
 * message that parses is written back with proto_dump and must parse again as the same kind
 * (what goniod echoes and gonioctl reads back). */
#include <stdlib.h>

#include "fuzz.h"
#include "protocol/proto.h"

/* dump(parse(line)) parses again, as a message of the same kind. */
static void check_roundtrip(const struct proto_msg *m)
{
        struct proto_msg again;
        size_t len;
        char err[128], *text = proto_dump(m->root, &len);

        if (!text)
                return; /* ENOMEM, or EMSGSIZE: the compact form may be longer */
        if (proto_parse(text, len - 1, &again, NULL, err, sizeof(err)) != 0 ||
            again.kind != m->kind)
                abort();
        json_decref(again.root);
        free(text);
}

static void parse_line(const char *line, size_t len)
{
        struct proto_msg m;
        json_t *id = NULL;
        char err[128];

        if (proto_parse(line, len, &m, &id, err, sizeof(err)) != 0) {
                json_decref(id);
                return;
        }
        (void)proto_answers(&m, 1);
        check_roundtrip(&m);
        json_decref(m.root);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
        struct proto_lines pl = {0};
        size_t chunk = size / 3 + 1;

        for (size_t off = 0; off < size; off += chunk) {
                size_t n = size - off < chunk ? size - off : chunk, len;
                char *line;
                int r;

                if (proto_lines_feed(&pl, (const char *)data + off, n) < 0)
                        break;
                while ((r = proto_lines_next(&pl, &line, &len)) != 0)
                        if (r > 0)
                                parse_line(line, len);
        }
        proto_lines_done(&pl);
        return 0;
}
