/* log.c - leveled logging to stderr, one line per call, safe across threads. */
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "log.h"

static int max_level = -1;
static const char *log_ident = "gonio";
static pthread_mutex_t log_lock = PTHREAD_MUTEX_INITIALIZER;

void gn_log_set_level(int level)
{
        max_level = level;
}

void gn_log_set_ident(const char *ident)
{
        log_ident = ident;
}

static int current_level(void)
{
        if (max_level < 0) {
                const char *e = getenv("GONIO_LOG_LEVEL");
                max_level = e ? atoi(e) : GN_LOG_INFO;
        }
        return max_level;
}

int gn_log_internal(int level, int error, const char *file, int line, const char *fmt, ...)
{
        static const char *const names[] = {
                [GN_LOG_ERR] = "error", [GN_LOG_WARNING] = "warning", [GN_LOG_NOTICE] = "notice",
                [GN_LOG_INFO] = "info", [GN_LOG_DEBUG] = "debug",
        };
        int saved = errno;
        char buf[2048];
        va_list ap;

        error = error < 0 ? -error : error;
        if (level > current_level())
                return -error;

        errno = error; /* so that %m prints the cause */
        va_start(ap, fmt);
        vsnprintf(buf, sizeof(buf), fmt, ap);
        va_end(ap);

        pthread_mutex_lock(&log_lock);
        if (current_level() >= GN_LOG_DEBUG)
                fprintf(stderr, "%s[%s] %s (%s:%d)\n", log_ident, names[level], buf, file, line);
        else
                fprintf(stderr, "%s: %s\n", log_ident, buf);
        pthread_mutex_unlock(&log_lock);

        errno = saved;
        return -error;
}
