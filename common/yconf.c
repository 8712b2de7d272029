/* yconf.c - typed, line-aware access to YAML configuration over libfyaml.
 *
 * Every error message has the form "FILE:LINE: key 'KEY': reason" and only the
 * first error of a load is kept, so that the operator sees the root cause. */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "log.h"
#include "yconf.h"

/* libfyaml reports parse errors through this; the first one goes into the context. */
static void diag_output(struct fy_diag *diag, void *user, const char *buf, size_t len)
{
        struct yconf *ctx = user;

        if (ctx->err && ctx->errlen && !ctx->err[0])
                snprintf(ctx->err, ctx->errlen, "%.*s", (int)strcspn(buf, "\n"), buf);
}

static struct fy_diag *capturing_diag(struct yconf *ctx)
{
        struct fy_diag_cfg dcfg;

        fy_diag_cfg_default(&dcfg);
        dcfg.fp = NULL;
        dcfg.output_fn = diag_output;
        dcfg.user = ctx;
        dcfg.colorize = false;
        dcfg.show_source = false;
        dcfg.show_type = false;
        dcfg.show_module = false;
        dcfg.show_position = true;
        return fy_diag_create(&dcfg);
}

/* Turns libfyaml's "SOURCE:LINE:COL: error: text" into "FILE:LINE: YAML syntax error: text". */
static int parse_failed(struct yconf *ctx)
{
        const char *text = ctx->err ? strstr(ctx->err, ": error: ") : NULL;
        char msg[512] = "cannot parse YAML";
        int line = 0;

        if (text) {
                const char *p = text;
                int colons = 0;
                while (p > ctx->err && colons < 2)
                        colons += *--p == ':';
                if (colons == 2)
                        line = atoi(p + 1);
                snprintf(msg, sizeof(msg), "%s", text + strlen(": error: "));
        }
        if (ctx->err)
                snprintf(ctx->err, ctx->errlen, "%s:%d: YAML syntax error: %s", ctx->path, line,
                         msg);
        return -EINVAL;
}

/* Length of the UTF-8 sequence at s (1 to 4), or 0 when it is not well-formed (overlong,
 * surrogate, beyond U+10FFFF, truncated, a stray continuation byte). */
static size_t utf8_seq(const unsigned char *s)
{
        unsigned c = s[0];
        size_t n = c < 0x80                 ? 1
                   : c >= 0xc2 && c <= 0xdf ? 2
                   : c >= 0xe0 && c <= 0xef ? 3
                   : c >= 0xf0 && c <= 0xf4 ? 4
                                            : 0;

        for (size_t i = 1; i < n; i++)
                if ((s[i] & 0xc0) != 0x80)
                        return 0;
        if ((c == 0xe0 && s[1] < 0xa0) || (c == 0xed && s[1] > 0x9f) ||
            (c == 0xf0 && s[1] < 0x90) || (c == 0xf4 && s[1] > 0x8f))
                return 0;
        return n;
}

/* YAML is Unicode text; libfyaml 0.7 loops forever on some malformed UTF-8 (a directive
 * line "%\x83"), so malformed text is refused before it gets there, at its line. */
static int check_utf8(struct yconf *ctx, const char *text)
{
        const unsigned char *p = (const unsigned char *)text;
        int line = 1;
        size_t n;

        for (; *p; p += n) {
                if (!(n = utf8_seq(p))) {
                        if (ctx->err)
                                snprintf(ctx->err, ctx->errlen,
                                         "%s:%d: not UTF-8 text (byte 0x%02x)", ctx->path, line,
                                         *p);
                        return -EINVAL;
                }
                line += *p == '\n';
        }
        return 0;
}

/* Whether the quote or hash at p (in text) starts a token: a quoted scalar, a comment. */
static bool starts_token(const char *text, const char *p)
{
        return p == text || strchr(" \t\n[{,", p[-1]);
}

/* libfyaml 0.7.12 writes through a NULL pointer on a tab after a complex key ("? a:\t? b", found
 * by fuzzing), and gonio's files need tabs nowhere YAML gives them meaning: a tab outside a
 * quoted scalar or a comment is refused before it gets there, at its line. */
static int check_tabs(struct yconf *ctx, const char *text)
{
        bool comment = false;
        char quote = 0;
        int line = 1;

        for (const char *p = text; *p; p++) {
                if (*p == '\n')
                        line++, comment = false;
                else if (comment)
                        continue;
                else if (quote == '"' && *p == '\\' && p[1])
                        p++;
                else if (quote && *p == quote && !(quote == '\'' && p[1] == '\''))
                        quote = 0;
                else if (quote && *p == quote)
                        p++; /* '' inside single quotes */
                else if (quote)
                        continue;
                else if (*p == '#' && starts_token(text, p))
                        comment = true;
                else if ((*p == '"' || *p == '\'') && starts_token(text, p))
                        quote = *p;
                else if (*p == '\t') {
                        if (ctx->err)
                                snprintf(ctx->err, ctx->errlen,
                                         "%s:%d: a tab: gonio's YAML files take spaces only "
                                         "(tabs only inside quotes and comments)",
                                         ctx->path, line);
                        return -EINVAL;
                }
        }
        return 0;
}

static int open_common(struct yconf *ctx, const char *path, const char *text, char *err,
                       size_t errlen)
{
        struct fy_parse_cfg cfg = {.flags = FYPCF_QUIET | FYPCF_DEFAULT_PARSE};
        struct fy_diag *diag;
        int r;

        memset(ctx, 0, sizeof(*ctx));
        ctx->path = path;
        ctx->err = err;
        ctx->errlen = errlen;
        if (err && errlen)
                err[0] = 0;
        if ((r = check_utf8(ctx, text)) < 0 || (r = check_tabs(ctx, text)) < 0)
                return r;
        diag = capturing_diag(ctx);
        cfg.diag = diag;
        ctx->doc = fy_document_build_from_string(&cfg, text, FY_NT);
        if (!ctx->doc)
                r = parse_failed(ctx);
        if (diag)
                fy_diag_unref(diag);
        return r;
}

int yconf_open(struct yconf *ctx, const char *path, char *err, size_t errlen)
{
        void *text = NULL;
        size_t len;
        int r = gn_read_file_at(AT_FDCWD, path, YCONF_FILE_MAX, &text, &len);

        if (r < 0) {
                memset(ctx, 0, sizeof(*ctx));
                snprintf(err, errlen, "%s: %s", path, strerror(-r));
                return r;
        }
        r = open_common(ctx, path, text, err, errlen);
        if (r < 0)
                free(text);
        else
                ctx->text = text;
        return r;
}

int yconf_open_string(struct yconf *ctx, const char *name, const char *text, char *err,
                      size_t errlen)
{
        return open_common(ctx, name, text, err, errlen);
}

void yconf_close(struct yconf *ctx)
{
        if (ctx->doc)
                fy_document_destroy(ctx->doc);
        ctx->doc = NULL;
        free(ctx->text);
        ctx->text = NULL;
}

struct fy_node *yconf_root(struct yconf *ctx)
{
        return ctx->doc ? fy_document_root(ctx->doc) : NULL;
}

struct fy_node *yconf_get(struct fy_node *map, const char *key)
{
        if (!map || fy_node_get_type(map) != FYNT_MAPPING)
                return NULL;
        return fy_node_mapping_lookup_by_string(map, key, FY_NT);
}

int yconf_line(struct fy_node *node)
{
        const struct fy_mark *m = NULL;
        void *iter = NULL;

        /* libfyaml 0.7 marks only tokens: use the first scalar inside a collection */
        switch (node ? fy_node_get_type(node) : FYNT_SCALAR) {
        case FYNT_SCALAR:
                if (node && fy_node_get_scalar_token(node))
                        m = fy_token_start_mark(fy_node_get_scalar_token(node));
                break;
        case FYNT_MAPPING: {
                struct fy_node_pair *pair = fy_node_mapping_iterate(node, &iter);
                return pair ? yconf_line(fy_node_pair_key(pair)) : 0;
        }
        case FYNT_SEQUENCE:
                return yconf_line(fy_node_sequence_iterate(node, &iter));
        }
        return m ? (int)m->line + 1 : 0;
}

int yconf_error(struct yconf *ctx, struct fy_node *node, const char *key, const char *fmt, ...)
{
        char msg[512];
        va_list ap;

        if (ctx->err && ctx->err[0]) /* keep the first error */
                return -EINVAL;
        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        if (ctx->err)
                snprintf(ctx->err, ctx->errlen, "%s:%d: key '%s': %s", ctx->path, yconf_line(node),
                         key ? key : "(root)", msg);
        return -EINVAL;
}

int yconf_check_keys(struct yconf *ctx, struct fy_node *map, const char *const *allowed)
{
        struct fy_node_pair *pair;
        void *iter = NULL;

        if (!map || fy_node_get_type(map) != FYNT_MAPPING)
                return yconf_error(ctx, map, NULL, "expected a mapping");
        while ((pair = fy_node_mapping_iterate(map, &iter))) {
                struct fy_node *k = fy_node_pair_key(pair);
                const char *name = fy_node_get_scalar0(k);
                bool ok = false;

                for (const char *const *a = allowed; name && *a; a++)
                        ok = ok || strcmp(*a, name) == 0;
                if (!ok)
                        return yconf_error(ctx, k, name ? name : "?", "unknown key");
        }
        return 0;
}

/* Fetches the scalar text of map[key]: 0 absent, 1 found, -EINVAL not a scalar. */
static int scalar(struct yconf *ctx, struct fy_node *map, const char *key, struct fy_node **node,
                  const char **text)
{
        struct fy_node *n = yconf_get(map, key);

        *node = n;
        if (!n)
                return 0;
        if (fy_node_get_type(n) != FYNT_SCALAR)
                return yconf_error(ctx, n, key, "expected a single value");
        *text = fy_node_get_scalar0(n);
        return *text ? 1 : yconf_error(ctx, n, key, "cannot read value");
}

/* Appends the bytes of s to out at *o. Returns 0 or -ENAMETOOLONG. */
static int append(const char *s, size_t n, char *out, size_t outlen, size_t *o)
{
        if (*o + n >= outlen)
                return -ENAMETOOLONG;
        memcpy(out + *o, s, n);
        *o += n;
        return 0;
}

/* Expands one reference: text is what stands between "${" and "}". */
static int expand_var(const char *text, size_t len, char *out, size_t outlen, size_t *o, char *var,
                      size_t varlen)
{
        const char *def = memmem(text, len, ":-", 2);
        size_t namelen = def ? (size_t)(def - text) : len;
        char name[YCONF_VAR_MAX];
        const char *val;

        snprintf(var, varlen, "%.*s", (int)namelen, text);
        if (namelen == 0 || namelen >= sizeof(name))
                return -EINVAL;
        memcpy(name, text, namelen);
        name[namelen] = 0;
        val = getenv(name);
        if (val && *val)
                return append(val, strlen(val), out, outlen, o);
        if (def) /* unset or empty: the default, which may be written empty on purpose */
                return append(def + 2, len - namelen - 2, out, outlen, o);
        return val ? -ENODATA : -ENOENT;
}

int yconf_expand(const char *src, char *out, size_t outlen, char *var, size_t varlen)
{
        size_t o = 0;
        int r;

        if (varlen)
                var[0] = 0;
        while (*src) {
                const char *end = src[0] == '$' && src[1] == '{' ? strchr(src, '}') : NULL;

                if (end) {
                        r = expand_var(src + 2, end - src - 2, out, outlen, &o, var, varlen);
                        src = end + 1;
                } else
                        r = append(src++, 1, out, outlen, &o);
                if (r < 0)
                        return r;
        }
        if (outlen == 0)
                return -ENAMETOOLONG;
        out[o] = 0;
        return 0;
}

int yconf_str(struct yconf *ctx, struct fy_node *map, const char *key, char *out, size_t outlen)
{
        char var[YCONF_VAR_MAX];
        struct fy_node *n;
        const char *text;
        int r = scalar(ctx, map, key, &n, &text);

        if (r <= 0)
                return r;
        r = yconf_expand(text, out, outlen, var, sizeof(var));
        if ((r == -ENOENT || r == -ENODATA) && ctx->keep_unset_vars)
                r = snprintf(out, outlen, "%s", text) < (int)outlen ? 0 : -ENAMETOOLONG;
        if (r == -ENOENT)
                return yconf_error(ctx, n, key,
                                   "environment variable %s is not set (write ${%s:-default} for "
                                   "a default)",
                                   var, var);
        if (r == -ENODATA)
                return yconf_error(ctx, n, key,
                                   "environment variable %s is empty (write ${%s:-default} for a "
                                   "default, or ${%s:-} for an empty value)",
                                   var, var, var);
        if (r == -EINVAL)
                return yconf_error(ctx, n, key, "'${%s}': bad variable reference", var);
        if (r < 0)
                return yconf_error(ctx, n, key, "value too long (at most %zu bytes)",
                                   outlen ? outlen - 1 : 0);
        return 1;
}

int yconf_str_req(struct yconf *ctx, struct fy_node *map, const char *key, char *out, size_t outlen)
{
        int r = yconf_str(ctx, map, key, out, outlen);

        if (r == 0)
                return yconf_error(ctx, map, key, "required key is missing");
        if (r > 0 && !out[0])
                return yconf_error(ctx, yconf_get(map, key), key, "must not be empty");
        return r;
}

static int parse_double(struct yconf *ctx, struct fy_node *n, const char *key, const char *text,
                        double min, double max, double *out)
{
        char *end;
        double v;

        errno = 0;
        v = strtod(text, &end);
        if (errno || end == text || *end || !isfinite(v))
                return yconf_error(ctx, n, key, "'%s' is not a number", text);
        if (v < min || v > max)
                return yconf_error(ctx, n, key, "%g is out of range [%g, %g]", v, min, max);
        *out = v;
        return 1;
}

int yconf_double(struct yconf *ctx, struct fy_node *map, const char *key, double min, double max,
                 double *out)
{
        struct fy_node *n;
        const char *text;
        int r = scalar(ctx, map, key, &n, &text);

        return r <= 0 ? r : parse_double(ctx, n, key, text, min, max, out);
}

int yconf_int(struct yconf *ctx, struct fy_node *map, const char *key, long min, long max,
              long *out)
{
        struct fy_node *n;
        const char *text;
        char *end;
        long v;
        int r = scalar(ctx, map, key, &n, &text);

        if (r <= 0)
                return r;
        errno = 0;
        v = strtol(text, &end, 0);
        if (errno || end == text || *end)
                return yconf_error(ctx, n, key, "'%s' is not an integer", text);
        if (v < min || v > max)
                return yconf_error(ctx, n, key, "%ld is out of range [%ld, %ld]", v, min, max);
        *out = v;
        return 1;
}

int yconf_bool_word(const char *text)
{
        static const char *const yes[] = {"true", "yes", "on", "1"};
        static const char *const no[] = {"false", "no", "off", "0"};

        for (size_t i = 0; i < ELEMENTSOF(yes); i++) {
                if (strcasecmp(text, yes[i]) == 0)
                        return 1;
                if (strcasecmp(text, no[i]) == 0)
                        return 0;
        }
        return -1;
}

int yconf_bool(struct yconf *ctx, struct fy_node *map, const char *key, bool *out)
{
        struct fy_node *n;
        const char *text;
        int r = scalar(ctx, map, key, &n, &text), b;

        if (r <= 0)
                return r;
        if ((b = yconf_bool_word(text)) < 0)
                return yconf_error(ctx, n, key, "'%s' is not a boolean (true/false)", text);
        *out = b;
        return 1;
}

int yconf_seq_len(struct yconf *ctx, struct fy_node *seq, const char *key)
{
        if (!seq || fy_node_get_type(seq) != FYNT_SEQUENCE)
                return yconf_error(ctx, seq, key, "expected a list");
        return fy_node_sequence_item_count(seq);
}

struct fy_node *yconf_seq_item(struct fy_node *seq, int i)
{
        return fy_node_sequence_get_by_index(seq, i);
}

int yconf_doubles(struct yconf *ctx, struct fy_node *map, const char *key, double *out, size_t nmin,
                  size_t n, size_t *count)
{
        struct fy_node *seq = yconf_get(map, key);
        int len;

        if (!seq)
                return 0;
        len = yconf_seq_len(ctx, seq, key);
        if (len < 0)
                return len;
        if ((size_t)len < MIN(nmin, n) || (size_t)len > n)
                return nmin < n
                               ? yconf_error(ctx, seq, key, "expected %zu to %zu numbers, got %d",
                                             nmin, n, len)
                               : yconf_error(ctx, seq, key, "expected %zu numbers, got %d", n, len);
        for (int i = 0; i < len; i++) {
                struct fy_node *item = yconf_seq_item(seq, i);
                const char *text =
                        fy_node_get_type(item) == FYNT_SCALAR ? fy_node_get_scalar0(item) : NULL;
                int r;

                if (!text)
                        return yconf_error(ctx, item, key, "item %d is not a number", i);
                r = parse_double(ctx, item, key, text, -INFINITY, INFINITY, &out[i]);
                if (r < 0)
                        return r;
        }
        if (count)
                *count = len;
        return 1;
}
