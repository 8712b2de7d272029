/* test-sim-proto.c - encode/decode of the frame-socket messages of the sim camera
 * backend (drivers/camera/sim/proto.c): request lines, frame headers, error replies
 * and the headers a client must refuse. */
#include <errno.h>
#include <string.h>

#include "drivers/camera/sim/proto.h"
#include "tests/sim/simtest.h"

static void test_encode(void)
{
        char buf[256];
        struct simproto_render rq = {.camera = "cam0", .exposure_us = 5000, .bits = 16};

        int n = simproto_encode_render(&rq, buf, sizeof buf);
        CHECK(n > 0 && (size_t)n == strlen(buf) && buf[n - 1] == '\n');
        CHECK(strstr(buf, "\"cmd\":\"render\"") && strstr(buf, "\"camera\":\"cam0\""));
        CHECK(strstr(buf, "\"exposure_us\":5000") && strstr(buf, "\"bits\":16"));
        CHECK(!strstr(buf, "gain")); /* 0: camera default, not sent */
        CHECK(simproto_encode_render(&rq, buf, 10) == -ENOBUFS);
        rq.camera = NULL;
        CHECK(simproto_encode_render(&rq, buf, sizeof buf) == -EINVAL);
}

static void test_decode(void)
{
        static const char ok[] =
                "{\"ok\":true,\"camera\":\"cam0\",\"seq\":7,\"timestamp_ns\":123,\"width\":4,"
                "\"height\":2,\"channels\":3,\"bits\":16,\"stride\":24,\"bytes\":48,"
                "\"exposure_us\":900,\"gain\":2.5,\"state\":{},\"truth\":[{\"name\":\"depth\","
                "\"type\":\"f32\",\"components\":1,\"bytes\":32}]}\n";
        struct simproto_header h;
        char msg[64];

        CHECK(simproto_decode_header(ok, strlen(ok), &h, msg, sizeof msg) == 0);
        CHECK(h.width == 4 && h.height == 2 && h.channels == 3 && h.bits == 16);
        CHECK(h.stride == 24 && h.bytes == 48 && h.extra_bytes == 32);
        CHECK(h.seq == 7 && h.timestamp_ns == 123 && h.exposure_us == 900 && h.gain == 2.5);

        static const char dropped[] =
                "{\"ok\":false,\"error\":\"ETIMEDOUT\",\"message\":\"frame dropped\"}";
        CHECK(simproto_decode_header(dropped, strlen(dropped), &h, msg, sizeof msg) == -ETIMEDOUT);
        CHECK(strcmp(msg, "frame dropped") == 0);
        static const char odd[] = "{\"ok\":false,\"error\":\"EWHATEVER\"}";
        CHECK(simproto_decode_header(odd, strlen(odd), &h, msg, sizeof msg) == -EIO);
}

static void test_refused(void)
{
        static const char *const bad[] = {
                "",
                "not json",
                "{\"width\":4}",
                "{\"ok\":true,\"width\":4,\"height\":2,\"channels\":3,\"bits\":8,\"stride\":12}",
                "{\"ok\":true,\"width\":4,\"height\":2,\"channels\":2,\"bits\":8,\"stride\":8,"
                "\"bytes\":16}",
                "{\"ok\":true,\"width\":4,\"height\":2,\"channels\":1,\"bits\":8,\"stride\":4,"
                "\"bytes\":9}",
                "{\"ok\":true,\"width\":4,\"height\":2,\"channels\":1,\"bits\":8,\"stride\":2,"
                "\"bytes\":4}",
                "{\"ok\":true,\"width\":-4,\"height\":2,\"channels\":1,\"bits\":8,\"stride\":4,"
                "\"bytes\":8}",
                "{\"ok\":true,\"width\":4,\"height\":2,\"channels\":1,\"bits\":12,\"stride\":4,"
                "\"bytes\":8}",
                "{\"ok\":true,\"width\":4,\"height\":2,\"channels\":1,\"bits\":8,\"stride\":4,"
                "\"bytes\":8,\"truth\":[{\"bytes\":-1}]}",
        };
        struct simproto_header h;
        char msg[64];

        for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
                CHECK(simproto_decode_header(bad[i], strlen(bad[i]), &h, msg, sizeof msg) ==
                      -EBADMSG);
}

int main(void)
{
        test_encode();
        test_decode();
        test_refused();
        CHECK(simproto_errno("ENOENT") == -ENOENT && simproto_errno(NULL) == -EIO);
        return 0;
}
