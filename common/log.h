/* log.h - leveled logging to stderr (the journal picks it up under systemd).
 *
 * Every log_*_errno() helper returns -abs(error) so that "log and return" is
 * one statement, and sets errno so "%m" in the format prints the cause. */
#pragma once

#include <errno.h>
#include <stdlib.h>

#include "cleanup.h"

enum gn_log_level {
        GN_LOG_ERR = 3,
        GN_LOG_WARNING = 4,
        GN_LOG_NOTICE = 5,
        GN_LOG_INFO = 6,
        GN_LOG_DEBUG = 7,
};

/* Sets the most verbose level printed (default GN_LOG_INFO, or $GONIO_LOG_LEVEL). */
void gn_log_set_level(int level);

/* Sets the program name printed before each line. The string must outlive logging. */
void gn_log_set_ident(const char *ident);

/* Prints one line if level is enabled; returns -abs(error). Thread-safe. */
int gn_log_internal(int level, int error, const char *file, int line, const char *fmt, ...)
        _printf_(5, 6);

#define gn_log_full_errno(level, error, ...)                                                       \
        gn_log_internal(level, error, __FILE__, __LINE__, __VA_ARGS__)

#define log_debug(...)   (void)gn_log_full_errno(GN_LOG_DEBUG, 0, __VA_ARGS__)
#define log_info(...)    (void)gn_log_full_errno(GN_LOG_INFO, 0, __VA_ARGS__)
#define log_notice(...)  (void)gn_log_full_errno(GN_LOG_NOTICE, 0, __VA_ARGS__)
#define log_warning(...) (void)gn_log_full_errno(GN_LOG_WARNING, 0, __VA_ARGS__)
#define log_error(...)   (void)gn_log_full_errno(GN_LOG_ERR, 0, __VA_ARGS__)

#define log_debug_errno(e, ...)   gn_log_full_errno(GN_LOG_DEBUG, e, __VA_ARGS__)
#define log_info_errno(e, ...)    gn_log_full_errno(GN_LOG_INFO, e, __VA_ARGS__)
#define log_warning_errno(e, ...) gn_log_full_errno(GN_LOG_WARNING, e, __VA_ARGS__)
#define log_error_errno(e, ...)   gn_log_full_errno(GN_LOG_ERR, e, __VA_ARGS__)

/* An errno value no system call produced, for log_*_errno(). */
#define SYNTHETIC_ERRNO(e) (e)
