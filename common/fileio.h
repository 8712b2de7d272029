/* fileio.h - whole-buffer file I/O and atomic, durable file replacement: the one place
 * that writes a temporary name, fsyncs, renames and fsyncs the directory. */
#pragma once

#include <stddef.h>

struct gn_sha256;

/* Writes all len bytes of buf to fd, retrying short writes and EINTR, in chunks of at
 * most 1 MiB; with sha, feeds it each chunk as it is written. Returns 0 or -errno of
 * write (-ENOSPC, -EFBIG...) or -EIO from the digest. */
int gn_write_all(int fd, const void *buf, size_t len, struct gn_sha256 *sha);

/* Replaces dir_fd/name (dir_fd may be AT_FDCWD; name may contain directories) with buf,
 * atomically and durably: write name.tmp, fsync, close, rename to name, fsync the
 * directory holding name. With sha, the bytes are hashed as they are written (never
 * read back). On failure nothing is left behind (neither the temporary nor, when the
 * directory fsync fails, name) and the -errno of the failing call is returned. */
int gn_write_atomic(int dir_fd, const char *name, const void *buf, size_t len,
                    struct gn_sha256 *sha);

/* fsyncs the directory that holds path (its parent), so that a new entry of path is
 * durable. Returns 0, -ENAMETOOLONG or -errno. */
int gn_fsync_parent(const char *path);

/* Reads the whole regular file name below dir_fd into a malloc'ed buffer (*ret, freed
 * by the caller) of *ret_len bytes. Returns 0, -EFBIG (larger than max), -EBADMSG (not
 * a regular file), -ENOMEM or -errno. */
int gn_read_file_at(int dir_fd, const char *name, size_t max, void **ret, size_t *ret_len);
