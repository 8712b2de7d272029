/* test-proto-errno.c - the -errno <-> JSON-RPC code table in both directions, and the
 * default socket path resolution. */
#include <errno.h>

#include "tests/test.h"
#include "protocol/proto.h"

static const struct {
        int err, code;
} canonical[] = {
        {EINVAL, PROTO_INVALID_PARAMS},
        {ENOSYS, PROTO_METHOD_NOT_FOUND},
        {EBUSY, PROTO_E_BUSY},
        {ERANGE, PROTO_E_RANGE},
        {EIO, PROTO_E_DEVICE},
        {ETIMEDOUT, PROTO_E_TIMEOUT},
        {ENOENT, PROTO_E_NOT_FOUND},
        {ENOSPC, PROTO_E_STORAGE},
        {ECANCELED, PROTO_E_CANCELED},
        {ESTALE, PROTO_E_STATE},
        {EMSGSIZE, PROTO_E_LINE_TOO_LONG},
};

static void test_both_ways(void)
{
        for (size_t i = 0; i < sizeof(canonical) / sizeof(canonical[0]); i++) {
                CHECK_INT(proto_errno_to_code(-canonical[i].err), canonical[i].code);
                CHECK_INT(proto_errno_to_code(canonical[i].err), canonical[i].code);
                CHECK_INT(proto_code_to_errno(canonical[i].code), canonical[i].err);
        }
}

static void test_aliases_and_unknown(void)
{
        CHECK_INT(proto_errno_to_code(-EAGAIN), PROTO_E_BUSY);
        CHECK_INT(proto_errno_to_code(-EPROTO), PROTO_E_DEVICE);
        CHECK_INT(proto_errno_to_code(-ENODEV), PROTO_E_DEVICE);
        CHECK_INT(proto_errno_to_code(-EROFS), PROTO_E_STORAGE);
        CHECK_INT(proto_errno_to_code(-EDQUOT), PROTO_E_STORAGE);
        CHECK_INT(proto_errno_to_code(-EPERM), PROTO_E_STATE);
        CHECK_INT(proto_errno_to_code(-EOPNOTSUPP), PROTO_INVALID_PARAMS);
        CHECK_INT(proto_errno_to_code(-EPROTONOSUPPORT), PROTO_INVALID_REQUEST);
        CHECK_INT(proto_errno_to_code(-ENOMEM), PROTO_INTERNAL_ERROR);
        CHECK_INT(proto_code_to_errno(PROTO_PARSE_ERROR), EPROTO);
        CHECK_INT(proto_code_to_errno(PROTO_INVALID_REQUEST), EPROTO);
        CHECK_INT(proto_code_to_errno(PROTO_INTERNAL_ERROR), EPROTO);
        CHECK_INT(proto_code_to_errno(-32050), EPROTO);
        CHECK_INT(proto_code_to_errno(0), EPROTO);
}

static void test_socket_path(void)
{
        char buf[108];

        CHECK_INT(setenv("GONIO_SOCKET", "/tmp/x.sock", 1), 0);
        CHECK_INT(proto_socket_path(buf, sizeof(buf)), 0);
        CHECK_STR(buf, "/tmp/x.sock");
        CHECK_INT(unsetenv("GONIO_SOCKET"), 0);
        CHECK_INT(setenv("XDG_RUNTIME_DIR", "/run/user/1000", 1), 0);
        CHECK_INT(proto_socket_path(buf, sizeof(buf)), 0);
        CHECK_STR(buf, "/run/user/1000/gonio/goniod.sock");
        CHECK_INT(unsetenv("XDG_RUNTIME_DIR"), 0);
        CHECK_INT(proto_socket_path(buf, sizeof(buf)), 0);
        CHECK_STR(buf, "/run/gonio/goniod.sock");
        CHECK_INT(proto_socket_path(buf, 8), -ENAMETOOLONG);
}

int main(void)
{
        test_both_ways();
        test_aliases_and_unknown();
        test_socket_path();
        return 0;
}
