/* sha256.h - SHA-256 of bytes as they stream by, and of whole files, as lowercase hex
 * (OpenSSL's EVP interface underneath). Used for the checksums of dataset images. */
#pragma once

#include <stddef.h>

/* Length of a hex digest plus its NUL. */
#define GN_SHA256_HEX 65

struct gn_sha256;

/* Starts a digest. Returns 0, -ENOMEM or -EIO; free with gn_sha256_free(). Any thread. */
int gn_sha256_new(struct gn_sha256 **ret);

/* Frees s; NULL is a no-op. Returns NULL. */
struct gn_sha256 *gn_sha256_free(struct gn_sha256 *s);

/* Feeds len bytes. Returns 0 or -EIO. */
int gn_sha256_update(struct gn_sha256 *s, const void *buf, size_t len);

/* Finishes the digest into hex (64 lowercase hex digits + NUL); s is then spent.
 * Returns 0 or -EIO. */
int gn_sha256_final(struct gn_sha256 *s, char hex[GN_SHA256_HEX]);

/* The SHA-256 of the whole file name below dir_fd (AT_FDCWD: relative to the working
 * directory, or an absolute name), read in 1 MiB chunks. Returns 0, -ENOMEM or the
 * -errno of open/read. */
int gn_sha256_file_at(int dir_fd, const char *name, char hex[GN_SHA256_HEX]);
