/* test-fileio.c - common/fileio, common/sha256 and common/clock: SHA-256 against the
 * FIPS 180-2 vectors fed in odd chunks, atomic replacement that leaves the old file
 * and no temporary on failure (RLIMIT_FSIZE), whole-file reads with a size cap, and
 * the two clocks.
 *
 * Usage: test-fileio CASE (one meson test per case). */
#include <fcntl.h>
#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/fileio.h"
#include "common/sha256.h"
#include "tests/test.h"

static void sha_of(const void *buf, size_t len, size_t chunk, char hex[GN_SHA256_HEX])
{
        struct gn_sha256 *s = NULL;

        CHECK_INT(gn_sha256_new(&s), 0);
        for (size_t off = 0; off < len; off += chunk)
                CHECK_INT(gn_sha256_update(s, (const uint8_t *)buf + off,
                                           len - off < chunk ? len - off : chunk),
                          0);
        CHECK_INT(gn_sha256_final(s, hex), 0);
        gn_sha256_free(s);
}

static void test_sha256(void)
{
        static const size_t chunks[] = {4099, 65536, 1 << 20}; /* odd, aligned, whole */
        size_t n = 1000000;
        char *a = malloc(n), hex[GN_SHA256_HEX];

        CHECK(a);
        memset(a, 'a', n);
        sha_of("", 0, 1, hex);
        CHECK_STR(hex, "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
        sha_of("abc", 3, 1, hex);
        CHECK_STR(hex, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
        for (size_t k = 0; k < sizeof(chunks) / sizeof(chunks[0]); k++) {
                sha_of(a, n, chunks[k], hex);
                CHECK_STR(hex, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
        }
        free(a);
}

/* A scratch directory; exits on failure. */
static char *scratch(void)
{
        char *p = strdup("/tmp/gonio-fileio-XXXXXX");

        CHECK(p && mkdtemp(p));
        return p;
}

static bool exists(const char *dir, const char *name)
{
        char p[512];

        snprintf(p, sizeof(p), "%s/%s", dir, name);
        return access(p, F_OK) == 0;
}

static void test_atomic(void)
{
        char *dir = scratch(), path[512], hex[GN_SHA256_HEX], want[GN_SHA256_HEX];
        static char big[3 << 20];
        struct gn_sha256 *s = NULL;
        struct rlimit saved, rl;
        void *back = NULL;
        size_t len = 0;

        for (size_t i = 0; i < sizeof(big); i++)
                big[i] = (char)(i * 2654435761u >> 13);
        snprintf(path, sizeof(path), "%s/sub", dir);
        CHECK(mkdir(path, 0755) == 0);
        snprintf(path, sizeof(path), "%s/sub/f", dir);
        /* AT_FDCWD with an absolute path; the bytes are hashed as they are written */
        CHECK_INT(gn_sha256_new(&s), 0);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, big, sizeof(big), s), 0);
        CHECK_INT(gn_sha256_final(s, hex), 0);
        s = gn_sha256_free(s);
        sha_of(big, sizeof(big), sizeof(big), want);
        CHECK_STR(hex, want);
        CHECK_INT(gn_sha256_file_at(AT_FDCWD, path, hex), 0);
        CHECK_STR(hex, want);
        CHECK(!exists(dir, "sub/f.tmp"));

        /* a failing write leaves the old file whole and no temporary */
        CHECK(signal(SIGXFSZ, SIG_IGN) != SIG_ERR);
        CHECK(getrlimit(RLIMIT_FSIZE, &saved) == 0);
        rl = saved;
        rl.rlim_cur = 1 << 20;
        CHECK(setrlimit(RLIMIT_FSIZE, &rl) == 0);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, "x", 1, NULL), 0); /* small: fits */
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, big, sizeof(big), NULL), -EFBIG);
        CHECK(setrlimit(RLIMIT_FSIZE, &saved) == 0);
        CHECK(!exists(dir, "sub/f.tmp"));
        CHECK_INT(gn_read_file_at(AT_FDCWD, path, 16, &back, &len), 0);
        CHECK(len == 1 && memcmp(back, "x", 1) == 0);
        free(back);

        /* reads are capped; directories are not files; a missing directory is an errno */
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, big, sizeof(big), NULL), 0);
        CHECK_INT(gn_read_file_at(AT_FDCWD, path, sizeof(big) - 1, &back, &len), -EFBIG);
        CHECK_INT(gn_read_file_at(AT_FDCWD, dir, 1 << 20, &back, &len), -EBADMSG);
        snprintf(path, sizeof(path), "%s/nodir/f", dir);
        CHECK_INT(gn_write_atomic(AT_FDCWD, path, "x", 1, NULL), -ENOENT);
        CHECK_INT(gn_fsync_parent(path), -ENOENT);
        snprintf(path, sizeof(path), "%s/sub/f", dir);
        CHECK_INT(gn_fsync_parent(path), 0);

        CHECK(unlink(path) == 0);
        snprintf(path, sizeof(path), "%s/sub", dir);
        CHECK(rmdir(path) == 0 && rmdir(dir) == 0);
        free(dir);
}

static void test_clock(void)
{
        uint64_t m0 = gn_monotonic_ns(), r = gn_realtime_ns(), m1 = gn_monotonic_ns();
        int64_t off = (int64_t)(r / 1000000000u) - (int64_t)time(NULL);

        CHECK(m1 >= m0);
        CHECK(off >= -1 && off <= 1);
}

int main(int argc, char **argv)
{
        static const struct {
                const char *name;
                void (*fn)(void);
        } cases[] = {{"sha256", test_sha256}, {"atomic", test_atomic}, {"clock", test_clock}};

        for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++)
                if (argc == 2 && strcmp(argv[1], cases[i].name) == 0) {
                        cases[i].fn();
                        return 0;
                }
        fprintf(stderr, "unknown case '%s'\n", argc == 2 ? argv[1] : "");
        return 1;
}
