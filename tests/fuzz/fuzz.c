/* fuzz.c - the helpers of the libFuzzer targets (fuzz.h): inputs as strings and as scratch
 * files under /dev/shm, one per process and suffix, removed at exit. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fuzz.h"

#define FUZZ_MAX_FILES 4

static struct {
        char suffix[16];
        char path[256];
} files[FUZZ_MAX_FILES];

static _Noreturn void die(const char *what, const char *path)
{
        fprintf(stderr, "fuzz harness: %s %s: %s\n", what, path, strerror(errno));
        abort();
}

char *fuzz_cstr(const uint8_t *data, size_t size)
{
        char *s = malloc(size + 1);

        if (!s)
                die("cannot allocate", "input");
        memcpy(s, data, size);
        s[size] = '\0';
        return s;
}

static void remove_files(void)
{
        for (size_t i = 0; i < FUZZ_MAX_FILES && files[i].path[0]; i++)
                unlink(files[i].path);
}

/* The scratch path for suffix, named on first use. */
static const char *scratch_path(const char *suffix)
{
        const char *dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : getenv("TMPDIR");
        size_t i;

        for (i = 0; i < FUZZ_MAX_FILES && files[i].path[0]; i++)
                if (strcmp(files[i].suffix, suffix) == 0)
                        return files[i].path;
        if (i == FUZZ_MAX_FILES)
                die("too many scratch files, at", suffix);
        if (i == 0)
                atexit(remove_files);
        snprintf(files[i].suffix, sizeof(files[i].suffix), "%s", suffix);
        snprintf(files[i].path, sizeof(files[i].path), "%s/gonio-fuzz-%d%s", dir ? dir : "/tmp",
                 (int)getpid(), suffix);
        return files[i].path;
}

const char *fuzz_file(const uint8_t *data, size_t size, const char *suffix)
{
        const char *path = scratch_path(suffix);
        int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);

        if (fd < 0)
                die("cannot create", path);
        for (size_t off = 0; off < size;) {
                ssize_t n = write(fd, data + off, size - off);
                if (n < 0 && errno != EINTR)
                        die("cannot write", path);
                off += n > 0 ? (size_t)n : 0;
        }
        close(fd);
        return path;
}
