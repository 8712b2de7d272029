/* bench.h - helpers of the benchmarks that run goniod on gonio-sim (the e2e harness):
 * the tools of the build tree, sample statistics, a hello'd raw client, a line reader for
 * notifications, gonio-sim's state, and a session of a few hundred captures. */
#pragma once

#include <jansson.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>

#include "tests/e2e/harness.h"

/* Starts gonio-sim and goniod of the build tree this program lives in (BUILD/bench/NAME)
 * on the e2e test rig at time_scale; goniod's stderr goes to DIR/goniod.log when log is
 * true (rigenv_start_logged). Exits on failure. */
void bench_start(struct rigenv *e, double time_scale, bool log);

/* Like bench_start on the rig file rig_text (YAML), goniod's log not kept. */
void bench_start_rig(struct rigenv *e, double time_scale, const char *rig_text);

/* CLOCK_MONOTONIC in milliseconds. */
double bench_now_ms(void);

/* CPU time (user + system) process pid has used so far, in seconds (all its threads). */
double bench_cpu_s(pid_t pid);

/* A growing array of samples. */
struct bench_samples {
        double *v;
        size_t n, cap;
};

/* Appends v (exits on out of memory). */
void bench_add(struct bench_samples *s, double v);

/* The q-quantile (0..1, nearest rank) of the samples, which it sorts; NAN when empty. */
double bench_quantile(struct bench_samples *s, double q);

/* Frees the samples' array and empties them. */
void bench_samples_clear(struct bench_samples *s);

/* Connects a raw client and says hello (answer checked). Returns the fd. */
int bench_client(struct rigenv *e, const char *name);

/* Buffered reader of one connection's lines. */
struct bench_lines {
        int fd;
        size_t len;
        char buf[1 << 16];
};

/* Reads what fd has (one read(); blocks when wait) and calls fn on each complete line
 * parsed as JSON (NULL when it is not JSON). Returns the bytes read, 0 at end of file, or
 * -errno (-EAGAIN when nothing was there and !wait). */
ssize_t bench_lines_read(struct bench_lines *l, bool wait, void (*fn)(json_t *msg, void *ud),
                         void *ud);

/* The angle in degrees of role (GN_ROLE_*) gonio-sim reports now, over the control
 * connection *fd (opened on first use, kept open: one request, one reply line). */
double bench_sim_angle(struct rigenv *e, int *fd, int role);

/* Writes a session file DIR/NAME.yaml of the e2e rig named and into dataset name:
 * 24 turntable x 2 light-arm positions, 2 lamps and a laser frame at each, 2 cameras
 * (288 captures), or with big_moves 2 x 2 positions 180 deg apart, no laser (16
 * captures). Returns its path in path. */
const char *bench_session(struct rigenv *e, const char *name, bool big_moves, char *path,
                          size_t len);

/* Clients that said hello and read every notification, one thread reading them all. */
struct bench_watchers {
        int n;
        struct bench_lines *lines;
        long *stored; /* capture.stored each has read */
        atomic_bool quit;
        pthread_t thread;
};

/* Connects n watchers (hello'd) and starts their reader thread. */
void bench_watchers_start(struct bench_watchers *w, struct rigenv *e, int n);

/* Stops the reader and closes the watchers; returns the fewest capture.stored one read. */
long bench_watchers_stop(struct bench_watchers *w);

/* Runs session name (bench_session) to its end, reading its notifications on the starting
 * connection; checks it is complete. Returns its captures per second (between its first and
 * last capture.stored, at bench_now_ms() times written to span_ms unless NULL), its capture
 * count in *n, and adds goniod's CPU time per capture (ms) to *cpu_ms. */
double bench_run_session(struct rigenv *e, const char *name, int64_t *n, double *cpu_ms,
                         double span_ms[2]);
