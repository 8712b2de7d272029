/* clock.h - the two clocks gonio reads: wall time for what is recorded (dataset rows,
 * frame timestamps) and monotonic time for deadlines and durations. */
#pragma once

#include <stdint.h>

/* CLOCK_REALTIME in nanoseconds since the epoch. Never fails; any thread. */
uint64_t gn_realtime_ns(void);

/* CLOCK_MONOTONIC in nanoseconds (arbitrary origin, never goes back). Never fails; any
 * thread. */
uint64_t gn_monotonic_ns(void);
