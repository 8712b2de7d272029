/* test.h - minimal assertions for gonio's test programs (exit 1 on failure,
 * 77 to tell meson the test was skipped). */
#pragma once

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TEST_SKIP 77

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
