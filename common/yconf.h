/* yconf.h - typed access to YAML configuration (rig and session files) with
 * errors that name the file, the line and the key.
 *
 * A thin layer over libfyaml. Every getter returns 0 when the key is absent
 * (the output keeps its default), 1 when it was read, or -EINVAL after
 * writing "FILE:LINE: key 'a.b': reason" into the context's error buffer.
 * String values have ${VAR} and ${VAR:-default} expanded from the environment; an
 * unset or empty ${VAR} without a default is an error that names the variable. */
#pragma once

#include <stdbool.h>
#include <stddef.h>

struct fy_document;
struct fy_node;

struct yconf {
        const char *path; /* file name used in messages; borrowed */
        struct fy_document *doc;
        char *err; /* caller's buffer for the first error */
        size_t errlen;
        /* ${VAR} unset or empty is kept as written instead of an error: for a file stored
         * with a dataset and read elsewhere, where the variables of its ports do not matter */
        bool keep_unset_vars;
        char *text; /* the file's bytes when opened by yconf_open (owned), else NULL */
};

/* Largest YAML file yconf_open reads (a rig, session or calibration file is a few KiB). */
#define YCONF_FILE_MAX (16 << 20)

/* Parses the YAML file at path into ctx->doc. Returns 0, -EINVAL (not UTF-8 or not YAML),
 * -EFBIG (over YCONF_FILE_MAX), -EBADMSG (not a regular file) or -errno (message in ctx->err). */
int yconf_open(struct yconf *ctx, const char *path, char *err, size_t errlen);

/* Parses YAML text held in memory; name is used in messages. */
int yconf_open_string(struct yconf *ctx, const char *name, const char *text, char *err,
                      size_t errlen);

/* Frees the document. Safe on a zeroed or already closed context. */
void yconf_close(struct yconf *ctx);

/* The document's root node, or NULL for an empty document. */
struct fy_node *yconf_root(struct yconf *ctx);

/* Looks up key in a mapping node; NULL if absent or node is not a mapping. */
struct fy_node *yconf_get(struct fy_node *map, const char *key);

/* Line (1-based) where node starts, 0 if unknown. */
int yconf_line(struct fy_node *node);

/* Records an error at node (or its parent map when node is NULL) for key; returns -EINVAL. */
int yconf_error(struct yconf *ctx, struct fy_node *node, const char *key, const char *fmt, ...)
        __attribute__((format(printf, 4, 5)));

/* Fails with "unknown key" if map holds a key not in the NULL-terminated list. */
int yconf_check_keys(struct yconf *ctx, struct fy_node *map, const char *const *allowed);

int yconf_str(struct yconf *ctx, struct fy_node *map, const char *key, char *out, size_t outlen);
int yconf_int(struct yconf *ctx, struct fy_node *map, const char *key, long min, long max,
              long *out);
int yconf_double(struct yconf *ctx, struct fy_node *map, const char *key, double min, double max,
                 double *out);
int yconf_bool(struct yconf *ctx, struct fy_node *map, const char *key, bool *out);

/* 1 when text is a word of true ("true", "yes", "on", "1", any case), 0 for one of false,
 * -1 for anything else. */
int yconf_bool_word(const char *text);
/* Reads a sequence of exactly n numbers (or between nmin and n when nmin < n); *count gets
 * the number read when count is non-NULL. */
int yconf_doubles(struct yconf *ctx, struct fy_node *map, const char *key, double *out, size_t nmin,
                  size_t n, size_t *count);
/* Like yconf_str but the key must be present. */
int yconf_str_req(struct yconf *ctx, struct fy_node *map, const char *key, char *out,
                  size_t outlen);

/* Number of items of a sequence node, -EINVAL (with message) if node is not a sequence. */
int yconf_seq_len(struct yconf *ctx, struct fy_node *seq, const char *key);
/* Item i of a sequence node. */
struct fy_node *yconf_seq_item(struct fy_node *seq, int i);

/* Longest variable name in ${VAR}, with its terminating NUL. */
#define YCONF_VAR_MAX 128

/* Expands ${VAR} and ${VAR:-def} in src into out. ${VAR} needs VAR set and not empty;
 * ${VAR:-def} gives def when VAR is unset or empty (${VAR:-} an empty string). Returns 0;
 * -ENOENT when VAR is unset, -ENODATA when it is empty (no default either way), -EINVAL for
 * an empty or over-long name (the variable's name goes into var, which may have varlen 0);
 * -ENAMETOOLONG when out is too small. */
int yconf_expand(const char *src, char *out, size_t outlen, char *var, size_t varlen);
