/* clock.h - the two clocks of the benchmarks: wall time (monotonic) and the CPU time of the
 * whole process (every thread), in seconds. */
#pragma once

#include <time.h>

/* CLOCK_MONOTONIC in seconds. */
static inline double bench_wall_s(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_MONOTONIC, &ts);
        return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* The CPU seconds (user + system) of this process so far, over all its threads. */
static inline double bench_cpu_self_s(void)
{
        struct timespec ts;

        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
        return ts.tv_sec + ts.tv_nsec * 1e-9;
}
