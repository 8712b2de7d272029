/* fileio.c - whole-buffer I/O and atomic file replacement (see fileio.h). */
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>

#include "cleanup.h"
#include "fileio.h"
#include "sha256.h"

#define IO_CHUNK (1u << 20)

int gn_write_all(int fd, const void *buf, size_t len, struct gn_sha256 *sha)
{
        const uint8_t *p = buf;

        while (len > 0) {
                ssize_t k = write(fd, p, MIN(len, IO_CHUNK));

                if (k < 0 && errno == EINTR)
                        continue;
                if (k < 0)
                        return -errno;
                if (sha && gn_sha256_update(sha, p, (size_t)k) < 0)
                        return -EIO;
                p += k;
                len -= (size_t)k;
        }
        return 0;
}

/* Writes buf to the new file dir_fd/tmp and fsyncs and closes it (errors of both count). */
static int write_synced(int dir_fd, const char *tmp, const void *buf, size_t len,
                        struct gn_sha256 *sha)
{
        int fd, r;

        fd = openat(dir_fd, tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
        if (fd < 0)
                return -errno;
        r = gn_write_all(fd, buf, len, sha);
        if (r == 0 && fsync(fd) < 0)
                r = -errno;
        if (close(fd) < 0 && r == 0)
                r = -errno;
        return r;
}

/* fsyncs the directory of name below dir_fd. */
static int fsync_dir_of(int dir_fd, const char *name)
{
        char copy[PATH_MAX];
        _cleanup_close_ int fd = -EBADF;

        if (snprintf(copy, sizeof(copy), "%s", name) >= (int)sizeof(copy))
                return -ENAMETOOLONG;
        fd = openat(dir_fd, dirname(copy), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (fd < 0 || fsync(fd) < 0)
                return -errno;
        return 0;
}

int gn_write_atomic(int dir_fd, const char *name, const void *buf, size_t len,
                    struct gn_sha256 *sha)
{
        char tmp[PATH_MAX];
        int r;

        if (!name || (!buf && len > 0))
                return -EINVAL;
        if (snprintf(tmp, sizeof(tmp), "%s.tmp", name) >= (int)sizeof(tmp))
                return -ENAMETOOLONG;
        r = write_synced(dir_fd, tmp, buf, len, sha);
        if (r == 0 && renameat(dir_fd, tmp, dir_fd, name) < 0)
                r = -errno;
        if (r < 0) {
                (void)unlinkat(dir_fd, tmp, 0);
                return r;
        }
        r = fsync_dir_of(dir_fd, name);
        if (r < 0)
                (void)unlinkat(dir_fd, name, 0);
        return r;
}

int gn_fsync_parent(const char *path)
{
        return fsync_dir_of(AT_FDCWD, path);
}

int gn_read_file_at(int dir_fd, const char *name, size_t max, void **ret, size_t *ret_len)
{
        _cleanup_close_ int fd = openat(dir_fd, name, O_RDONLY | O_CLOEXEC);
        _cleanup_free_ uint8_t *buf = NULL;
        struct stat st;
        size_t n = 0;

        if (fd < 0 || fstat(fd, &st) < 0)
                return -errno;
        if (!S_ISREG(st.st_mode))
                return -EBADMSG;
        if ((uint64_t)st.st_size > max)
                return -EFBIG;
        buf = malloc(st.st_size > 0 ? (size_t)st.st_size : 1);
        if (!buf)
                return -ENOMEM;
        while (n < (size_t)st.st_size) {
                ssize_t k = read(fd, buf + n, (size_t)st.st_size - n);

                if (k < 0 && errno == EINTR)
                        continue;
                if (k <= 0)
                        return k < 0 ? -errno : -EIO;
                n += (size_t)k;
        }
        *ret = TAKE_PTR(buf);
        *ret_len = n;
        return 0;
}
