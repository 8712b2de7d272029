/* test.h - minimal assertions for gonio's test programs (exit 1 on failure,
 * 77 to tell meson the test was skipped). */
#pragma once

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#define TEST_SKIP 77

/* SIGKILLs pid only while it is a child of ours not yet reaped (WNOHANG answers 0 for exactly
 * those), so a stale or garbage pid in an exit handler never hits another process. */
static inline void kill_own_child(pid_t pid)
{
        if (pid > 0 && waitpid(pid, NULL, WNOHANG) == 0)
                kill(pid, SIGKILL);
}

#define CHECK(cond)                                                                                \
        do {                                                                                       \
                if (!(cond)) {                                                                     \
                        fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);   \
                        exit(1);                                                                   \
                }                                                                                  \
        } while (0)

#define CHECK_INT(a, b)                                                                            \
        do {                                                                                       \
                long long _a = (a), _b = (b);                                                      \
                if (_a != _b) {                                                                    \
                        fprintf(stderr, "%s:%d: %s == %lld, expected %s == %lld\n", __FILE__,      \
                                __LINE__, #a, _a, #b, _b);                                         \
                        exit(1);                                                                   \
                }                                                                                  \
        } while (0)

#define CHECK_NEAR(a, b, tol)                                                                      \
        do {                                                                                       \
                double _a = (a), _b = (b);                                                         \
                if (!(fabs(_a - _b) <= (tol))) {                                                   \
                        fprintf(stderr, "%s:%d: %s == %.9g, expected %.9g +- %g\n", __FILE__,      \
                                __LINE__, #a, _a, _b, (double)(tol));                              \
                        exit(1);                                                                   \
                }                                                                                  \
        } while (0)

#define CHECK_STR(a, b)                                                                            \
        do {                                                                                       \
                const char *_a = (a), *_b = (b);                                                   \
                if (!_a || !_b || strcmp(_a, _b) != 0) {                                           \
                        fprintf(stderr, "%s:%d: %s == \"%s\", expected \"%s\"\n", __FILE__,        \
                                __LINE__, #a, _a ? _a : "(null)", _b ? _b : "(null)");             \
                        exit(1);                                                                   \
                }                                                                                  \
        } while (0)

#define CHECK_STR_CONTAINS(s, sub)                                                                 \
        do {                                                                                       \
                const char *_s = (s);                                                              \
                if (!_s || !strstr(_s, (sub))) {                                                   \
                        fprintf(stderr, "%s:%d: '%s' does not contain '%s'\n", __FILE__, __LINE__, \
                                _s ? _s : "(null)", (sub));                                        \
                        exit(1);                                                                   \
                }                                                                                  \
        } while (0)

/* A case of a test program that runs its cases by name (TEST_RUN_CASES). */
struct test_case {
        const char *name;
        void (*fn)(void);
};

/* Runs the case named argv[1], or every case when there is no argument. An unknown name
 * or a second argument fails the program (exit 1) with a message naming the known cases,
 * so a misspelt case in meson.build cannot pass without testing. Returns 0. */
static inline int test_run_cases(const struct test_case *cases, size_t n, int argc, char **argv)
{
        int ran = 0;

        for (size_t i = 0; i < n && argc <= 2; i++)
                if (argc < 2 || strcmp(argv[1], cases[i].name) == 0) {
                        cases[i].fn();
                        ran++;
                }
        if (argc < 2 || ran > 0)
                return 0;
        fprintf(stderr, "%s: unknown case '%s'%s; cases:", argv[0], argv[1],
                argc > 2 ? " or extra arguments" : "");
        for (size_t i = 0; i < n; i++)
                fprintf(stderr, " %s", cases[i].name);
        fputc('\n', stderr);
        exit(1);
}

#define TEST_RUN_CASES(cases, argc, argv)                                                          \
        test_run_cases((cases), sizeof(cases) / sizeof((cases)[0]), (argc), (argv))

/* Connects a Unix stream socket to path. Returns the fd, or -errno when nothing accepts
 * there (the test decides whether that is a failure). */
static inline int test_unix_connect(const char *path)
{
        struct sockaddr_un sa;
        int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

        CHECK(fd >= 0);
        memset(&sa, 0, sizeof(sa));
        sa.sun_family = AF_UNIX;
        snprintf(sa.sun_path, sizeof(sa.sun_path), "%s", path);
        if (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0) {
                int r = -errno;
                close(fd);
                return r;
        }
        return fd;
}

/* Runs gonioctl (its path in $GONIOCTL) with args, a shell command line's tail; its stdout
 * and stderr into out (len bytes, NUL-terminated), echoed to stderr. Returns its exit code. */
static inline int test_run_gonioctl(const char *args, char *out, size_t len)
{
        char cmd[4096];
        FILE *p;
        size_t n;
        int st;

        snprintf(cmd, sizeof(cmd), "%s %s 2>&1", getenv("GONIOCTL"), args);
        p = popen(cmd, "r");
        CHECK(p);
        n = fread(out, 1, len - 1, p);
        out[n] = 0;
        st = pclose(p);
        fprintf(stderr, "$ gonioctl %s -> %d\n%s", args, WEXITSTATUS(st), out);
        return WEXITSTATUS(st);
}
