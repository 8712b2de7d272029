/* sha256.c - streaming and file SHA-256 through OpenSSL's EVP (see sha256.h). */
#include <fcntl.h>
#include <openssl/evp.h>
#include <stdio.h>

#include "cleanup.h"
#include "sha256.h"

#define SHA_CHUNK (1u << 20)

struct gn_sha256 {
        EVP_MD_CTX *md;
};

int gn_sha256_new(struct gn_sha256 **ret)
{
        struct gn_sha256 *s = calloc(1, sizeof(*s));

        if (!s)
                return -ENOMEM;
        s->md = EVP_MD_CTX_new();
        if (!s->md) {
                free(s);
                return -ENOMEM;
        }
        if (!EVP_DigestInit_ex(s->md, EVP_sha256(), NULL)) {
                gn_sha256_free(s);
                return -EIO;
        }
        *ret = s;
        return 0;
}

struct gn_sha256 *gn_sha256_free(struct gn_sha256 *s)
{
        if (s) {
                EVP_MD_CTX_free(s->md);
                free(s);
        }
        return NULL;
}

int gn_sha256_update(struct gn_sha256 *s, const void *buf, size_t len)
{
        return EVP_DigestUpdate(s->md, buf, len) ? 0 : -EIO;
}

int gn_sha256_final(struct gn_sha256 *s, char hex[GN_SHA256_HEX])
{
        unsigned char h[EVP_MAX_MD_SIZE];
        unsigned n = 0;

        if (!EVP_DigestFinal_ex(s->md, h, &n) || n * 2 + 1 != GN_SHA256_HEX)
                return -EIO;
        for (unsigned i = 0; i < n; i++)
                snprintf(hex + 2 * i, 3, "%02x", h[i]);
        return 0;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct gn_sha256 *, gn_sha256_free);

int gn_sha256_file_at(int dir_fd, const char *name, char hex[GN_SHA256_HEX])
{
        _cleanup_(gn_sha256_freep) struct gn_sha256 *s = NULL;
        _cleanup_close_ int fd = openat(dir_fd, name, O_RDONLY | O_CLOEXEC);
        _cleanup_free_ void *buf = malloc(SHA_CHUNK);
        ssize_t k;
        int r;

        if (fd < 0)
                return -errno;
        if (!buf)
                return -ENOMEM;
        r = gn_sha256_new(&s);
        while (r == 0 && (k = read(fd, buf, SHA_CHUNK)) != 0) {
                if (k < 0 && errno == EINTR)
                        continue;
                r = k < 0 ? -errno : gn_sha256_update(s, buf, (size_t)k);
        }
        return r < 0 ? r : gn_sha256_final(s, hex);
}
